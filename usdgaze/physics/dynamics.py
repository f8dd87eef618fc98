"""MuJoCo full-body dynamics as a part of the planner's state: x = [q, qdot] in minimal coordinates.

The body state is ``2 nv`` long: positions in tangent (exponential) coordinates, velocities as
MuJoCo's ``qvel``. Positions are the base position (metres, world), the base orientation as the
rotation vector of ``anchor^T R_base`` (``anchor`` is a fixed rotation the caller sets per window,
e.g. the reference heading, so the vector stays far from its singularity at pi), each ball joint's
rotation vector and each hinge's angle. Differences of such states are meaningful, which is what the
solver's feedback ``K (x - X)`` needs.

``step`` is one MuJoCo ``mj_step`` with ``opt.timestep = h``: the semi-implicit Euler integrator
(velocities first, positions from the new velocities; joint damping implicit), no substeps.
``linearize`` takes MuJoCo's finite-difference transition matrices (``mjd_transitionFD``), which
perturb positions in the tangent space, and maps them to these coordinates with the right Jacobian
of SO(3) per rotation: ``dx = Jr^-1(r) dtangent``. The controls' and the velocities' columns come
in closed form where the model allows it (``physics.controls``, ``physics.velocity``: the same
numbers within MuJoCo's own differencing error, at a fraction of its cost), the positions' from
MuJoCo's differencing rule run as one batch of steps.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from usdgaze.errors import UsdGazeError
from usdgaze.physics import controls, velocity
from usdgaze.physics.model import BodyModel


def require_mujoco():
    """The ``mujoco`` module, or a one-line error saying how to get it (an optional extra): a missing
    package is the machine's setup, not a bug a farm should retry."""
    try:
        import mujoco
    except ImportError:
        raise UsdGazeError("--physics needs MuJoCo: pip install 'usdgaze[physics]'") from None
    return mujoco


def _skew(v: np.ndarray) -> np.ndarray:
    out = np.zeros(v.shape[:-1] + (3, 3))  # filled in place: the same values as stacking, fewer calls
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -z, y, -x
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = z, -y, x
    return out


def _jr(r: np.ndarray, inverse: bool) -> np.ndarray:
    """Right Jacobian of SO(3) (or its inverse) at rotation vectors ``r`` ``(n, 3)``."""
    th = np.linalg.norm(r, axis=-1)[:, None, None]
    s = _skew(r)
    s2 = s @ s
    small = th < 1e-6
    t = np.where(small, 1.0, th)
    if inverse:
        c = np.where(small, 1.0 / 12.0, 1.0 / t**2 - (1 + np.cos(t)) / (2 * t * np.sin(t)))
        return np.eye(3) + 0.5 * s + c * s2
    a = np.where(small, 0.5, (1 - np.cos(t)) / t**2)
    b = np.where(small, 1.0 / 6.0, (t - np.sin(t)) / t**3)
    return np.eye(3) - a * s + b * s2


def _quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vectors of MuJoCo (w, x, y, z) quaternions ``(n, 4)``."""
    q = q * np.where(q[:, :1] < 0, -1.0, 1.0)
    v = q[:, 1:]
    s = np.sqrt(np.einsum("ij,ij->i", v, v))[:, None]
    ang = 2.0 * np.arctan2(s, q[:, :1])
    big = s > 1e-12
    return v * np.where(big, ang / np.where(big, s, 1.0), 2.0)


def _rotvec_to_quat(r: np.ndarray) -> np.ndarray:
    ang = np.sqrt(np.einsum("ij,ij->i", r, r))[:, None]
    big = ang > 1e-12
    k = np.where(big, np.sin(0.5 * ang) / np.where(big, ang, 1.0), 0.5)
    return np.concatenate([np.cos(0.5 * ang), r * k], axis=1)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, v1, w2, v2 = a[..., :1], a[..., 1:], b[..., :1], b[..., 1:]
    return np.concatenate([w1 * w2 - np.sum(v1 * v2, -1, keepdims=True), w1 * v2 + w2 * v1 + np.cross(v1, v2)], -1)


# MuJoCo's warnings of an unstable step (``mjtWarning``: mjWARN_BADQPOS, BADQVEL, BADQACC)
_BAD = [3, 4, 5]


def _quiet(message: str) -> None:
    return None


class MujocoBody:
    """The simulated body as a dynamics part (``nx = 2 nv``, ``nu`` motors), usable on its own as a
    ``ddp.Dynamics`` or stacked with the eye and belief parts (``bind`` gives it its slices)."""

    name = "body"

    def __init__(self, model: BodyModel, h: float = 0.02, forces: Callable[[int], np.ndarray] | None = None,
                 centered: bool = False, eps: float = 1e-6, workers: int = 1, stride: int = 1, reuse: int = 1) -> None:
        import mujoco

        from usdgaze.physics import mjcf

        self.model, self.h, self.centered, self.eps = model, float(h), centered, eps
        # Trial controls of the line search can blow a step up; ``step_body`` reads MuJoCo's warning
        # counter and hands the solver an infinite cost instead, so MuJoCo's own printout (and its
        # MUJOCO_LOG.TXT in the working folder) would only be noise.
        mujoco.set_mju_user_warning(_quiet)
        self.mj = mujoco.MjModel.from_xml_string(mjcf.write(model, timestep=h))
        self.data = mujoco.MjData(self.mj)
        self.nv, self.nq = self.mj.nv, self.mj.nq
        self.nx, self.nu = 2 * self.nv, self.mj.nu
        self.xs, self.us = slice(0, self.nx), slice(0, self.nu)
        self.stack = None
        self.forces = forces
        self.workers, self._pool, self._clones = int(workers), None, []
        self.stride = int(stride)
        self.kept = None  # finite differences kept across windows (``reuse > 1``, see linearize_batch)
        if reuse > 1:
            from usdgaze.physics.reuse import KeptDifferences

            self.kept = KeptDifferences(int(reuse))
        self.closed_controls = controls.applies(self.mj)
        self._moments = controls.moments(self.mj) if self.closed_controls else None
        # the velocity columns' closed form needs the model's implicit twin (physics.velocity)
        self._twin = velocity.implicit_twin(self.mj) if velocity.applies(self.mj) else None
        self.anchor = np.array([1.0, 0, 0, 0])  # wxyz
        # qpos of recent states (key: their position bytes), for this anchor: a window's rollout, its
        # costs and the head pose ask for the same rows in turn (a pure function: results unchanged).
        self._qpos_cache: dict[bytes, np.ndarray] = {}
        qadr, dadr = model.layout()
        balls = [b for b, k in enumerate(model.kind) if k == "ball"]
        hinges = [b for b, k in enumerate(model.kind) if k == "hinge"]
        self._bq, self._bd = qadr[balls], dadr[balls]
        self._hq, self._hd = qadr[hinges], dadr[hinges]
        # Rotation blocks of the position tangent: base orientation first, then the balls; as index
        # arrays into qpos (4 per block) and into the state (3 per block), so conversions are one gather.
        self._rot = np.concatenate([[3], self._bd])
        self._rot_x = self._rot[:, None] + np.arange(3)
        self._rot_q = np.concatenate([[3], self._bq])[:, None] + np.arange(4)
        self._set_anchor_maps()

    # -- coordinates ------------------------------------------------------------------------------
    def bind(self, stack, xs: slice, us: slice) -> None:
        self.stack, self.xs, self.us = stack, xs, us

    def set_anchor(self, quat_wxyz: np.ndarray) -> None:
        self.anchor = np.asarray(quat_wxyz, dtype=float) / np.linalg.norm(quat_wxyz)
        self._set_anchor_maps()
        self._qpos_cache.clear()

    def _same_anchor(self, other: "MujocoBody") -> None:
        """``other``'s anchor, bit for bit (``set_anchor`` normalizes again, which may move the last bit:
        a thread's copy must convert states exactly as the part it works for)."""
        if self.anchor is not other.anchor:
            self.anchor, self._left, self._left_conj = other.anchor, other._left, other._left_conj
            self._qpos_cache.clear()

    def _set_anchor_maps(self) -> None:
        # Left multiplication by the anchor (and by its conjugate) as 4x4 matrices on wxyz quaternions.
        w, x, y, z = self.anchor
        self._left = np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])
        self._left_conj = self._left.T.copy()

    def to_state(self, qpos: np.ndarray, qvel: np.ndarray | None = None) -> np.ndarray:
        """Body states ``(..., 2 nv)`` from ``qpos`` ``(..., nq)`` (and ``qvel``, default zero)."""
        if np.ndim(qpos) == 1:
            return self._state(qpos, qvel)
        qpos = np.atleast_2d(qpos)
        n = len(qpos)
        out = np.zeros((n, 2 * self.nv))
        out[:, 0:3] = qpos[:, 0:3]
        q = qpos[:, self._rot_q]  # (n, blocks, 4): base orientation first
        q[:, 0] = q[:, 0] @ self._left_conj.T  # relative to the anchor
        out[:, self._rot_x] = _quat_to_rotvec(q.reshape(-1, 4)).reshape(n, -1, 3)
        out[:, self._hd] = qpos[:, self._hq]
        if qvel is not None:
            out[:, self.nv:] = np.atleast_2d(qvel)
        return out

    def _state(self, qpos: np.ndarray, qvel: np.ndarray | None) -> np.ndarray:
        """``to_state`` of one ``qpos``: the same operations on the same shapes (its numbers bit for bit),
        fewer calls (a rollout makes one per step)."""
        out = np.zeros(2 * self.nv)
        out[0:3] = qpos[0:3]
        q = qpos[self._rot_q]
        q[0:1] = q[0:1] @ self._left_conj.T
        out[self._rot_x] = _quat_to_rotvec(q)
        out[self._hd] = qpos[self._hq]
        if qvel is not None:
            out[self.nv:] = qvel
        return out

    def to_mujoco(self, xb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``qpos``, ``qvel`` of one body state (new arrays)."""
        return self.qpos_of(xb).copy(), xb[self.nv:2 * self.nv].copy()

    def qpos_of(self, xb: np.ndarray) -> np.ndarray:
        """``qpos`` of one body state, from the cache (not to be written to)."""
        key = xb[:self.nv].tobytes()
        qpos = self._qpos_cache.get(key)
        if qpos is None:
            if len(self._qpos_cache) >= 4096:
                self._qpos_cache.clear()
            qpos = self._qpos_cache[key] = self._qpos(xb)
        return qpos

    def _qpos(self, xb: np.ndarray) -> np.ndarray:
        qpos = np.empty(self.nq)
        qpos[0:3] = xb[0:3]
        q = _rotvec_to_quat(xb[self._rot_x])
        q[0] = self._left @ q[0]
        qpos[self._rot_q] = q
        qpos[self._hq] = xb[self._hd]
        return qpos

    def _tangent_map(self, xb: np.ndarray, inverse: bool) -> np.ndarray:
        """Per rotation block, ``dx/dtangent`` (``inverse=False`` gives Jr^-1) or its inverse."""
        r = xb[self._rot[:, None] + np.arange(3)]
        return _jr(r, inverse=not inverse)

    # -- what the vision parts need: the head pose and its Jacobian (``compose.BodyPart``) ---------
    def _head_setup(self) -> None:
        """Head body, the eyes' midpoint in its frame and its forward/left/up axes in its frame (rest)."""
        m = self.model
        heads = [b for b, r in enumerate(m.role) if r == "head" and m.kind[b] != "weld"]
        hb = heads[-1] if heads else len(m.bodies) - 1
        eyes = m.eyes
        r_h = m.rest_rot[hb]
        fwd = m.forward if m.forward is not None else np.array([1.0, 0.0, 0.0])
        up = np.array([0.0, 0.0, 1.0])
        axes = np.column_stack([fwd, np.cross(up, fwd), up])
        if eyes:
            mid = m.rest_pos[eyes].mean(axis=0)
        else:  # no eye joints: a typical eye height and depth for the head's size
            mid = m.rest_pos[hb] + m.height * (0.04 * up + 0.05 * fwd)
        self._head = (hb + 1, r_h.T @ (mid - m.rest_pos[hb]), r_h.T @ axes)

    def head_pose_batch(self, X: np.ndarray, k0: int):
        """Eyes' midpoint ``(N, 3)`` and head axes ``(N, 3, 3)`` (columns forward, left, up)."""
        import mujoco

        if not hasattr(self, "_head"):
            self._head_setup()
        body, offset, axes = self._head
        d = self.data
        p, R = np.zeros((len(X), 3)), np.zeros((len(X), 3, 3))
        for i, x in enumerate(X):
            d.qpos[:] = self.qpos_of(x[self.xs])
            mujoco.mj_kinematics(self.mj, d)
            xm = d.xmat[body].reshape(3, 3)
            p[i], R[i] = d.xpos[body] + xm @ offset, xm @ axes
        return p, R

    def head_jacobian_batch(self, X: np.ndarray, k0: int):
        """dp ``(N, 3, NX)`` and dR ``(N, 3, 3, NX)`` w.r.t. the full state (positions only)."""
        import mujoco

        if not hasattr(self, "_head"):
            self._head_setup()
        body, offset, axes = self._head
        nx = self.stack.nx if self.stack is not None else self.nx
        dp, dR = np.zeros((len(X), 3, nx)), np.zeros((len(X), 3, 3, nx))
        d, rot, s = self.data, self._rot_x, self.xs.start
        maps = _jr(X[:, self.xs][:, rot].reshape(-1, 3), inverse=False).reshape(len(X), len(rot), 3, 3)  # d tangent / d x
        jp, jr = np.zeros((3, self.nv)), np.zeros((3, self.nv))
        for i, x in enumerate(X):
            d.qpos[:] = self.qpos_of(x[self.xs])
            mujoco.mj_kinematics(self.mj, d)
            mujoco.mj_comPos(self.mj, d)
            xm = d.xmat[body].reshape(3, 3)
            p, R = d.xpos[body] + xm @ offset, xm @ axes  # head_pose_batch's, from the same kinematics
            jp[:], jr[:] = 0.0, 0.0
            mujoco.mj_jac(self.mj, d, jp, jr, p, body)
            # per rotation block, (3, 3) @ (3, 3) as one stacked matmul (the same products, fewer calls)
            jp[:, rot] = np.matmul(jp[:, rot].transpose(1, 0, 2), maps[i]).transpose(1, 0, 2)
            jr[:, rot] = np.matmul(jr[:, rot].transpose(1, 0, 2), maps[i]).transpose(1, 0, 2)
            dp[i, :, s:s + self.nv] = jp
            dR[i, :, :, s:s + self.nv] = np.einsum("ijn,jk->ikn", _skew(jr.T).transpose(1, 2, 0), R)
        return dp, dR

    def head_pose(self, x, k):
        p, R = self.head_pose_batch(x[None], k)
        return p[0], R[0]

    def head_pose_jacobian(self, x, k):
        dp, dR = self.head_jacobian_batch(x[None], k)
        return dp[0], dR[0]

    # -- dynamics ---------------------------------------------------------------------------------
    def _load(self, xb: np.ndarray, ub: np.ndarray, k: int) -> None:
        d = self.data
        d.qpos[:] = self.qpos_of(xb)
        d.qvel[:] = xb[self.nv:2 * self.nv]
        d.ctrl[:] = ub
        d.qacc_warmstart[:] = 0.0
        d.xfrc_applied[:] = 0.0 if self.forces is None else self.forces(k)
        d.time = k * self.h

    def step_body(self, xb: np.ndarray, ub: np.ndarray, k: int) -> np.ndarray:
        import mujoco

        self._load(xb, ub, k)
        counts = self.data.warning.number
        bad = counts[_BAD].tolist()
        mujoco.mj_step(self.mj, self.data)
        if counts[_BAD].tolist() != bad:
            # MuJoCo resets an unstable state to qpos0; say so to the solver instead (infinite cost).
            return np.full(self.nx, np.nan)
        return self.to_state(self.data.qpos, self.data.qvel)

    def step(self, x: np.ndarray, u: np.ndarray, k: int) -> np.ndarray:
        return self.step_body(x[self.xs], u[self.us], k)

    def linearize_body(self, xb: np.ndarray, ub: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of one step in these coordinates: ``(2nv, 2nv)``, ``(2nv, nu)``."""
        A, B = self._fd(xb, ub, k)
        # Tangent -> minimal coordinates: rows by Jr^-1 at the next state, columns by Jr at this one.
        return self._minimal(A, B, xb, self._next(xb, ub, k))

    def _fd(self, xb: np.ndarray, ub: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """One step's transition matrices in MuJoCo's tangent coordinates: the velocities' and the
        controls' columns in closed form where the model allows (``physics.velocity``), the positions'
        by finite differences; MuJoCo's ``mjd_transitionFD`` for what the closed forms do not cover."""
        import mujoco

        nv = self.nv
        self._load(xb, ub, k)
        A = np.zeros((2 * nv, 2 * nv))
        if self.closed_controls:
            mujoco.mj_forward(self.mj, self.data)
            if self._twin is not None:
                got = velocity.columns(self.mj, self._twin, self.data, self._rot_x, self._moments)
                if got is not None:
                    A[:, nv:], B = got
                    self._load(xb, ub, k)
                    A[:, :nv] = velocity.position_columns(self.mj, self.data, self.eps, self.centered)
                    return A, B
            B = controls.closed_form(self.mj, self.data, np.asarray(self.data.ctrl), self._rot_x, self._moments)
            if B is not None:
                self._load(xb, ub, k)
                mujoco.mjd_transitionFD(self.mj, self.data, self.eps, self.centered, A, None, None, None)
                return A, B
            self._load(xb, ub, k)
        B = np.zeros((2 * nv, self.nu))
        mujoco.mjd_transitionFD(self.mj, self.data, self.eps, self.centered, A, B, None, None)
        return A, B

    def _minimal(self, A: np.ndarray, B: np.ndarray, xb: np.ndarray, xn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tangent-space (A, B) of the step from ``xb`` to ``xn`` in the state's coordinates (in place)."""
        # Jr^-1(r') at the next state for the rows, Jr(r) at this one for the columns
        return self._to_minimal(A, B, self._tangent_map(xn, inverse=False), self._tangent_map(xb, inverse=True))

    def _to_minimal(self, A: np.ndarray, B: np.ndarray, out_map: np.ndarray, in_map: np.ndarray):
        """``_minimal`` with its tangent maps ``(blocks, 3, 3)`` given (in place)."""
        idx = self._rot_x
        A[idx] = np.einsum("bij,bjn->bin", out_map, A[idx])
        B[idx] = np.einsum("bij,bjn->bin", out_map, B[idx])
        A[:, idx] = np.einsum("nbi,bij->nbj", A[:, idx], in_map)
        return A, B

    def window_maps(self, Xb: np.ndarray, inverse: bool) -> np.ndarray:
        """``_tangent_map`` of each body state ``Xb`` ``(n, 2nv)`` in one call: ``(n, blocks, 3, 3)``, the
        same numbers element by element."""
        r = Xb[:, self._rot_x]
        return _jr(r.reshape(-1, 3), inverse=not inverse).reshape(r.shape + (3,))

    def linearize(self, x: np.ndarray, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        from usdgaze.physics import fdpool

        return fdpool.stack_rows(self, *self.linearize_body(x[self.xs], u[self.us], k))

    def linearize_batch(self, X: np.ndarray, U: np.ndarray, k0: int) -> tuple[np.ndarray, np.ndarray]:
        """The window's linearizations. With ``stride > 1`` MuJoCo's finite differences are taken at
        every ``stride``-th step and the last, and linearly interpolated in between (the derivative
        interpolation of Han et al. 2016, which the paper's solver uses). With ``reuse > 1`` a step
        differentiated by an earlier call (the previous window, for a receding horizon) keeps its
        matrices for up to ``reuse`` calls (``physics.reuse``). With ``workers > 1`` the steps are
        split over threads, each with its own copy of the part (MuJoCo releases the GIL inside its
        functions)."""
        return self.linearize_start(X, U, k0)()

    def linearize_start(self, X: np.ndarray, U: np.ndarray, k0: int,
                        after: np.ndarray | None = None) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
        """``linearize_batch`` begun: with ``workers > 1`` the threads start now and the caller may do
        other work (the cost's expansion) before calling the result for the matrices; at stride 1 with
        nothing kept, the result's ``step(i)`` gives one step's rows as soon as they are made
        (``fdpool.StepRows``: the threads take the window's steps last first). ``after``: the state
        each step led to where ``X`` is the rollout of ``U`` (``ddp.solve``'s), so that no step is
        stepped again for its next state (None: each is)."""
        from usdgaze.physics import fdpool

        n = len(U)
        if self.stride <= 1 and self.kept is None:
            return fdpool.StepRows(self, X, U, k0, after)
        at = np.unique(np.r_[np.arange(0, n, max(1, self.stride)), n - 1]) if n else np.zeros(0, int)
        if self.kept is not None:
            return self.kept.linearize_start(self, X, U, k0, at)
        work = lambda body, chunk: [body.linearize_body(X[i, self.xs], U[i, self.us], k0 + i) for i in chunk]  # noqa: E731
        got = fdpool.split(self, work, at)
        return lambda: fdpool.window_matrices(self, [p for part in got() for p in part], at, n)

    def _next(self, xb: np.ndarray, ub: np.ndarray, k: int) -> np.ndarray:
        """The next body state's positions (velocities zero) under MuJoCo's step."""
        import mujoco

        self._load(xb, ub, k)
        mujoco.mj_step(self.mj, self.data)
        return self.to_state(self.data.qpos)
