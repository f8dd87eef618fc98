"""Moving obstacles (Eom et al. 2019, section 7): an exponential proximity cost, the four nearest.

The paper's cost (eq. 9) is on the root: ``c_tsk = sum_j exp(-|p_root - p_j|^2 / s_j^2)`` over the
four obstacles nearest the character at each step, ``w_tsk = 1``, with two sub-windows: the
optimized window follows the root trajectory; a further ``lookahead`` (the paper: 1.0 s optimized
+ 0.6 s) is costed on the root extrapolated linearly from the last optimized state with its
velocity held, so the terminal cost sees obstacles beyond the window without optimizing over it.
``form="root"`` is that term; ``form="body"`` (the default) is ours, below. Ours: the optimized
window is the controller's (0.6 s by default) and ``lookahead`` 1.0 s, the paper's 1.6 s in all at
the optimized cost of 0.6 s (0.6 s extrapolated left the body-only walk touching in 1 of 5 runs).

Ours, where the paper leaves room (docs/physics.md):

* ``form="body"``: the same exponential on the body's collision capsule nearest each obstacle (at
  its point nearest the obstacle's centre, in 3D): ``sum_j max_g exp(-|p_g - p_j|^2 / s_gj^2)``
  with ``s_gj`` the obstacle's radius plus the capsule's plus ``clearance`` (0.1 m; the gradient
  is largest ~6 cm before contact). On the CMU walk the spheres meet the arms ~0.5 m from the
  root, which a root term cannot see (with it, contact in 4 of 5 coupled runs before this
  work). "Four nearest": the four obstacles with the largest terms per step. The extrapolated
  sub-window carries the whole body along the root's ground-plane velocity.
* ``p_j``: with the eyes coupled (``physics.visuomotor``) it is the belief's mean before each solve,
  run forward at its estimated velocity (the optimizer's expected mean), and an obstacle not yet
  seen costs nothing; on the body-only controller the planner knows the obstacles' paths (the
  Han et al. 2016 setting the paper compares against).
* ``form="root"``: distances in the ground plane (the root's height says nothing about whether a
  sphere at knee or head height meets the body, and the root cannot dodge vertically), ``s_j`` the
  radius plus ``clearance`` (0.6 m: the arms reach ~0.35 m from the root in the ground plane, plus
  a margin; with the radius alone the cost is ~exp(-4) where a 25 cm sphere already touches the
  arms), the four largest terms (nearest relative to size, so the sum stays continuous).

Derivatives: gradients exact (the nearest point of a capsule moves along it, which changes the
distance only to second order; the nearest capsule changes where two are equally near, a kink the
line search copes with; its Jacobian is MuJoCo's ``mj_jac`` mapped to the state's rotation
vectors, ``points.Capsules``). Hessians Gauss-Newton-like: each term's curvature along the
point-to-centre direction, ``e (a^2 d^2 - a)`` with ``a = 2 / s^2``, kept where positive and
mapped through the point's Jacobian (``J' n n' J``), the rest (negative near an obstacle, and the
kinematics' second derivatives) dropped, so the solver's model is convex.
"""

from __future__ import annotations

import numpy as np

from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.points import Capsules
from usdgaze.physics.shapes import half_lengths

W_TSK = 1.0
NEAREST = 4
LOOKAHEAD_S = 1.0
CLEARANCE_M = {"body": 0.1, "root": 0.6}
FORMS = tuple(CLEARANCE_M)
FORM = "body"  # the default (benchmarks/bench_physics.py --obstacle-form root compares the paper's)


class ObstacleTask:
    """The obstacle task term over the planner's state (a ``ddp.Cost`` plus ``measure``)."""

    name = "obstacles"

    def __init__(self, dyn: MujocoBody, centres: np.ndarray, radii: np.ndarray, weight: float = W_TSK,
                 lookahead_s: float = LOOKAHEAD_S, clearance: float | None = None, nearest: int = NEAREST,
                 objects: list[int] | None = None, form: str | None = None) -> None:
        """``centres``: the true paths at the planner's steps (what is measured, and what the body-only
        planner knows); ``objects``: the obstacles' indices among the coupled loop's objects, whose
        belief then replaces the true paths inside the optimizer (-1: not an object, path known);
        ``form``: "body" (ours, the default) or "root" (the paper's eq. 9)."""
        form = FORM if form is None else form
        if form not in FORMS:
            raise ValueError(f"obstacle cost form {form!r}: expected one of {FORMS}")
        self.dyn, self.w, self.form = dyn, float(weight), form
        self.centres = np.asarray(centres, dtype=float)  # (K, J, 3) model world at the planner's steps
        self.truth = self.centres
        self.objects = objects
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        margin = CLEARANCE_M[form] if clearance is None else float(clearance)
        self.s2 = (self.radii + margin) ** 2
        self.nearest = int(nearest)
        self.ahead = int(round(lookahead_s / dyn.h))
        nv = dyn.nv
        self._p = slice(0, 2)  # root position (ground plane) in the body state
        self._v = slice(nv, nv + 2)  # root linear velocity (MuJoCo's free joint: world frame)
        self._offsets = {tail: np.arange(self.ahead + 1 if tail else 1) for tail in (False, True)}
        self._lead = {tail: dyn.h * steps for tail, steps in self._offsets.items()}
        if form == "body":
            self.caps = Capsules(dyn)
            self.s2g = (self.radii[:, None] + self.caps.radius[None] + margin) ** 2  # (J, G)

    def perceive(self, percept) -> None:
        """Before each solve of the coupled loop: the obstacles as the character believes them, from
        step ``percept.k`` on (constant velocity; unseen ones far away, so they cost nothing)."""
        if self.objects is None:
            return
        t = percept.h * (np.arange(len(self.truth)) - percept.k)[:, None]
        believed = np.full(self.truth.shape, 1e6)
        for j, index in enumerate(self.objects):
            if index < 0:  # not an object the eyes can see: known as the body-only planner knows it
                believed[:, j] = self.truth[:, j]
                continue
            mu = percept.mu.get(index)
            if mu is not None:
                believed[:, j] = mu[:3] + t * mu[3:6]
        self.centres = believed

    def _at(self, k: int) -> np.ndarray:
        return self.centres[min(max(int(k), 0), len(self.centres) - 1), :, :2]

    def _terms(self, p: np.ndarray, k: int):
        """Value, gradient (2,) and PSD Hessian (2, 2) of the proximity sum at root ``p`` at step ``k``."""
        if not len(self.radii):
            return 0.0, np.zeros(2), np.zeros((2, 2))
        r = p - self._at(k)
        e = np.exp(-np.sum(r * r, axis=1) / self.s2)
        keep = np.argsort(-e, kind="stable")[: self.nearest]
        g, H = np.zeros(2), np.zeros((2, 2))
        for j in keep:
            a = 2.0 / self.s2[j]
            g += -a * e[j] * r[j]
            hj = e[j] * (a * a * np.outer(r[j], r[j]) - a * np.eye(2))
            w, V = np.linalg.eigh(hj)
            H += (V * np.maximum(w, 0.0)) @ V.T
        return float(e[keep].sum()), g, H

    def exact_hessian(self, p: np.ndarray, k: int) -> np.ndarray:
        """The true 2x2 Hessian of the step's sum (for checks; the solver gets its PSD part)."""
        r = p - self._at(k)
        e = np.exp(-np.sum(r * r, axis=1) / self.s2)
        keep = np.argsort(-e, kind="stable")[: self.nearest]
        a = 2.0 / self.s2[keep]
        return sum(e[j] * (aj * aj * np.outer(r[j], r[j]) - aj * np.eye(2)) for j, aj in zip(keep, a))

    def _running(self, xb, k):
        return self._terms(xb[self._p], k)

    def _tail(self, xb, k):
        """The extrapolated sub-window: root p + i h v for i = 1..ahead, at steps k + i."""
        p, v, h = xb[self._p], xb[self._v], self.dyn.h
        c, gp, gv = 0.0, np.zeros(2), np.zeros(2)
        Hpp, Hpv, Hvv = np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))
        for i in range(1, self.ahead + 1):
            ci, g, H = self._terms(p + i * h * v, k + i)
            t = i * h
            c, gp, gv = c + ci, gp + g, gv + t * g
            Hpp, Hpv, Hvv = Hpp + H, Hpv + t * H, Hvv + t * t * H
        return c, gp, gv, Hpp, Hpv, Hvv

    def _body(self, xb: np.ndarray, k: int, tail: bool, derivs: bool):
        """The body form at step ``k`` (and, with ``tail``, its extrapolated sub-window): value, and
        with ``derivs`` the gradient and PSD Hessian over ``[q (nv), root ground-plane velocity (2)]``."""
        nv = self.dyn.nv
        if not len(self.radii):
            return (0.0, np.zeros(nv + 2), np.zeros((nv + 2, nv + 2))) if derivs else 0.0
        caps = self.caps
        c, axis = caps.segments(xb)
        lead = self._lead[tail]  # seconds extrapolated, per time
        # (integer clip and ground-plane velocity without np.clip's and np.r_'s wrappers: one call a step)
        steps = np.minimum(np.maximum(k + self._offsets[tail], 0), len(self.centres) - 1)
        v = np.zeros(3)
        v[:2] = xb[self._v]
        centres = self.centres[steps] - lead[:, None, None] * v  # relative to the body carried along
        rel = centres[:, :, None, :] - c  # (T, J, G, 3)
        t = np.clip(np.einsum("tjgk,gk->tjg", rel, axis), -caps.half, caps.half)
        r = t[..., None] * axis - rel  # nearest capsule point minus the centre
        d2 = np.einsum("tjgk,tjgk->tjg", r, r)
        e = np.exp(-d2 / self.s2g)
        # Per obstacle its nearest capsule only (relative to size): a sum over all 33 pushed the
        # whole body away from a sphere near one hand, 10x the paper's cost (falls in 3 of 5 runs).
        e = e * (np.arange(e.shape[2]) == e.argmax(axis=2)[..., None])
        if len(self.radii) > self.nearest:  # the four obstacles with the largest terms, per time
            order = np.argsort(-e.sum(axis=2), axis=1, kind="stable")
            keep = np.zeros(e.shape[:2], bool)
            np.put_along_axis(keep, order[:, : self.nearest], True, axis=1)
            e = e * keep[..., None]
        if not derivs:
            return float(e.sum())
        ti, ji, gi = np.nonzero(e > 1e-12)
        if not len(ti):  # nothing near (or nothing seen yet)
            return float(e.sum()), np.zeros(nv + 2), np.zeros((nv + 2, nv + 2))
        a = 2.0 / self.s2g[ji, gi]
        es, rs, d2s = e[ti, ji, gi], r[ti, ji, gi], d2[ti, ji, gi]
        gp = -(a * es)[:, None] * rs  # d e / d (the point), (n, 3)
        lam = es * np.maximum(a * a * d2s - a, 0.0)
        n = rs / np.sqrt(np.maximum(d2s, 1e-24))[:, None]
        # The gradient is sum_i gp_i J_i = sum_i (-a e |r|) n_i J_i: one projection gives both.
        nq = caps.project(xb, gi, c[gi] + t[ti, ji, gi][:, None] * axis[gi], n)
        scale = -a * es * np.sqrt(d2s)
        grad = np.concatenate([scale @ nq, lead[ti] @ gp[:, :2]])
        rows = np.hstack([nq, lead[ti, None] * n[:, :2]])
        return float(e.sum()), grad, rows.T @ (lam[:, None] * rows)

    def _full(self, x, grads: np.ndarray, hess: np.ndarray, cols: np.ndarray):
        """Gradient and Hessian over the body state's entries ``cols`` as the whole state's."""
        nx = len(x)
        lx, lxx = np.zeros(nx), np.zeros((nx, nx))
        idx = self.dyn.xs.start + cols
        lx[idx] = grads
        lxx[np.ix_(idx, idx)] = hess
        return lx, lxx

    def _root_cols(self) -> np.ndarray:
        nv = self.dyn.nv
        return np.r_[0, 1, nv, nv + 1]

    def _body_cols(self) -> np.ndarray:
        nv = self.dyn.nv
        return np.r_[np.arange(nv), nv, nv + 1]

    # -- ddp.Cost --------------------------------------------------------------------------------
    def l(self, x, u, k):
        xb = x[self.dyn.xs]
        if self.form == "body":
            return self.w * self._body(xb, k, False, False)
        return self.w * self._running(xb, k)[0]

    def derivs(self, x, u, k):
        xb = x[self.dyn.xs]
        if self.form == "body":
            _, g, H = self._body(xb, k, False, True)
            lx, lxx = self._full(x, self.w * g, self.w * H, self._body_cols())
        else:
            _, g, H = self._running(xb, k)
            z = np.zeros((2, 2))
            lx, lxx = self._full(x, self.w * np.r_[g, 0.0, 0.0], self.w * np.block([[H, z], [z, z]]),
                                 self._root_cols())
        nu = len(u)
        return lx, np.zeros(nu), lxx, np.zeros((nu, nu)), np.zeros((nu, len(x)))

    def terminal(self, x, k):
        xb = x[self.dyn.xs]
        if self.form == "body":
            return self.w * self._body(xb, k, True, False)
        return self.w * (self._running(xb, k)[0] + self._tail(xb, k)[0])

    def terminal_derivs(self, x, k):
        xb = x[self.dyn.xs]
        if self.form == "body":
            _, g, H = self._body(xb, k, True, True)
            return self._full(x, self.w * g, self.w * H, self._body_cols())
        _, g, H = self._running(xb, k)
        _, gp, gv, Hpp, Hpv, Hvv = self._tail(xb, k)
        grads = self.w * np.r_[g + gp, gv]
        hess = self.w * np.block([[H + Hpp, Hpv], [Hpv.T, Hvv]])
        return self._full(x, grads, hess, self._root_cols())

    # -- per-step report -------------------------------------------------------------------------
    def measure(self, k: int, data) -> dict[str, float]:
        """The proximity sum at the simulated state (as the planner sees the obstacles, unweighted),
        and the smallest gap between any body geom and any obstacle sphere (metres; negative is a
        contact)."""
        if self.form == "body":
            cost = self._body(self.dyn.to_state(data.qpos), k, False, False)
        else:
            cost = self._terms(data.qpos[:2], k)[0]
        truth = self.truth[min(k, len(self.truth) - 1)]
        return {"proximity": cost, "clearanceM": clearance(self.dyn.mj, data, truth, self.radii)}


def clearance(mj, data, centres: np.ndarray, radii: np.ndarray) -> float:
    """Smallest distance between the body's capsules/spheres and spheres at ``centres`` (3D)."""
    if not len(radii):
        return float("inf")
    gap = np.inf
    for g in range(mj.ngeom):
        if mj.geom_bodyid[g] == 0:  # the ground
            continue
        c, half, rad = data.geom_xpos[g], half_lengths(mj, g), mj.geom_size[g, 0]
        axis = data.geom_xmat[g].reshape(3, 3)[:, 2]  # a capsule is a segment along its z
        t = np.clip((centres - c) @ axis, -half, half)
        d = np.linalg.norm(centres - (c + t[:, None] * axis), axis=1) - rad - radii
        gap = min(gap, float(d.min()))
    return gap


def factory(centres_at, radii: np.ndarray, objects: list[int] | None = None, **options):
    """A ``physics.tasks.TaskFactory``; ``centres_at(seconds)`` gives ``(K, J, 3)`` model-world centres at the
    planner's step times (seconds from the clip's start); ``objects`` as for :class:`ObstacleTask`."""

    def make(plan, ref_q):
        return ObstacleTask(plan, centres_at(plan.h * np.arange(len(ref_q))), radii, objects=objects, **options)

    return make
