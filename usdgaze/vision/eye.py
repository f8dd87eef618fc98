"""The eye model (Eom et al. 4.1-4.2): pose e = [theta, psi, zeta], speed limits, point of sight.

theta (azimuth, + toward the character's left) and psi (elevation, + up) are radians in the head
frame; zeta is the focal length in mm. The point-of-sight distance is d = s * zeta / (1 - zeta/17)
with the scale s = 1/17 m per mm, i.e. d = x / (1 - x) metres for x = zeta/17: zeta = 3.4 mm looks
0.25 m away (near fixation, the planner's lower bound ``ZETA_LO``), 8.5 mm 1 m, 15.3 mm 9 m, and
17 mm is infinity. The planner's range stops at ``ZETA_HI`` = 16.5 mm (d = 33 m, "infinity" for a shot: beyond it parallax is nil and d's
derivative, which grows as 1/(1 - zeta/17)^2, would make the optimization stiff); d itself is
clamped at ``ZETA_CAP`` so it stays finite whatever the state.

Speed: |(theta', psi')| <= B with B = 800 deg/s inside a saccade window and 100 deg/s (pursuit)
outside; windows repeat every 400 ms: 200 ms in which a saccade may run, then 200 ms of recharge
(``speed_bound``). The planner sees these as soft bounds (``costs``); the simulated eye clips to
them (``limit``), so the written motion never exceeds them.
"""

from __future__ import annotations

import numpy as np

from usdgaze.planning.compose import LinearPart

THETA = np.radians(44.2)
PSI_LO, PSI_HI = np.radians(-47.1), np.radians(27.7)
ZETA_INF = 17.0
ZETA_HI = 16.5
ZETA_CAP = 17.0 * 0.99
SCALE_M_PER_MM = 1.0 / 17.0
ZETA_LO = 3.4  # mm: d = 0.25 m, the near point of fixation
LO = np.array([-THETA, PSI_LO, ZETA_LO])
HI = np.array([THETA, PSI_HI, ZETA_HI])
SACCADE_SPEED = np.radians(800.0)
PURSUIT_SPEED = np.radians(100.0)
SACCADE_WINDOW_S = 0.2
RECHARGE_S = 0.2


def distance(zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Point-of-sight distance (m) and its derivative d d / d zeta."""
    z = np.clip(zeta, 0.0, ZETA_CAP)
    inside = (zeta > 0.0) & (zeta < ZETA_CAP)
    den = 1.0 - z / ZETA_INF
    return SCALE_M_PER_MM * z / den, np.where(inside, SCALE_M_PER_MM / den**2, 0.0)


def zeta_for(d: np.ndarray) -> np.ndarray:
    """The focal length that puts the point of sight at distance d (m)."""
    x = np.asarray(d) / (1.0 + np.asarray(d))
    return np.clip(ZETA_INF * x, ZETA_LO, ZETA_HI)


def speed_bound(t: np.ndarray) -> np.ndarray:
    """B(t), rad/s: saccade speed in the first 200 ms of every 400 ms, pursuit speed otherwise."""
    # A step's time is k * h in floating point: 40 * 0.025 % 0.4 is 0.19999999999999996, which made
    # the first step of some recharge windows (1.0 s, 1.8 s, ...) a saccade step. A nanosecond settles it.
    phase = np.mod(np.asarray(t) + 1e-9, SACCADE_WINDOW_S + RECHARGE_S)
    return np.where(phase < SACCADE_WINDOW_S, SACCADE_SPEED, PURSUIT_SPEED)


def limit(e: np.ndarray, de: np.ndarray, bound: float, h: float) -> np.ndarray:
    """The eye velocity actually applied: speed clipped to ``bound``, and stopping at the range."""
    de = np.array(de, dtype=float)
    speed = np.hypot(de[0], de[1])
    if speed > bound:
        de[:2] *= bound / speed
    nxt = np.clip(e + h * de, LO, HI)
    return (nxt - e) / h


def direction_local(e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaze direction in head axes (forward, left, up) for rows of e, and d/dtheta, d/dpsi."""
    th, ps = e[..., 0], e[..., 1]
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(ps), np.sin(ps)
    d = np.stack([cp * ct, cp * st, sp], -1)
    d_th = np.stack([-cp * st, cp * ct, np.zeros_like(th)], -1)
    d_ps = np.stack([-sp * ct, -sp * st, cp], -1)
    return d, d_th, d_ps


def angles_for(direction_head: np.ndarray) -> np.ndarray:
    """(theta, psi) that look along a direction given in head axes."""
    v = direction_head / np.linalg.norm(direction_head, axis=-1, keepdims=True)
    return np.stack([np.arctan2(v[..., 1], v[..., 0]), np.arcsin(np.clip(v[..., 2], -1, 1))], -1)


class Eye(LinearPart):
    """State e (3), control e' (3): e_{k+1} = e_k + h e'_k (the paper's eye update)."""

    name = "eye"
    nx = nu = 3

    def __init__(self, h: float) -> None:
        self.h = float(h)

    def step(self, x, u, k):
        return x[self.xs] + self.h * u[self.us]

    def linear_rows(self):
        fx = np.zeros((3, self.stack.nx))
        fu = np.zeros((3, self.stack.nu))
        fx[:, self.xs] = np.eye(3)
        fu[:, self.us] = self.h * np.eye(3)
        return fx, fu


class Sight:
    """The point of sight p_ps = p_eyes + d(zeta) R_head dir(theta, psi) over the stacked state."""

    def __init__(self, eye: Eye, body) -> None:
        self.eye, self.body = eye, body
        self._cache: tuple | None = None

    def _key(self, X: np.ndarray) -> bytes:
        cols = np.r_[np.arange(self.eye.xs.start, self.eye.xs.stop), np.arange(self.body.xs.start, self.body.xs.stop)]
        return np.ascontiguousarray(X[:, cols]).tobytes()

    def points(self, X: np.ndarray, k0: int):
        """Point of sight, eye midpoint and head axes for rows of X (steps k0, k0+1, ...).

        The last result is kept: a rollout, its cost and its terminal cost ask for the same rows (or
        leading rows of them) in turn, and only the eye and body columns matter.
        """
        key = self._key(X)
        c = self._cache
        if c is not None and c[0] == k0 and c[1][: len(key)] == key:
            n = len(X)
            return c[2][:n], c[3][:n], c[4][:n]
        out = self._points(X, k0)
        self._cache = (k0, key) + out
        return out

    def _poses(self, X: np.ndarray, k0: int):
        if hasattr(self.body, "head_pose_batch"):
            return self.body.head_pose_batch(X, k0)
        poses = [self.body.head_pose(x, k0 + i) for i, x in enumerate(X)]  # the BodyPart protocol minimum
        return np.stack([p for p, _ in poses]), np.stack([R for _, R in poses])

    def _jacobians(self, X: np.ndarray, k0: int):
        if hasattr(self.body, "head_jacobian_batch"):
            return self.body.head_jacobian_batch(X, k0)
        jac = [self.body.head_pose_jacobian(x, k0 + i) for i, x in enumerate(X)]
        return np.stack([a for a, _ in jac]), np.stack([b for _, b in jac])

    def _points(self, X: np.ndarray, k0: int):
        p, R = self._poses(X, k0)
        e = X[:, self.eye.xs]
        d, _ = distance(e[:, 2])
        dl, _, _ = direction_local(e)
        return p + d[:, None] * np.einsum("nij,nj->ni", R, dl), p, R

    def point(self, x: np.ndarray, k: int):
        """Single-step ``points``: (p_ps, p_eyes, R_head)."""
        p, R = self.body.head_pose(x, k)
        th, ps, ze = x[self.eye.xs]
        d = float(distance(np.array(ze))[0])
        cp = np.cos(ps)
        return p + d * (R @ np.array([cp * np.cos(th), cp * np.sin(th), np.sin(ps)])), p, R

    def jacobian(self, X: np.ndarray, k0: int):
        """(pps, p, R, dpps (N,3,NX), dp (N,3,NX), dR (N,3,3,NX))."""
        p, R = self._poses(X, k0)
        dp, dR = self._jacobians(X, k0)
        e = X[:, self.eye.xs]
        d, dd = distance(e[:, 2])
        dl, dl_th, dl_ps = direction_local(e)
        z = np.einsum("nij,nj->ni", R, dl)
        pps = p + d[:, None] * z
        J = dp + d[:, None, None] * np.einsum("nijx,nj->nix", dR, dl)
        i0 = self.eye.xs.start
        J[:, :, i0] += d[:, None] * np.einsum("nij,nj->ni", R, dl_th)
        J[:, :, i0 + 1] += d[:, None] * np.einsum("nij,nj->ni", R, dl_ps)
        J[:, :, i0 + 2] += dd[:, None] * z
        return pps, p, R, J, dp, dR
