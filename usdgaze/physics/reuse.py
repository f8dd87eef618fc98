"""Finite differences kept across receding-horizon windows (``mpc.Options.fd_reuse``, off by default).

Consecutive windows of a receding horizon overlap in all but one step, and with one solver iteration
a window, a step's state moves little from one solve to the next. ``KeptDifferences`` keeps MuJoCo's
transition matrices of each differentiated step in MuJoCo's own tangent coordinates (which no anchor
changes), keyed by the absolute step, and maps them to the new window's states instead of
differentiating again. Differentiated anew at every call: the window's first ``FD_FRESH`` steps
(they decide the control applied next), a step not differentiated before or whose constraint rows
(contacts, joint limits) are not those it was differentiated with, and a ``1 / reuse`` share of the
others in turn, so that no step's matrices are older than ``reuse`` calls. On the CMU walk this cut
the CPU by 27% at ``reuse`` 3 but took the deepest foot from 1.7 to 4.2 cm (docs/physics.md).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from usdgaze.physics import fdpool

FD_FRESH = 5  # 0.1 s at h 0.02


class KeptDifferences:
    """The kept matrices of one ``MujocoBody`` (the part whose windows these are; never a thread's copy)."""

    def __init__(self, reuse: int) -> None:
        self.reuse, self.calls = int(reuse), 0
        self.cache: dict[int, tuple[np.ndarray, np.ndarray, bytes]] = {}  # step -> A, B (tangent), constraints

    def fresh_steps(self, body, at: np.ndarray, X: np.ndarray, U: np.ndarray, k0: int) -> np.ndarray:
        """Which of the steps ``at`` (window indices) MuJoCo differentiates in this call (see the module)."""
        import mujoco

        self.calls += 1
        for k in [k for k in self.cache if k < k0]:
            del self.cache[k]
        fresh = np.ones(len(at), bool)
        for j, i in enumerate(at):
            k = k0 + i
            if i < FD_FRESH or k not in self.cache or (k + self.calls) % self.reuse == 0:
                continue
            body._load(X[i, body.xs], U[i, body.us], k)
            mujoco.mj_fwdPosition(body.mj, body.data)
            fresh[j] = constraints(body.data) != self.cache[k][2]
        return fresh

    def linearize_start(self, body, X: np.ndarray, U: np.ndarray, k0: int, at: np.ndarray) -> Callable:
        """``body.linearize_start`` over the steps ``at``: the fresh ones differentiated (on the body's
        threads), the others read back and mapped to this window's states, the next state from the
        window itself (``X`` is a rollout of ``U``) where it is finite."""
        fresh = self.fresh_steps(body, at, X, U, k0)
        xs, us = body.xs, body.us

        def work(part, chunk):
            out = []
            for i in chunk:
                xb, ub = X[i, xs], U[i, us]
                A, B = part._fd(xb, ub, k0 + i)
                xn = part._next(xb, ub, k0 + i)  # its forward pass made the constraints at xb
                out.append(((A.copy(), B.copy(), constraints(part.data)), part._minimal(A, B, xb, xn)))
            return out

        got = fdpool.split(body, work, at[fresh])

        def matrices():
            done = iter(p for part in got() for p in part)
            pairs = []
            for i, new in zip(at, fresh):
                k = k0 + i
                if new:
                    self.cache[k], (A, B) = next(done)
                else:
                    A_t, B_t, _ = self.cache[k]
                    xb = X[i, xs]
                    nxt = X[i + 1, xs] if i + 1 < len(X) else None
                    xn = nxt if nxt is not None and np.all(np.isfinite(nxt)) else body._next(xb, U[i, us], k)
                    A, B = body._minimal(A_t.copy(), B_t.copy(), xb, xn)
                pairs.append((A, B))
            return fdpool.window_matrices(body, pairs, at, len(U))

        return matrices


def constraints(d) -> bytes:
    """The constraint rows MuJoCo made at a data's state: the kind and the contact or limit of each."""
    return d.efc_type[:d.nefc].tobytes() + d.efc_id[:d.nefc].tobytes()
