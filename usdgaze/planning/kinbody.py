"""The kinematic body: second-order offsets of the gaze chain on top of the base motion.

Four offset angles q = [spine yaw, spine pitch, neck yaw, neck pitch] (radians), each pair a world
rotation G(yaw, pitch) = Rot(up, yaw) Rot(left_k, pitch) about that joint's pivot, where ``left_k``
is the character's horizontal left at step k. With the base motion's pivots P_s (upper spine),
P_n (neck), eye midpoint P_e and head axes Rh = [forward, left, up] (columns, world):

    p_eye = P_s + G_s (P_n - P_s) + G_n G_s (P_e - P_n),     R_head = G_n G_s Rh.

State [q, qd], control qdd (``SecondOrder``); the head pose and its Jacobian are closed form.
Steps past the end of the base motion hold its last frame (windows run past the clip's end).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.planning.compose import SecondOrder


@dataclass
class BaseChain:
    """The base motion sampled at planner steps: pivots, eye midpoint, head axes, left, up."""

    spine: np.ndarray  # (K, 3)
    neck: np.ndarray  # (K, 3)
    eyes: np.ndarray  # (K, 3)
    head_axes: np.ndarray  # (K, 3, 3) columns forward, left, up
    left: np.ndarray  # (K, 3) horizontal character left
    up: np.ndarray  # (3,)

    def at(self, k: np.ndarray) -> np.ndarray:
        return np.clip(k, 0, len(self.spine) - 1)


def _skew(a: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) cross-product matrices."""
    z = np.zeros(a.shape[:-1])
    return np.stack([np.stack([z, -a[..., 2], a[..., 1]], -1),
                     np.stack([a[..., 2], z, -a[..., 0]], -1),
                     np.stack([-a[..., 1], a[..., 0], z], -1)], -2)


def _rot(axis_skew: np.ndarray, t: np.ndarray) -> np.ndarray:
    s, c = np.sin(t)[..., None, None], np.cos(t)[..., None, None]
    return np.eye(3) + s * axis_skew + (1 - c) * (axis_skew @ axis_skew)


class KinematicBody(SecondOrder):
    """Gaze-chain offsets as a ``BodyPart`` for the stacked dynamics.

    ``LO``/``HI``: the offsets' range (radians): upper spine yaw +-35, pitch +-25 deg; neck yaw +-60,
    pitch +-40 deg on top of the base motion (soft bounds in the cost, clipped in simulation).
    """

    n_dof = 4
    LO = np.radians([-35.0, -25.0, -60.0, -40.0])
    HI = np.radians([35.0, 25.0, 60.0, 40.0])
    # The head's speed from the offsets (spine and neck turn about the same axes, so their rates add),
    # bounded as the eye's: a soft cost for the planner, clipped in simulation (vision.loop). Eom et al.
    # bound only the eyes; their body's inertia keeps its head slow, and a double integrator priced at
    # w_eng 1e-5 is not: a sphere coming into view 60 deg aside during the eye's 100 deg/s recharge was
    # taken by the head at 1145 deg/s (51 deg out in 50 ms, most of it back once the eyes could
    # saccade), as a new track's velocity variance (sigma_v^2 ~ 1e4 in c_uct) outbids any soft bound at
    # w_bnd 0.1. Head peak velocity grows with the gaze shift's amplitude, to a few hundred deg/s at
    # most in the largest shifts (Freedman & Sparks 1997 in monkeys; lower in humans). The sources
    # give no figure for it (LEAP's 75 deg/s is a base speed): 300 is assumed, the top of that range.
    HEAD_SPEED = np.radians(300.0)

    @staticmethod
    def head_rate(qd: np.ndarray) -> np.ndarray:
        """The head's (yaw, pitch) rate ``(..., 2)`` from the offsets' rates ``(..., 4)`` (spine yaw and
        pitch, neck yaw and pitch): the two turn about the same axes, so their rates add."""
        return qd[..., :2] + qd[..., 2:4]

    def __init__(self, base: BaseChain, h: float, name: str = "body") -> None:
        super().__init__(self.n_dof, h, name)
        self.base = base
        self._up_x = _skew(base.up)
        # per-step constants of the single-step path (the rollout calls it once per step)
        self._lx = _skew(base.left)
        self._lx2 = self._lx @ self._lx
        self._ux2 = self._up_x @ self._up_x
        self._a = base.neck - base.spine
        self._c = base.eyes - base.neck

    def _pieces(self, Q: np.ndarray, ks: np.ndarray):
        b = self.base
        ks = b.at(ks)
        lx = self._lx[ks]  # (N,3,3)
        ux = np.broadcast_to(self._up_x, lx.shape)
        ry_s, rp_s = _rot(ux, Q[:, 0]), _rot(lx, Q[:, 1])
        ry_n, rp_n = _rot(ux, Q[:, 2]), _rot(lx, Q[:, 3])
        gs, gn = ry_s @ rp_s, ry_n @ rp_n
        dgs = np.stack([ux @ gs, ry_s @ lx @ rp_s], 1)  # (N,2,3,3)
        dgn = np.stack([ux @ gn, ry_n @ lx @ rp_n], 1)
        a = b.neck[ks] - b.spine[ks]
        c = b.eyes[ks] - b.neck[ks]
        return ks, gs, gn, dgs, dgn, a, c

    def head_pose_batch(self, X: np.ndarray, k0: int):
        Q = X[:, self.xs][:, : self.n]
        ks, gs, gn, _, _, a, c = self._pieces(Q, k0 + np.arange(len(X)))
        b = self.base
        gng = gn @ gs
        p = b.spine[ks] + np.einsum("nij,nj->ni", gs, a) + np.einsum("nij,nj->ni", gng, c)
        return p, gng @ b.head_axes[ks]

    def head_jacobian_batch(self, X: np.ndarray, k0: int):
        """dp (N, 3, NX) and dR (N, 3, 3, NX) w.r.t. the full state."""
        Q = X[:, self.xs][:, : self.n]
        ks, gs, gn, dgs, dgn, a, c = self._pieces(Q, k0 + np.arange(len(X)))
        rh = self.base.head_axes[ks]
        n = len(X)
        nx = self.stack.nx if self.stack is not None else self.nx
        i0 = self.xs.start
        dp = np.zeros((n, 3, nx))
        dR = np.zeros((n, 3, 3, nx))
        for j in range(2):  # spine yaw/pitch move the neck pivot and everything above it
            dp[:, :, i0 + j] = (np.einsum("nij,nj->ni", dgs[:, j], a)
                                + np.einsum("nij,njk,nk->ni", gn, dgs[:, j], c))
            dR[:, :, :, i0 + j] = gn @ dgs[:, j] @ rh
        for j in range(2):
            dp[:, :, i0 + 2 + j] = np.einsum("nij,njk,nk->ni", dgn[:, j], gs, c)
            dR[:, :, :, i0 + 2 + j] = dgn[:, j] @ gs @ rh
        return dp, dR

    def head_pose(self, x, k):
        k = int(self.base.at(k))
        q = x[self.xs][: self.n]
        s, c = np.sin(q), np.cos(q)
        i3, ux, ux2, lx, lx2 = np.eye(3), self._up_x, self._ux2, self._lx[k], self._lx2[k]
        gs = (i3 + s[0] * ux + (1 - c[0]) * ux2) @ (i3 + s[1] * lx + (1 - c[1]) * lx2)
        gn = (i3 + s[2] * ux + (1 - c[2]) * ux2) @ (i3 + s[3] * lx + (1 - c[3]) * lx2)
        gng = gn @ gs
        return self.base.spine[k] + gs @ self._a[k] + gng @ self._c[k], gng @ self.base.head_axes[k]

    def head_pose_jacobian(self, x, k):
        dp, dR = self.head_jacobian_batch(x[None], k)
        return dp[0], dR[0]
