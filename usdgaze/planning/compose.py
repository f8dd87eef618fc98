"""Dynamics made of parts: eye, belief, body... stacked into one state and one control vector.

Each part owns a slice of the state (``nx`` entries) and of the control (``nu`` entries) and computes
its own next slice. A part may *read* other parts' slices (the belief reads the eye and the body
through the point of sight), so its linearization returns full rows: (nx_part, NX) and (nx_part, NU).
``Stacked`` assigns the slices in the order given and is itself a ``ddp.Dynamics``.

A body part (kinematic offsets here, MuJoCo in ``usdgaze.physics``) additionally provides the head
pose and its Jacobian, which is all the vision parts need from it (see ``BodyPart``).
"""

from __future__ import annotations

from typing import Protocol, Sequence, runtime_checkable

import numpy as np


class Part:
    """Base for a dynamics part; ``Stacked`` calls ``bind`` to give it its slices."""

    name: str = "part"
    nx: int = 0
    nu: int = 0
    xs: slice = slice(0, 0)
    us: slice = slice(0, 0)
    stack: "Stacked | None" = None

    def bind(self, stack: "Stacked", xs: slice, us: slice) -> None:
        self.stack, self.xs, self.us = stack, xs, us

    def step(self, x: np.ndarray, u: np.ndarray, k: int) -> np.ndarray:
        raise NotImplementedError

    def linearize(self, x: np.ndarray, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def linearize_batch(self, X: np.ndarray, U: np.ndarray, k0: int) -> tuple[np.ndarray, np.ndarray]:
        pairs = [self.linearize(X[i], U[i], k0 + i) for i in range(len(U))]
        return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


@runtime_checkable
class BodyPart(Protocol):
    """What the vision system needs from a body: the head pose over a window and its derivative.

    ``head_pose(x, k)`` -> (p (3,), R (3, 3)): the eyes' midpoint in world space and the head's
    world rotation whose columns are the head's forward, left and up axes (so the neutral eye looks
    along column 0). ``head_pose_jacobian(x, k)`` -> (dp (3, NX), dR (3, 3, NX)) w.r.t. the FULL state.
    """

    nx: int
    nu: int

    def head_pose(self, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]: ...

    def head_pose_jacobian(self, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]: ...


class Stacked:
    """The product of parts: x = [x_part0, x_part1, ...], u = [u_part0, ...]."""

    def __init__(self, parts: Sequence[Part]) -> None:
        self.parts = list(parts)
        ix = iu = 0
        self.by_name: dict[str, Part] = {}
        for part in self.parts:
            part.bind(self, slice(ix, ix + part.nx), slice(iu, iu + part.nu))
            ix += part.nx
            iu += part.nu
            self.by_name[part.name] = part
        self.nx, self.nu = ix, iu

    def __getitem__(self, name: str) -> Part:
        return self.by_name[name]

    def step(self, x: np.ndarray, u: np.ndarray, k: int) -> np.ndarray:
        return np.concatenate([p.step(x, u, k) for p in self.parts])

    def linearize(self, x: np.ndarray, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        rows = [p.linearize(x, u, k) for p in self.parts]
        return np.vstack([r[0] for r in rows]), np.vstack([r[1] for r in rows])

    def linearize_batch(self, X: np.ndarray, U: np.ndarray, k0: int) -> tuple[np.ndarray, np.ndarray]:
        return self.linearize_start(X, U, k0)()

    def linearize_start(self, X: np.ndarray, U: np.ndarray, k0: int, after: np.ndarray | None = None) -> "StackRows":
        """``linearize_batch`` begun: parts with a ``linearize_start`` (the MuJoCo body's threaded finite
        differences) start first, the others' rows are made meanwhile; call the result for the rows,
        or its ``step(i)`` for one step's. ``after``: as ``ddp.linearize_start``'s, for those parts."""
        started = {i: p.linearize_start(X, U, k0, after) for i, p in enumerate(self.parts) if hasattr(p, "linearize_start")}
        done = {i: p.linearize_batch(X, U, k0) for i, p in enumerate(self.parts) if i not in started}
        return StackRows(self, [done[i] if i in done else started[i] for i in range(len(self.parts))], len(U))

    def forward_pass(self, X, U, kff, K, alpha, k0):
        """Roll out u = U + alpha kff + K (x - X) with the passive parts done last, in one batch.

        A *passive* part (``passive = True``, no controls, read by no other part: the belief) does
        not change the other parts' motion, so they are stepped first and the passive part follows
        their whole trajectory at once (``rollout``). Its feedback columns are left out of the policy:
        the deviation of a passive part is itself a function of the others' deviation. None when no
        part is passive (the solver then steps the whole state).
        """
        passive = [p for p in self.parts if getattr(p, "passive", False)]
        if not passive:
            return None
        active = [p for p in self.parts if p not in passive]
        cols = np.concatenate([np.arange(p.xs.start, p.xs.stop) for p in active])
        Xn = X.copy()
        Un = np.empty_like(U)
        Ka = K[:, :, cols]
        Xa = X[:, cols]
        base = U + alpha * kff
        if all(isinstance(p, LinearPart) for p in active):  # x' = A x + B u: fused, no per-part calls
            rows = [p.linear_rows() for p in active]
            A = np.vstack([r[0] for r in rows])[:, cols]
            B = np.vstack([r[1] for r in rows])
            out = np.empty_like(Xa)  # rows written into Xn once, after the loop: no fancy indexing per step
            xa = out[0] = Xn[0, cols]
            for i in range(len(U)):
                u = base[i] + Ka[i] @ (xa - Xa[i])
                Un[i] = u
                xa = out[i + 1] = A @ xa + B @ u
            Xn[:, cols] = out
        else:
            for i in range(len(U)):
                Un[i] = base[i] + Ka[i] @ (Xn[i, cols] - Xa[i])
                for p in active:
                    Xn[i + 1, p.xs] = p.step(Xn[i], Un[i], k0 + i)
        for p in passive:
            Xn[:, p.xs] = p.rollout(Xn, k0)
        return Xn, Un


class StackRows:
    """A stack's started linearization, as the whole window's rows ``fx`` ``(n, NX, NX)``, ``fu``: the
    parts' rows made already are written at once; a part started with ``block(i)`` (the MuJoCo body's
    threads) writes step ``i``'s when ``step(i)`` first asks for it."""

    def __init__(self, stack: Stacked, parts: list, n: int) -> None:
        self.fx, self.fu = np.zeros((n, stack.nx, stack.nx)), np.zeros((n, stack.nx, stack.nu))
        self.lazy, self.whole, self.made = [], [], [False] * n
        for part, got in zip(stack.parts, parts):
            if hasattr(got, "block"):
                self.lazy.append((part, got))
            elif callable(got):
                self.whole.append((part, got))
            else:
                self.fx[:, part.xs], self.fu[:, part.xs] = got

    def step(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        while self.whole:  # a started part without steps of its own (a strided body): all at once
            part, got = self.whole.pop()
            self.fx[:, part.xs], self.fu[:, part.xs] = got()
        if not self.made[i]:
            for part, got in self.lazy:
                A, B = got.block(i)
                self.fx[i, part.xs, part.xs], self.fu[i, part.xs, part.us] = A, B
            self.made[i] = True
        return self.fx[i], self.fu[i]

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        for i in range(len(self.made)):
            self.step(i)
        return self.fx, self.fu


class LinearPart(Part):
    """A part whose step is linear and the same at every k: x' = A x + B u. Subclasses give
    ``linear_rows()`` (their rows of A and B over the whole stack); ``Stacked`` fuses such parts."""

    def linear_rows(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def linearize(self, x, u, k):
        return self.linear_rows()

    def linearize_batch(self, X, U, k0):
        fx, fu = self.linear_rows()
        n = len(U)
        return np.broadcast_to(fx, (n,) + fx.shape), np.broadcast_to(fu, (n,) + fu.shape)


class SecondOrder(LinearPart):
    """A double integrator (semi-implicit Euler): state [q, qd], control qdd.

    qd' = qd + h qdd,  q' = q + h qd'. Used for the kinematic gaze-chain offsets.
    """

    def __init__(self, n: int, h: float, name: str = "body") -> None:
        self.n, self.h, self.name = n, float(h), name
        self.nx, self.nu = 2 * n, n

    def step(self, x, u, k):
        q, qd = x[self.xs][: self.n], x[self.xs][self.n:]
        qd_n = qd + self.h * u[self.us]
        return np.concatenate([q + self.h * qd_n, qd_n])

    def linear_rows(self):
        st, n, h = self.stack, self.n, self.h
        fx = np.zeros((self.nx, st.nx))
        fu = np.zeros((self.nx, st.nu))
        i0, j0 = self.xs.start, self.us.start
        eye = np.eye(n)
        fx[:n, i0:i0 + n] = eye
        fx[:n, i0 + n:i0 + 2 * n] = h * eye
        fx[n:, i0 + n:i0 + 2 * n] = eye
        fu[:n, j0:j0 + n] = h * h * eye
        fu[n:, j0:j0 + n] = h * eye
        return fx, fu


class CostSum:
    """Several costs over the same stacked state and controls, summed: itself a ``ddp.Cost``.

    Batched methods are used per member when it has them, so a vectorized cost stays vectorized.
    """

    def __init__(self, costs: Sequence) -> None:
        self.costs = tuple(costs)

    def l(self, x, u, k):
        return sum(float(c.l(x, u, k)) for c in self.costs)

    def derivs(self, x, u, k):
        parts = [c.derivs(x, u, k) for c in self.costs]
        return tuple(sum(p[j] for p in parts) for j in range(5))

    def terminal(self, x, k):
        return sum(float(c.terminal(x, k)) for c in self.costs)

    def terminal_derivs(self, x, k):
        parts = [c.terminal_derivs(x, k) for c in self.costs]
        return parts[0][0] + sum(p[0] for p in parts[1:]), parts[0][1] + sum(p[1] for p in parts[1:])

    def cost_batch(self, X, U, k0):
        out = np.zeros(len(U))
        for c in self.costs:
            out += c.cost_batch(X, U, k0) if hasattr(c, "cost_batch") else \
                [c.l(X[i], U[i], k0 + i) for i in range(len(U))]
        return out

    def derivs_batch(self, X, U, k0):
        total = None
        for c in self.costs:
            if hasattr(c, "derivs_batch"):
                part = c.derivs_batch(X, U, k0)
            else:
                got = [c.derivs(X[i], U[i], k0 + i) for i in range(len(U))]
                part = tuple(np.stack([g[j] for g in got]) for j in range(5))
            total = part if total is None else tuple(a + b for a, b in zip(total, part))
        return total
