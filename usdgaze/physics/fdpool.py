"""The MuJoCo body's finite differences on threads: the window's steps handed out one at a time.

MuJoCo releases the GIL inside ``mjd_transitionFD`` and ``mujoco.rollout`` (the positions' batch of
steps, ``physics.velocity``; ~3.5-6 ms a step on the CMU model), so threads,
each with its own copy of the body (its own ``MjData``), differentiate steps side by side. A thread
takes the next step when it is free (the steps' costs differ with their contacts, so fixed halves
would leave one thread idle while the other finishes), last step first: the solver's backward pass
reads the window from its end, so it starts on the first matrices while the threads make the rest
(``StepRows.step``). Which thread differentiates a step does not change its numbers: each starts
from the state, control and time loaded anew (``MujocoBody._load``).
"""

from __future__ import annotations

import copy
import threading
from typing import Callable

import numpy as np


def clone(body):
    """A copy of ``body`` for a thread: its own ``MjData`` and state cache, no threads of its own."""
    import mujoco

    twin = copy.copy(body)
    twin.data = mujoco.MjData(body.mj)
    twin._qpos_cache = {}  # each thread its own
    twin.workers, twin._pool, twin._clones = 1, None, []
    twin.kept = None  # the part it works for keeps the matrices
    return twin


def threads(body) -> list:
    """The body's thread pool's copies of it (made on first use), each set to the body's anchor and forces."""
    if body._pool is None:
        from concurrent.futures import ThreadPoolExecutor

        body._pool = ThreadPoolExecutor(body.workers)
        body._clones = [clone(body) for _ in range(body.workers)]
    for c in body._clones:
        c._same_anchor(body)
        c.forces = body.forces
    return body._clones


def split(body, work: Callable, steps: np.ndarray) -> Callable[[], list]:
    """``work(copy, chunk)`` over ``steps``: here, or split in ``workers`` chunks over the threads
    (started now); the result, called, gives each chunk's outcome in order."""
    if body.workers <= 1 or len(steps) < 2:
        done = [work(body, steps)]
        return lambda: done
    futures = [body._pool.submit(work, c, chunk)
               for c, chunk in zip(threads(body), np.array_split(steps, body.workers))]
    return lambda: [f.result() for f in futures]


def stack_rows(body, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The body's (A, B) (one step ``(2nv, ...)`` or a window ``(n, 2nv, ...)``) as its rows of the stack."""
    if body.stack is None:
        return A, B
    fx = np.zeros(A.shape[:-1] + (body.stack.nx,))
    fu = np.zeros(B.shape[:-1] + (body.stack.nu,))
    fx[..., body.xs] = A
    fu[..., body.us] = B
    return fx, fu


def window_matrices(body, pairs, at: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The window's (A, B) from those at steps ``at`` (interpolated between), as the stack's rows."""
    A = np.stack([p[0] for p in pairs])
    B = np.stack([p[1] for p in pairs])
    if len(at) < n:  # interpolate between the differentiated steps
        j = np.clip(np.searchsorted(at, np.arange(n), side="right") - 1, 0, len(at) - 2)
        w = ((np.arange(n) - at[j]) / (at[j + 1] - at[j]))[:, None, None]
        A = (1 - w) * A[j] + w * A[j + 1]
        B = (1 - w) * B[j] + w * B[j + 1]
    return stack_rows(body, A, B)


class StepRows:
    """Every step of a window differentiated (stride 1, nothing kept), on the body's threads or here.

    ``step(i)`` waits for step ``i`` alone and gives its rows of the stack; called, the object gives
    the whole window's ``(fx, fu)`` (``linearize_batch``'s)."""

    def __init__(self, body, X: np.ndarray, U: np.ndarray, k0: int, after: np.ndarray | None = None) -> None:
        n = len(U)
        self.body, self.n = body, n
        self.A = np.empty((n, body.nx, body.nx))
        self.B = np.empty((n, body.nx, body.nu))
        self.rows: list = [None] * n
        self.error: BaseException | None = None
        self.args = [(X[i, body.xs], U[i, body.us], k0 + i) for i in range(n)]
        # The tangent maps of the window's states (and, where ``after`` gives them, of the next states)
        # in one call here, not one per step on the threads, where numpy's small calls hold the GIL.
        self.maps_in = body.window_maps(X[:n, body.xs], inverse=True)
        self.maps_out: list = [None] * n
        if after is not None:
            nxt = after[:n, body.xs]
            known = np.flatnonzero(np.all(np.isfinite(nxt), axis=1))  # a blown-up step: stepped anew
            for i, m in zip(known, body.window_maps(nxt[known], inverse=False)):
                self.maps_out[i] = m
        if body.workers <= 1 or n < 2:
            self.ready = None
            for i in range(n):
                self._one(body, i)
            return
        self.ready = [threading.Event() for _ in range(n)]
        order = iter(range(n - 1, -1, -1))  # the backward pass reads the last step first
        lock = threading.Lock()
        for c in threads(body):
            body._pool.submit(self._work, c, order, lock)

    def _one(self, part, i: int) -> None:
        """Step ``i`` differentiated by ``part`` (the body or a thread's copy): ``linearize_body``'s numbers."""
        xb, ub, k = self.args[i]
        A, B = part._fd(xb, ub, k)
        out = self.maps_out[i]
        if out is None:
            out = part._tangent_map(part._next(xb, ub, k), inverse=False)
        self.A[i], self.B[i] = part._to_minimal(A, B, out, self.maps_in[i])

    def _work(self, part, order, lock) -> None:
        while True:
            with lock:
                i = next(order, None)
            if i is None:
                return
            try:
                self._one(part, i)
            except BaseException as e:  # handed to the reader of the step, not lost in the pool
                self.error = e
            self.ready[i].set()

    def block(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Step ``i``'s (A, B) in the body's own coordinates, once it is made."""
        if self.ready is not None:
            self.ready[i].wait()
        if self.error is not None:
            raise self.error
        return self.A[i], self.B[i]

    def step(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Step ``i``'s rows of the stack, once it is made."""
        if self.rows[i] is None:
            self.rows[i] = stack_rows(self.body, *self.block(i))
        return self.rows[i]

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        for i in range(self.n):
            self.block(i)
        return stack_rows(self.body, self.A, self.B)
