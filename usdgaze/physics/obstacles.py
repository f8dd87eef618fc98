"""Moving obstacles (Eom et al. 2019, section 7): an exponential proximity cost on the root.

``c_tsk = sum_j exp(-|p_root - p_j|^2 / s_j^2)`` over the four obstacles nearest the root at each
step, ``w_tsk = 1`` (the paper's). The paper's two sub-windows: the optimized window follows the
root trajectory; a further ``lookahead`` window (the paper: 1.0 s optimized + 0.6 s) is costed on the
root extrapolated linearly from the last optimized state with its velocity held, so the terminal
cost sees obstacles beyond the window without optimizing over it.

Ours, where the paper leaves room (docs/physics.md):

* ``p_j``: with the eyes coupled (``physics.visuomotor``) it is the belief's mean before each solve,
  run forward at its estimated velocity (the optimizer's expected mean), and an obstacle not yet
  seen costs nothing; on the body-only controller the planner knows the obstacles' paths (the
  Han et al. 2016 setting the paper compares against).
* Distances are taken in the ground plane: the root's height says nothing about whether a sphere
  at knee or head height meets the body, and the root cannot dodge vertically.
* ``s_j`` is the obstacle's radius plus ``clearance`` (0.6 m: the arms reach ~0.35 m from the root
  in the ground plane, plus a margin): with ``s_j`` the radius alone the cost is ~exp(-4) where a
  25 cm sphere already touches the arms, too little against the tracking of the root. On the CMU
  walk, 0.35 m left 5-16 cm overlaps with the arms where 0.6 m cleared every run (docs/physics.md).
* "Four nearest" is the four largest terms (nearest relative to size), so the sum stays continuous
  when the set changes.

Derivatives are exact (the root position and velocity are state entries); the 2x2 Hessian block of
each term, indefinite near an obstacle, is given to DDP with its negative curvature dropped.
"""

from __future__ import annotations

import numpy as np

from usdgaze.physics.dynamics import MujocoBody

W_TSK = 1.0
NEAREST = 4
LOOKAHEAD_S = 0.6
CLEARANCE_M = 0.6


class ObstacleTask:
    """The obstacle task term over the planner's state (a ``ddp.Cost`` plus ``measure``)."""

    name = "obstacles"

    def __init__(self, dyn: MujocoBody, centres: np.ndarray, radii: np.ndarray, weight: float = W_TSK,
                 lookahead_s: float = LOOKAHEAD_S, clearance: float = CLEARANCE_M, nearest: int = NEAREST,
                 objects: list[int] | None = None) -> None:
        """``centres``: the true paths at the planner's steps (what is measured, and what the body-only
        planner knows); ``objects``: the obstacles' indices among the coupled loop's objects, whose
        belief then replaces the true paths inside the optimizer (-1: not an object, path known)."""
        self.dyn, self.w = dyn, float(weight)
        self.centres = np.asarray(centres, dtype=float)  # (K, J, 3) model world at the planner's steps
        self.truth = self.centres
        self.objects = objects
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        self.s2 = (self.radii + clearance) ** 2
        self.nearest = int(nearest)
        self.ahead = int(round(lookahead_s / dyn.h))
        nv = dyn.nv
        self._p = slice(0, 2)  # root position (ground plane) in the body state
        self._v = slice(nv, nv + 2)  # root linear velocity (MuJoCo's free joint: world frame)

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

    def _full(self, x, grads: np.ndarray, hess: np.ndarray):
        nx = len(x)
        lx, lxx = np.zeros(nx), np.zeros((nx, nx))
        s = self.dyn.xs.start
        idx = np.r_[s + 0, s + 1, s + self.dyn.nv, s + self.dyn.nv + 1]
        lx[idx] = grads
        lxx[np.ix_(idx, idx)] = hess
        return lx, lxx

    # -- ddp.Cost --------------------------------------------------------------------------------
    def l(self, x, u, k):
        return self.w * self._running(x[self.dyn.xs], k)[0]

    def derivs(self, x, u, k):
        _, g, H = self._running(x[self.dyn.xs], k)
        z = np.zeros((2, 2))
        lx, lxx = self._full(x, self.w * np.r_[g, 0.0, 0.0], self.w * np.block([[H, z], [z, z]]))
        nu = len(u)
        return lx, np.zeros(nu), lxx, np.zeros((nu, nu)), np.zeros((nu, len(x)))

    def terminal(self, x, k):
        xb = x[self.dyn.xs]
        return self.w * (self._running(xb, k)[0] + self._tail(xb, k)[0])

    def terminal_derivs(self, x, k):
        xb = x[self.dyn.xs]
        _, g, H = self._running(xb, k)
        _, gp, gv, Hpp, Hpv, Hvv = self._tail(xb, k)
        grads = self.w * np.r_[g + gp, gv]
        hess = self.w * np.block([[H + Hpp, Hpv], [Hpv.T, Hvv]])
        return self._full(x, grads, hess)

    # -- per-step report -------------------------------------------------------------------------
    def measure(self, k: int, data) -> dict[str, float]:
        """The proximity sum at the simulated root, and the smallest gap between any body geom and
        any obstacle sphere (metres; negative is a contact)."""
        cost, _, _ = self._terms(data.qpos[:2], k)  # as the planner sees them
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
        c, half, rad = data.geom_xpos[g], 0.0, mj.geom_size[g, 0]
        axis = data.geom_xmat[g].reshape(3, 3)[:, 2]
        if mj.geom_type[g] == 3:  # capsule: a segment of half-length size[1] along its z
            half = mj.geom_size[g, 1]
        t = np.clip((centres - c) @ axis, -half, half)
        d = np.linalg.norm(centres - (c + t[:, None] * axis), axis=1) - rad - radii
        gap = min(gap, float(d.min()))
    return gap


def factory(centres_at, radii: np.ndarray, objects: list[int] | None = None, **options):
    """A ``mpc.TaskFactory``; ``centres_at(seconds)`` gives ``(K, J, 3)`` model-world centres at the
    planner's step times (seconds from the clip's start); ``objects`` as for :class:`ObstacleTask`."""

    def make(plan, ref_q):
        return ObstacleTask(plan, centres_at(plan.h * np.arange(len(ref_q))), radii, objects=objects, **options)

    return make
