"""The belief over objects (Eom et al. 4.3, appendix A): one Kalman filter per object.

Object state x = [p, v]; process x' = F x + y + delta, F = [[I, hI], [0, I]], y = [0, h a] with a
the gravity for ballistic objects (0 for others), delta ~ N(0, Q). Observation z = p + rho,
rho ~ N(0, r I). Every covariance block stays a multiple of I, so each filter keeps the paper's
3-vector sigma = [sigma_p, sigma_v, sigma_pv] and the update is scalar per object.

Process noise. The paper writes Q = alpha I with alpha = 0.2 and h = 0.02-0.03 s. We read alpha as
the noise *per second* of a continuous process, Q = alpha h I a step (``VisionParams.q``), so that its
behaviour does not change with h. Read literally, as alpha I added every step, with r < 1 an unwatched
object's sigma_p reaches its fixed point in about three steps (0.17, 0.29, 0.34, 0.36 at alpha 0.2):
its uncertainty never keeps growing, switching between objects buys nothing, and the paper's
Figure 4c cannot arise (``per_second=False`` keeps that reading; docs/attend.md has the numbers).

Observation noise r grows with the distance D from the point of sight to the object:
r = r0 + 1 - exp(-D / eta), with D smoothed at 0 (sqrt(D^2 + eps^2) - eps) so it is twice
differentiable and r0 keeping the gain finite; the paper's formula is partly garbled in our copy, this
is its legible part: 0 at the fovea, rising to 1 far from it, eta the fovea constant.

Field of view. The paper's -60..60 deg is "the character's field of view", "the human's field of
view for binocular vision" (Henson 2000): measured about the head's forward from the eyes' midpoint
(docs/attend.md says why not the line of sight: the binocular field's edges are the nose's and the
brows', which stay with the head when the eyes turn). An object is in view when any part of it is:
its angle off the head's forward, less its angular radius ``asin(radius / distance)``
(``angular_radius``; radius 0 is a point), is within 60 deg (``in_view``). Outside it there is no
observation: the simulation skips the update, the planner adds ``R_OUT`` smoothly, (1 - vis) R_OUT
with vis a logistic of the centre's angle (``visibility``: the planner's model keeps the point; with
the radius in it as well, the planner's cost moved for a ball in view throughout and a bench catch
throw fell, docs/physics.md).

Units. The paper gives r in [0, 1) and alpha as bare numbers. Covariances here are kept in units of
``unit_m`` squared (0.1 m: r = 1 is an observation error of 10 cm standard deviation): the
recursions for sigma and the gain K = sp/(sp + r) do not depend on the unit, only the drawn
observation z = p + unit_m sqrt(r) N(0, I) does, so the paper's numbers keep their meaning relative
to each other. Read in metres, r would be a 1 m error, which keeps a fixating eye from ever settling
on a ball.

Planning uses the expected mean mu' = F mu + y (deterministic); simulation draws z with a seeded
generator and applies the full update (``kalman_update``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.planning.compose import Part

FOV = np.radians(60.0)  # half the field of view, about the head's forward
COS_FOV = np.cos(FOV)
VIS_WIDTH = 0.03  # logistic width in cos(angle): ~ +-3 deg around the edge of the field of view
R_OUT = 50.0
R0 = 1e-4
GRAVITY = 9.81
EPS_D = 0.02  # metres: smooths |p_ps - p| at 0 so r is twice differentiable
SLOT = 9  # mu_p (3), mu_v (3), sigma_p, sigma_v, sigma_pv


@dataclass
class VisionParams:
    alpha: float = 0.2
    eta: float = 0.3  # fovea constant, metres
    h: float = 0.025
    unit_m: float = 0.1  # the length unit of the belief's covariance numbers (see the module docstring)
    per_second: bool = True  # alpha is the process noise per second: Q = alpha h I a step (module docstring)

    @property
    def q(self) -> float:
        """The process noise added to each covariance block per step."""
        return self.alpha * self.h if self.per_second else self.alpha


def predict_cov(s: np.ndarray, alpha: float, h: float) -> np.ndarray:
    """A priori [sp, sv, spv] (rows of s) and the constant Jacobian M."""
    sp, sv, spv = s[..., 0], s[..., 1], s[..., 2]
    return np.stack([sp + 2 * h * spv + h * h * sv + alpha, sv + alpha, spv + h * sv], -1)


def predict_jac(h: float) -> np.ndarray:
    return np.array([[1.0, h * h, 2 * h], [0.0, 1.0, 0.0], [0.0, h, 1.0]])


def update_cov(sb: np.ndarray, r: np.ndarray):
    """A posteriori sigma from the a priori sb and noise r; d/dsb (..., 3, 3) and d/dr (..., 3)."""
    p, v, pv = sb[..., 0], sb[..., 1], sb[..., 2]
    S = p + r
    S2 = S * S
    out = np.stack([p * r / S, v - pv * pv / S, pv * r / S], -1)
    z = np.zeros_like(p)
    d_sb = np.stack([np.stack([r * r / S2, z, z], -1),
                     np.stack([pv * pv / S2, np.ones_like(p), -2 * pv / S], -1),
                     np.stack([-pv * r / S2, z, r / S], -1)], -2)
    d_r = np.stack([p * p / S2, pv * pv / S2, pv * p / S2], -1)
    return out, d_sb, d_r


def noise(pps: np.ndarray, pos: np.ndarray, eta: float):
    """r0 + 1 - exp(-D/eta) with D the distance smoothed at 0, and its gradient w.r.t. the point of sight."""
    diff = pps - pos
    ds = np.sqrt(np.sum(diff * diff, -1) + EPS_D * EPS_D)
    e = np.exp(-(ds - EPS_D) / eta)
    return R0 + 1.0 - e, (e / (eta * ds))[..., None] * diff


def angular_radius(dist: np.ndarray, radius) -> np.ndarray:
    """asin(radius / dist): the half-angle a sphere subtends (pi/2 with the eyes inside it)."""
    r = np.asarray(radius, float)
    return np.arcsin(np.clip(r / np.maximum(dist, 1e-9), 0.0, 1.0))


def visibility(pos: np.ndarray, eyes: np.ndarray, forward: np.ndarray):
    """Smooth in-view weight, and its gradients w.r.t. pos (= -w.r.t. eyes) and forward."""
    v = pos - eyes
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    n = np.maximum(n, 1e-9)
    c = np.sum(v * forward, -1, keepdims=True) / n
    s = 1.0 / (1.0 + np.exp(-(c[..., 0] - COS_FOV) / VIS_WIDTH))
    ds_dc = (s * (1 - s) / VIS_WIDTH)[..., None]
    return s, ds_dc * (forward / n - c * v / n**2), ds_dc * v / n


def in_view(pos: np.ndarray, eyes: np.ndarray, forward: np.ndarray, radius=0.0) -> np.ndarray:
    """The hard test the simulation uses: some part of the sphere (centre ``pos``, ``radius``; 0 a point)
    within 60 deg of the head's ``forward`` seen from ``eyes``."""
    v = pos - eyes
    n = np.maximum(np.linalg.norm(v, axis=-1), 1e-9)
    c = np.sum(v * forward, -1) / n
    return c >= np.cos(FOV + angular_radius(n, radius))


def kalman_update(mu: np.ndarray, s: np.ndarray, z: np.ndarray | None, r: float, accel: np.ndarray,
                  params: VisionParams):
    """One filter step for one object; z None means not observed (prediction only)."""
    h = params.h
    mp = mu[:3] + h * mu[3:]
    mv = mu[3:] + h * accel
    sb = predict_cov(s, params.q, h)
    if z is None:
        return np.concatenate([mp, mv]), sb
    S = sb[0] + r
    m = z - mp
    s_new, _, _ = update_cov(sb, np.asarray(r))
    return np.concatenate([mp + sb[0] / S * m, mv + sb[2] / S * m]), s_new


class Belief(Part):
    """The planner's belief over ``n`` object slots: expected mean, covariance through the sight."""

    name = "belief"
    passive = True  # no controls, read by no other part: rolled out after the eye and body (compose.Stacked)

    def __init__(self, n: int, accel: np.ndarray, params: VisionParams, sight) -> None:
        self.n, self.accel, self.params, self.sight = n, np.asarray(accel, float).reshape(n, 3), params, sight
        self.nx, self.nu = SLOT * n, 0

    def _split(self, X):
        B = X[:, self.xs].reshape(len(X), self.n, SLOT)
        return B[..., :3], B[..., 3:6], B[..., 6:9]

    def _r(self, X, k0, with_jac: bool):
        mp, _, s = self._split(X)
        if with_jac:
            pps, p, R, J, dp, dR = self.sight.jacobian(X, k0)
        else:
            pps, p, R = self.sight.points(X, k0)
        r_d, g_pps = noise(pps[:, None], mp, self.params.eta)
        vis, g_pos, g_fwd = visibility(mp, p[:, None], R[:, None, :, 0])
        r = r_d + (1 - vis) * R_OUT
        if not with_jac:
            return s, r
        # dr/dx (N, n, NX): through the point of sight, the object estimate, the eyes and the head forward
        dr = np.einsum("nsi,nix->nsx", g_pps, J)
        dr -= R_OUT * (np.einsum("nsi,nix->nsx", -g_pos, dp) + np.einsum("nsi,nix->nsx", g_fwd, dR[:, :, 0]))
        d_pos = -g_pps - R_OUT * g_pos
        cols = self.xs.start + SLOT * np.arange(self.n)[:, None] + np.arange(3)
        for j in range(self.n):
            dr[:, j, cols[j]] += d_pos[:, j]
        return s, r, dr

    def rollout(self, X: np.ndarray, k0: int) -> np.ndarray:
        """Belief states along a window whose other parts are already in X (row 0: the start)."""
        h, a, n = self.params.h, self.params.q, self.n
        N = len(X)
        B0 = X[0, self.xs].reshape(n, SLOT)
        i = np.arange(N)[:, None, None]
        mv = B0[None, :, 3:6] + i * h * self.accel[None]
        mp = B0[None, :, :3] + i * h * B0[None, :, 3:6] + h * h * (i * (i - 1) / 2) * self.accel[None]
        pps, p, R = self.sight.points(X, k0)
        r = noise(pps[:, None], mp, self.params.eta)[0]
        vis = visibility(mp, p[:, None], R[:, None, :, 0])[0]
        r = r + (1 - vis) * R_OUT
        # The covariance recursion is sequential and each object's is a few scalars: plain Python floats
        # do the same IEEE operations in the same order as numpy would, without a ufunc call per operation.
        S = np.empty((n, N, 3))
        h2, h_2 = h * h, 2 * h
        for j, (rj, s0) in enumerate(zip(r.T.tolist(), B0[:, 6:9].tolist())):
            sp_, sv_, spv_ = s0
            rows = [s0]
            for rk in rj[: N - 1]:
                pb = sp_ + h_2 * spv_ + h2 * sv_ + a
                cb = spv_ + h * sv_
                den = pb + rk
                sp_, sv_, spv_ = pb * rk / den, sv_ + a - cb * cb / den, cb * rk / den
                rows.append((sp_, sv_, spv_))
            S[j] = rows
        return np.concatenate([mp, mv, S.transpose(1, 0, 2)], -1).reshape(N, -1)

    def step(self, x, u, k):
        h, a = self.params.h, self.params.q
        B = x[self.xs].reshape(self.n, SLOT)
        mp, mv, s = B[:, :3], B[:, 3:6], B[:, 6:9]
        pps, p, R = self.sight.point(x, k)
        r = noise(pps, mp, self.params.eta)[0]
        v = mp - p
        cosang = (v @ R[:, 0]) / np.maximum(np.sqrt(np.einsum("si,si->s", v, v)), 1e-9)
        r = r + R_OUT * (1.0 - 1.0 / (1.0 + np.exp(-(cosang - COS_FOV) / VIS_WIDTH)))
        sp = s[:, 0] + 2 * h * s[:, 2] + h * h * s[:, 1] + a
        sv = s[:, 1] + a
        spv = s[:, 2] + h * s[:, 1]
        S = sp + r
        out = np.empty((self.n, SLOT))
        out[:, :3] = mp + h * mv
        out[:, 3:6] = mv + h * self.accel
        out[:, 6] = sp * r / S
        out[:, 7] = sv - spv * spv / S
        out[:, 8] = spv * r / S
        return out.ravel()

    def _next(self, X, k0):
        h = self.params.h
        mp, mv, _ = self._split(X)
        s, r = self._r(X, k0, with_jac=False)
        s_new, _, _ = update_cov(predict_cov(s, self.params.q, h), r)
        out = np.concatenate([mp + h * mv, mv + h * self.accel, s_new], -1)
        return out.reshape(len(X), -1)

    def linearize(self, x, u, k):
        fx, fu = self.linearize_batch(x[None], u[None], k)
        return fx[0], fu[0]

    def linearize_batch(self, X, U, k0):
        h, N = self.params.h, len(X)
        s, r, dr = self._r(X, k0, with_jac=True)
        sb = predict_cov(s, self.params.q, h)
        _, d_sb, d_r = update_cov(sb, r)
        fx = np.zeros((N, self.n, SLOT, self.stack.nx))
        M = predict_jac(h)
        for j in range(self.n):
            c0 = self.xs.start + SLOT * j
            fx[:, j, :6, c0:c0 + 6] = np.block([[np.eye(3), h * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
            fx[:, j, 6:, :] = d_r[:, j, :, None] * dr[:, j, None, :]
            fx[:, j, 6:, c0 + 6:c0 + 9] += d_sb[:, j] @ M
        return fx.reshape(N, self.nx, self.stack.nx), np.zeros((N, self.nx, self.stack.nu))
