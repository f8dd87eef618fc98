"""The planner's cost (Eom et al. 6): w_trk c_trk + w_eng c_eng + w_uct c_uct + w_bnd c_bnd (+ task).

* c_trk: the gaze-chain offsets and their rates (x_fb - x_fb_ref, the reference being the base motion,
  i.e. zero offsets) plus the displacement of the head from its base position (the paper's torso
  up-vector term o_ub, root to head).
* c_eng = |u|^2 (running cost only).
* c_uct = sum_j w_j |sigma_j|^2 over the object slots (w_j: the object's importance).
* c_bnd: soft bounds. Our copy of the paper prints smax(x_hi - x) + smax(x - x_lo), which would
  penalise being *inside* the range; we implement the stated meaning, a penalty for *leaving* it:
  smax(x - x_hi) + smax(x_lo - x) for theta, psi (degrees) and zeta (mm), plus
  smax(|(theta', psi')| - B) in deg/s, with smax(y; gamma) = (sqrt(y^2 + gamma^2) + y) / 2.
* ``mode``: "uncertainty" (the paper's), "distance" (sum_j |p_ps - mu_p_j|^2 in place of c_uct, the
  paper's Figure 4a baseline) or "sequential" (the same distance to the one slot ``target``
  names, Yeo et al.'s one-after-the-other tracking, Figure 4b).

The Hessians are exact for the quadratic and smax terms and Gauss-Newton for the distances through
the point of sight. Every method works on stacked windows (``*_batch``) and per step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.vision import eye as eyemod
from usdgaze.vision.belief import SLOT

DEG = 180.0 / np.pi


@dataclass
class Weights:
    trk: float = 0.1
    eng: float = 1e-5
    uct: float = 1.0
    bnd: float = 0.1
    dist: float = 1.0
    head_pos: float = 10.0  # relative weight of the head-displacement part of c_trk (metres vs radians)
    offsets: float = 1.0  # relative weight of the chain offsets (radians) in c_trk: 1 is the paper's
    # w_trk on joint angles. Its body prices a held head turn the same way (the torques to turn a head,
    # at w_eng 1e-5, add little). 20 (tried) priced a 10 deg head turn (0.03-0.06 a step) at or above
    # all that a fixation saves (c_uct of a still object 0.041 fixated, 0.081 looked 2 m past): a sphere
    # 50 deg aside was held on 61 % of the frames of an idle clip (tests/test_attend_side.py).
    rate: float = 1.0  # relative weight of offset rates in c_trk
    gamma: float = 1.0
    u_scale: np.ndarray = field(default_factory=lambda: np.ones(0))
    # c_uct weighs [sigma_p, sigma_v, sigma_pv] by these before squaring; (1, h^2, h) reads velocities
    # per planner step, so the three entries share one unit (the coupled physics loop, physics.visuomotor)
    sigma_scale: np.ndarray = field(default_factory=lambda: np.ones(3))


def smax(y: np.ndarray, gamma: float):
    """Smoothed max(y, 0) and its first and second derivatives."""
    s = np.sqrt(y * y + gamma * gamma)
    return 0.5 * (s + y), 0.5 * (y / s + 1.0), 0.5 * gamma * gamma / s**3


class AttendCost:
    """The cost over a stacked [eye, body, belief] state; ``t0`` is the time (s) of step 0."""

    def __init__(self, stack, sight, importance: np.ndarray, weights: Weights | None = None,
                 mode: str = "uncertainty", target: int = 0, t0: float = 0.0, track_body: bool = True) -> None:
        """``track_body=False``: leave out the kinematic body's terms (its offsets, their bounds and the head
        displacement), for a body whose tracking is its own cost (the MuJoCo body's ``BodyTracking``)."""
        self.stack, self.sight, self.w = stack, sight, weights or Weights()
        self.track_body = track_body
        self.eye, self.body, self.belief = stack["eye"], stack["body"], stack["belief"]
        self.imp = np.asarray(importance, float)
        self.mode, self.target, self.t0 = mode, target, t0
        self.h = self.eye.h

    # -- pieces ---------------------------------------------------------------------------------
    def _state_terms(self, X, k0, derivs: bool):
        """Cost of the state part per row; with derivs also lx (N,NX) and lxx (N,NX,NX)."""
        w, N, nx = self.w, len(X), self.stack.nx
        ex = self.eye.xs
        lx = np.zeros((N, nx)) if derivs else None
        lxx = np.zeros((N, nx, nx)) if derivs else None
        J = pps = None
        if self.track_body:
            c, J, pps = self._body_terms(X, k0, derivs, lx, lxx)
        else:
            c = np.zeros(N)
        if pps is None and (derivs and self.mode != "uncertainty"):
            pps, _, _, J, _, _ = self.sight.jacobian(X, k0)
        elif pps is None and self.mode != "uncertainty":
            pps = self.sight.points(X, k0)[0]
        # soft eye-range bounds (degrees for the angles, mm for zeta)
        e = X[:, ex]
        scale = np.array([DEG, DEG, 1.0])
        for sign, edge in ((1.0, eyemod.HI), (-1.0, eyemod.LO)):
            v, d1, d2 = smax(sign * (e - edge) * scale, w.gamma)
            c = c + w.bnd * v.sum(1)
            if derivs:
                lx[:, ex] += w.bnd * d1 * sign * scale
                ii = np.arange(ex.start, ex.stop)
                lxx[:, ii, ii] += w.bnd * d2 * scale**2
        c = c + self._attention(X, derivs, lx, lxx, J, pps, k0)
        return c, lx, lxx

    def _body_terms(self, X, k0, derivs, lx, lxx):
        """The kinematic body's tracking (offsets, rates, head displacement) and its soft bounds."""
        w, N = self.w, len(X)
        bx = self.body.xs
        nq = self.body.n
        qb = X[:, bx]
        c = w.trk * w.offsets * (np.sum(qb[:, :nq] ** 2, 1) + w.rate * np.sum(qb[:, nq:] ** 2, 1))
        if derivs:
            wv = np.r_[np.ones(nq), np.full(nq, w.rate)] * w.trk * w.offsets
            lx[:, bx] = 2 * wv * qb
            idx = np.arange(bx.start, bx.stop)
            lxx[:, idx, idx] = 2 * wv
        ks = self.body.base.at(k0 + np.arange(N))
        J = None
        if derivs:
            pps, p, R, J, dp, dR = self.sight.jacobian(X, k0)
        else:
            pps, p, R = self.sight.points(X, k0)
        dh = p - self.body.base.eyes[ks]
        c = c + w.trk * w.head_pos * np.sum(dh * dh, 1)
        if derivs:
            g = 2 * w.trk * w.head_pos
            lx += g * np.einsum("ni,nix->nx", dh, dp)
            lxx += g * np.einsum("nix,niy->nxy", dp, dp)
        # soft bounds of the body offsets, in degrees
        if hasattr(self.body, "LO"):
            qd = qb[:, :nq]
            for sign, edge in ((1.0, self.body.HI), (-1.0, self.body.LO)):
                v, d1, d2 = smax(sign * (qd - edge) * DEG, w.gamma)
                c = c + w.bnd * v.sum(1)
                if derivs:
                    lx[:, bx.start:bx.start + nq] += w.bnd * d1 * sign * DEG
                    ii = np.arange(bx.start, bx.start + nq)
                    lxx[:, ii, ii] += w.bnd * d2 * DEG**2
        if hasattr(self.body, "HEAD_SPEED"):
            c = c + self._head_speed(qb[:, nq:], derivs, lx, lxx)
        return c, J, pps

    def _head_speed(self, qd, derivs, lx, lxx):
        """w_bnd smax(|head rate| - B_head) in deg/s, as the eye's speed bound: the head turns at the
        spine's and the neck's yaw rates added, and pitch likewise (columns spine y/p, neck y/p)."""
        w = self.w
        rate = self.body.head_rate(qd) * DEG
        speed = np.sqrt(np.sum(rate * rate, 1) + 1e-9)
        v, d1, d2 = smax(speed - self.body.HEAD_SPEED * DEG, w.gamma)
        if derivs:
            n_ = rate / speed[:, None]
            hess = (d2[:, None, None] * n_[:, :, None] * n_[:, None, :]
                    + d1[:, None, None] * (np.eye(2) - n_[:, :, None] * n_[:, None, :]) / speed[:, None, None])
            i0 = self.body.xs.start + self.body.n  # the rates' columns
            for a in (0, 2):  # d head_rate / d qd is [I I]: spine and neck columns alike
                lx[:, i0 + a:i0 + a + 2] += (w.bnd * d1)[:, None] * n_ * DEG
                for b in (0, 2):
                    lxx[:, i0 + a:i0 + a + 2, i0 + b:i0 + b + 2] += w.bnd * hess * DEG**2
        return w.bnd * v

    def _attention(self, X, derivs, lx, lxx, J, pps, k0):
        w, n = self.w, self.belief.n
        Bx = X[:, self.belief.xs].reshape(len(X), n, SLOT)
        if self.mode == "uncertainty":
            s = Bx[..., 6:9]
            sc = np.asarray(w.sigma_scale, float)
            scaled = s * sc
            c = w.uct * np.einsum("s,nsi->n", self.imp, scaled * scaled)
            if derivs:
                for j in range(n):
                    cols = slice(self.belief.xs.start + SLOT * j + 6, self.belief.xs.start + SLOT * j + 9)
                    lx[:, cols] += 2 * w.uct * self.imp[j] * scaled[:, j] * sc
                    ii = np.arange(cols.start, cols.stop)
                    lxx[:, ii, ii] += 2 * w.uct * self.imp[j] * sc * sc
            return c
        sel = np.ones((len(X), n))
        if self.mode == "sequential":
            sel = np.broadcast_to((np.arange(n) == self.target).astype(float), (len(X), n))
        res = pps[:, None, :] - Bx[..., :3]
        c = w.dist * np.einsum("ns,nsi->n", sel, res * res)
        if derivs:
            for j in range(n):
                Jj = J.copy()
                c0 = self.belief.xs.start + SLOT * j
                Jj[:, :, c0:c0 + 3] -= np.eye(3)
                g = 2 * w.dist * sel[:, j]
                lx += g[:, None] * np.einsum("ni,nix->nx", res[:, j], Jj)
                lxx += g[:, None, None] * np.einsum("nix,niy->nxy", Jj, Jj)
        return c

    def _control_terms(self, U, k0, derivs: bool):
        w, N, nu = self.w, len(U), self.stack.nu
        us = w.u_scale if len(w.u_scale) == nu else np.ones(nu)
        c = w.eng * np.sum(us * U * U, 1)
        ue = U[:, self.eye.us][:, :2] * DEG
        speed = np.sqrt(np.sum(ue * ue, 1) + 1e-9)
        bound = eyemod.speed_bound(self.t0 + (k0 + np.arange(N)) * self.h) * DEG
        v, d1, d2 = smax(speed - bound, w.gamma)
        c = c + w.bnd * v
        if not derivs:
            return c, None, None
        lu = 2 * w.eng * us * U
        luu = np.zeros((N, nu, nu))
        i = np.arange(nu)
        luu[:, i, i] = 2 * w.eng * us
        n_ = ue / speed[:, None]  # d speed / d ue
        e0 = self.eye.us.start
        lu[:, e0:e0 + 2] += (w.bnd * d1)[:, None] * n_ * DEG
        hess = (d2[:, None, None] * n_[:, :, None] * n_[:, None, :]
                + d1[:, None, None] * (np.eye(2) - n_[:, :, None] * n_[:, None, :]) / speed[:, None, None])
        luu[:, e0:e0 + 2, e0:e0 + 2] += w.bnd * hess * DEG**2
        return c, lu, luu

    # -- the ddp.Cost protocol ------------------------------------------------------------------
    def total_batch(self, X, U, k0):
        """Running costs of X[:N], U plus the terminal cost of X[N], with one pass over the states."""
        state = self._state_terms(X, k0, False)[0]
        return float(np.sum(state) + np.sum(self._control_terms(U, k0, False)[0]))

    def cost_batch(self, X, U, k0):
        return self._state_terms(X, k0, False)[0] + self._control_terms(U, k0, False)[0]

    def derivs_batch(self, X, U, k0):
        _, lx, lxx = self._state_terms(X, k0, True)
        _, lu, luu = self._control_terms(U, k0, True)
        return lx, lu, lxx, luu, np.zeros((len(X), self.stack.nu, self.stack.nx))

    def l(self, x, u, k):
        return float(self.cost_batch(x[None], u[None], k)[0])

    def derivs(self, x, u, k):
        return tuple(a[0] for a in self.derivs_batch(x[None], u[None], k))

    def terminal(self, x, k):
        return float(self._state_terms(x[None], k, False)[0][0])

    def terminal_derivs(self, x, k):
        _, lx, lxx = self._state_terms(x[None], k, True)
        return lx[0], lxx[0]
