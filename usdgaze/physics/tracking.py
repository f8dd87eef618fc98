"""The full-body costs of the paper (section 6) for the body part of the state, and the reference.

``c = w_trk (|x_ref - x|_W^2 + w_o |o_ref - o|^2) + w_eng |tau|^2``, where ``o`` is the vector from
the root to the head (the paper's upper-body orientation term) and ``tau = gear * u`` the joint
torques in N m. The state norm is weighted per block (``Weights``) because its entries mix metres,
radians and their rates; the paper's weights (``w_trk = 0.1``, ``w_eng = 1e-5``) are the defaults.
Derivatives are exact for the quadratic terms and Gauss-Newton for ``o`` (its Jacobian from MuJoCo's
``mj_jac``, mapped to the state's minimal coordinates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.physics.dynamics import MujocoBody, _jr
from usdgaze.physics.measures import bottom_point, lowest_z


@dataclass
class Weights:
    w_trk: float = 0.1
    w_eng: float = 1e-5
    root_pos: float = 30.0
    root_rot: float = 30.0
    joint: float = 3.0
    root_vel: float = 0.3
    joint_vel: float = 0.03
    head: float = 30.0
    terminal: float = 3.0  # the last step's state terms are scaled by this


def resample(qpos: np.ndarray, seconds: np.ndarray, h: float, dyn: MujocoBody) -> np.ndarray:
    """Reference ``qpos`` at steps of ``h`` from samples at ``seconds`` (linear, quaternions nlerped)."""
    # Steps cover the whole clip: the last one may pass its end by under a step (holding the last pose).
    n = int(np.ceil((seconds[-1] - seconds[0]) / h - 1e-6)) + 1
    t = seconds[0] + h * np.arange(n)
    i = np.clip(np.searchsorted(seconds, t, side="right") - 1, 0, len(seconds) - 2)
    a = np.clip((t - seconds[i]) / np.maximum(seconds[i + 1] - seconds[i], 1e-12), 0.0, 1.0)[:, None]
    q0, q1 = qpos[i], qpos[i + 1].copy()
    quats = [3] + [int(j) for j in dyn._bq]
    for s in quats:  # same hemisphere before blending
        flip = np.sum(q0[:, s:s + 4] * q1[:, s:s + 4], axis=1) < 0
        q1[flip, s:s + 4] *= -1
    out = (1 - a) * q0 + a * q1
    for s in quats:
        out[:, s:s + 4] /= np.linalg.norm(out[:, s:s + 4], axis=1, keepdims=True)
    return out


def velocities(qpos: np.ndarray, h: float, mj) -> np.ndarray:
    """``qvel`` of a ``qpos`` sequence by MuJoCo's own position differences (central inside)."""
    import mujoco

    n = len(qpos)
    qvel = np.zeros((n, mj.nv))
    for k in range(n):
        a, b = max(k - 1, 0), min(k + 1, n - 1)
        if b > a:
            mujoco.mj_differentiatePos(mj, qvel[k], (b - a) * h, qpos[a], qpos[b])
    return qvel


class BodyTracking:
    """Tracking + energy cost of the body part over absolute steps ``k`` (the reference's indices)."""

    def __init__(self, dyn: MujocoBody, ref_qpos: np.ndarray, ref_qvel: np.ndarray, head_body: int,
                 weights: Weights = Weights()) -> None:
        import mujoco

        self.dyn, self.w = dyn, weights
        self.ref_qpos, self.ref_qvel = ref_qpos, ref_qvel
        self.head = head_body  # MuJoCo body id
        self.data = mujoco.MjData(dyn.mj)
        nv = dyn.nv
        w = np.full(2 * nv, weights.joint)
        w[0:3], w[3:6] = weights.root_pos, weights.root_rot
        w[nv:nv + 6] = weights.root_vel
        w[nv + 6:] = weights.joint_vel
        self.wx = w * weights.w_trk
        gear = np.abs(dyn.mj.actuator_gear[:, :3]).max(axis=1)
        self.wu = weights.w_eng * gear * gear
        self.ref_o = np.array([self._o(q)[0] for q in ref_qpos])
        self._xref_cache: dict = {}

    def ref_state(self, k: int) -> np.ndarray:
        k = min(max(k, 0), len(self.ref_qpos) - 1)
        key = (k, tuple(self.dyn.anchor))
        if key not in self._xref_cache:
            self._xref_cache[key] = self.dyn.to_state(self.ref_qpos[k], self.ref_qvel[k])
        return self._xref_cache[key]

    def _o(self, qpos: np.ndarray, jac: bool = False):
        import mujoco

        d = self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.dyn.mj, d)
        o = d.xpos[self.head] - d.xpos[1]
        if not jac:
            return o, None
        mujoco.mj_comPos(self.dyn.mj, d)
        jh, jr = np.zeros((3, self.dyn.nv)), np.zeros((3, self.dyn.nv))
        mujoco.mj_jacBody(self.dyn.mj, d, jh, None, self.head)
        mujoco.mj_jacBody(self.dyn.mj, d, jr, None, 1)
        return o, jh - jr

    def _terms(self, xb: np.ndarray, k: int, derivs: bool):
        scale = self.w.terminal if derivs == "terminal" else 1.0
        e = xb - self.ref_state(k)
        qpos, _ = self.dyn.to_mujoco(xb)
        o, J = self._o(qpos, jac=bool(derivs))
        eo = o - self.ref_o[min(max(k, 0), len(self.ref_o) - 1)]
        wo = self.w.w_trk * self.w.head
        c = scale * (float(np.sum(self.wx * e * e)) + wo * float(eo @ eo))
        if not derivs:
            return c, None, None
        nv = self.dyn.nv
        # d(tangent)/dx = Jr(r) per rotation block: the Jacobian in the state's coordinates.
        rot = self.dyn._rot[:, None] + np.arange(3)
        maps = _jr(xb[rot], inverse=False)
        Jx = J.copy()
        for b in range(len(rot)):
            Jx[:, rot[b]] = J[:, rot[b]] @ maps[b]
        lx = 2 * self.wx * e
        lx[:nv] += 2 * wo * Jx.T @ eo
        lxx = np.diag(2 * self.wx)
        lxx[:nv, :nv] += 2 * wo * Jx.T @ Jx
        return c * 1.0, scale * lx, scale * lxx

    # -- the solver's Cost protocol for a body-only problem --------------------------------------
    def l(self, x, u, k):
        return self._terms(x[self.dyn.xs], k, False)[0] + float(np.sum(self.wu * u[self.dyn.us] ** 2))

    def derivs(self, x, u, k):
        c, lxb, lxxb = self._terms(x[self.dyn.xs], k, True)
        nx, nu = len(x), len(u)
        lx = np.zeros(nx)
        lxx = np.zeros((nx, nx))
        lx[self.dyn.xs], lxx[self.dyn.xs, self.dyn.xs] = lxb, lxxb
        lu = np.zeros(nu)
        luu = np.zeros((nu, nu))
        lu[self.dyn.us] = 2 * self.wu * u[self.dyn.us]
        luu[self.dyn.us, self.dyn.us] = np.diag(2 * self.wu)
        return lx, lu, lxx, luu, np.zeros((nu, nx))

    def terminal(self, x, k):
        return self._terms(x[self.dyn.xs], k, False)[0] * self.w.terminal

    def terminal_derivs(self, x, k):
        _, lxb, lxxb = self._terms(x[self.dyn.xs], k, "terminal")
        lx = np.zeros(len(x))
        lxx = np.zeros((len(x), len(x)))
        lx[self.dyn.xs], lxx[self.dyn.xs, self.dyn.xs] = lxb, lxxb
        return lx, lxx

    # -- batched over a window (the solver uses these when present) ------------------------------
    def _window(self, X: np.ndarray, k0: int, jac: bool):
        """State errors ``(n, 2nv)``, head-vector errors ``(n, 3)`` and their Jacobians in the state's
        coordinates ``(n, 3, nv)`` (None unless ``jac``) of the body states ``X[:, xs]``."""
        import mujoco

        dyn, d = self.dyn, self.data
        Xb = X[:, dyn.xs]
        n = len(Xb)
        ref = np.stack([self.ref_state(k0 + i) for i in range(n)])
        last = len(self.ref_o) - 1
        ref_o = self.ref_o[np.clip(k0 + np.arange(n), 0, last)]
        o = np.empty((n, 3))
        J = np.zeros((n, 3, dyn.nv)) if jac else None
        jr = np.zeros((3, dyn.nv))
        for i in range(n):
            d.qpos[:] = dyn.qpos_of(Xb[i])
            mujoco.mj_kinematics(dyn.mj, d)
            o[i] = d.xpos[self.head] - d.xpos[1]
            if jac:
                mujoco.mj_comPos(dyn.mj, d)
                mujoco.mj_jacBody(dyn.mj, d, J[i], None, self.head)
                mujoco.mj_jacBody(dyn.mj, d, jr, None, 1)
                J[i] -= jr
        if jac:  # d(tangent)/dx = Jr(r) per rotation block
            rot = dyn._rot_x
            maps = _jr(Xb[:, rot].reshape(-1, 3), inverse=False).reshape(n, len(rot), 3, 3)
            J[:, :, rot] = np.einsum("nkbi,nbij->nkbj", J[:, :, rot], maps)
        return Xb - ref, o - ref_o, J

    def _state_cost(self, E: np.ndarray, Eo: np.ndarray) -> np.ndarray:
        return np.einsum("nj,j,nj->n", E, self.wx, E) + self.w.w_trk * self.w.head * np.einsum("nj,nj->n", Eo, Eo)

    def cost_batch(self, X, U, k0):
        E, Eo, _ = self._window(X, k0, jac=False)
        Ub = U[:, self.dyn.us]
        return self._state_cost(E, Eo) + np.einsum("nj,j,nj->n", Ub, self.wu, Ub)

    def total_batch(self, X, U, k0):
        """Running costs of ``X[:-1]``, ``U`` plus the terminal cost of ``X[-1]``, in one pass."""
        E, Eo, _ = self._window(X, k0, jac=False)
        c = self._state_cost(E, Eo)
        Ub = U[:, self.dyn.us]
        return float(np.sum(c[:-1]) + np.einsum("nj,j,nj->", Ub, self.wu, Ub) + self.w.terminal * c[-1])

    def derivs_batch(self, X, U, k0):
        dyn = self.dyn
        n, nx, nu, nv = len(U), X.shape[1], U.shape[1], dyn.nv
        E, Eo, J = self._window(X[:n], k0, jac=True)
        wo = self.w.w_trk * self.w.head
        xs, us = dyn.xs, dyn.us
        lx = np.zeros((n, nx))
        lx[:, xs] = 2 * self.wx * E
        lx[:, xs.start:xs.start + nv] += 2 * wo * np.einsum("nki,nk->ni", J, Eo)
        lxx = np.zeros((n, nx, nx))
        b = np.arange(xs.start, xs.stop)
        lxx[:, b, b] = 2 * self.wx
        top = slice(xs.start, xs.start + nv)
        lxx[:, top, top] += 2 * wo * np.einsum("nki,nkj->nij", J, J)
        lu = np.zeros((n, nu))
        luu = np.zeros((n, nu, nu))
        lu[:, us] = 2 * self.wu * U[:, us]
        c = np.arange(us.start, us.stop)
        luu[:, c, c] = 2 * self.wu
        return lx, lu, lxx, luu, np.zeros((n, nu, nx))


def clear_ground(dyn: MujocoBody, ref_qpos: np.ndarray, step_deg: float = 1.0, reach_deg: float = 45.0) -> np.ndarray:
    """The reference with its toes turned out of the ground: per frame, each toe hinge whose geoms reach
    below ``z = 0`` is turned by the smallest angle (up to ``reach_deg``, either way) that clears them;
    where none does, the foot itself is too low and the toe is left as it is.

    Capture and model differ (CMU 131_01's lunge puts the model's toes up to 5 cm into the floor);
    tracking such a target makes the planner drive a light toe through the soft ground. Only the toes
    are changed (turning the ankles too measured worse on the walk: 6.0 cm deepest, not 2.3); the
    measures use the reference as is.
    """
    import mujoco

    m = dyn.model
    qadr, _ = m.layout()
    toes = [b for b in m.toes if m.kind[b] == "hinge"]
    geoms = {b: np.flatnonzero(dyn.mj.geom_bodyid == b + 1) for b in toes}
    out = ref_qpos.copy()
    d = mujoco.MjData(dyn.mj)

    def lowest(q, b):
        d.qpos[:] = q
        mujoco.mj_kinematics(dyn.mj, d)
        return lowest_z(dyn.mj, d, geoms[b])

    step = np.radians(step_deg)
    turns = step * np.arange(1, int(round(reach_deg / step_deg)) + 1)
    turns = np.repeat(turns, 2) * np.tile([1.0, -1.0], len(turns))  # smallest first, either way
    for k in range(len(out)):
        for b in toes:
            if lowest(out[k], b) >= 0.0:
                continue
            a, q = qadr[b], out[k].copy()
            for t in turns:
                q[a] = out[k, a] + t
                if lowest(q, b) >= 0.0:
                    out[k, a] = q[a]
                    break
    return out


def _leg(m, foot: int) -> list[int]:
    """The knee's and the hip's bodies above ``foot``: each the topmost movable part of the shank and of
    the thigh. The foot's parent and grandparent were taken: on a split bone (Rigify's DEF-shin.L and
    DEF-shin.L.001) the shin's two halves, and no hip. Without leg roles, those two still."""
    found, b = {}, int(m.body_parent[foot])
    while b > 0 and m.role[b] in ("shank", "thigh"):
        if m.kind[b] in ("ball", "hinge"):
            found[m.role[b]] = b  # overwritten going up: the segment's topmost part
        b = int(m.body_parent[b])
    if b != int(m.body_parent[foot]):
        return [found[r] for r in ("shank", "thigh") if r in found]
    return [b for b in (m.body_parent[foot], m.body_parent[m.body_parent[foot]]) if b > 0 and m.kind[b] in ("ball", "hinge")]


def lift_feet(dyn: MujocoBody, ref_qpos: np.ndarray, iterations: int = 20, step_rad: float = 0.1,
              reach_deg: float = 30.0) -> np.ndarray:
    """The reference with each foot still in the ground after :func:`clear_ground` lifted out of it by
    its leg: per frame, the thigh's and the shank's joints turned by the least (damped least squares
    on the foot's lowest point, each step at most ``step_rad``) that puts the foot's lowest geom on the
    ground; the pelvis, the other leg and the foot's own joints stay. Where ``reach_deg`` of leg
    rotation does not do it, the leg is left as it is.

    CMU 131_01's lunge has a foot 4-5 cm deep for 12 steps after its toes are turned out: tracked as
    it is, the planner drives the foot into the soft ground."""
    import mujoco

    m, mj = dyn.model, dyn.mj
    _, vadr = m.layout()
    d = mujoco.MjData(mj)
    out = ref_qpos.copy()
    jacp = np.zeros((3, mj.nv))
    for foot in m.feet:
        parts = [foot] + [b for b in m.toes if m.body_parent[b] == foot]
        geoms = np.flatnonzero(np.isin(mj.geom_bodyid - 1, parts))
        leg = _leg(m, foot)
        if not leg or not len(geoms):  # a foot hung from the base itself, or with no shape: nothing to lift
            continue
        cols = np.concatenate([vadr[b] + np.arange(3 if m.kind[b] == "ball" else 1) for b in leg]).astype(int)
        for k in range(len(out)):
            q = out[k].copy()
            turned = 0.0
            for _ in range(iterations):
                d.qpos[:] = q
                mujoco.mj_kinematics(mj, d)
                bottoms = [float(bottom_point(mj, d, g)[2]) for g in geoms]
                g = geoms[int(np.argmin(bottoms))]
                depth = -min(bottoms)
                if depth <= 0.0:
                    out[k] = q
                    break
                mujoco.mj_comPos(mj, d)
                point = bottom_point(mj, d, g)
                mujoco.mj_jac(mj, d, jacp, None, point, int(mj.geom_bodyid[g]))
                j = jacp[2, cols]
                dv = j * (depth + 1e-4) / (j @ j + 1e-4)
                norm = np.linalg.norm(dv)
                if norm > step_rad:
                    dv *= step_rad / norm
                turned += np.linalg.norm(dv)
                if turned > np.radians(reach_deg):
                    break
                full = np.zeros(mj.nv)
                full[cols] = dv
                mujoco.mj_integratePos(mj, q, full, 1.0)
    return out
