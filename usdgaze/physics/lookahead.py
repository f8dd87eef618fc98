"""A task that looks only part way into the planner's window: costed on each window's first steps.

The stepping stones' task keeps its look-ahead at 0.6 s whatever the window (``StoneTask.look_ahead_s``).
Costed over a whole 0.8 s or 1.0 s window, it fell every 4.0-5.5 s stones shot tried, 0.3-0.7 s in: from
0.3 s on, a 1.0 s window reaches the displaced landing at 1.3 s, long before the swing that makes it
starts (0.7 s). Costed only on each window's first 0.6 s, a 1.0 s window landed 12 of 12 bar shots, no
fall (10 of them simulated again: the first simulation, one iteration a step, can still fall), where
the whole-window task fell in every simulation (docs/physics-log.md, "The stones' look-ahead");
costed on its first 0.4 s they stood but missed (the swing is 0.6 s).

The planner's costs learn where a window starts only from the batched calls (``cost_batch(X, U, k0)``,
``derivs_batch``), which are what ``compose.CostSum`` and the solver use; the per-step ``l`` and
``derivs`` have no window and are refused.
"""

from __future__ import annotations

import numpy as np


class Lookahead:
    """``task`` costed on the first ``steps`` steps of each window, without its terminal (made only for
    windows longer than ``steps``: their end lies past what the task looks at); its name, measures,
    verdict and percepts are the task's own."""

    def __init__(self, task, steps: int) -> None:
        self.task, self.steps = task, int(steps)

    def __getattr__(self, name: str):
        if name == "task":  # not set yet (a copy being made): no recursion
            raise AttributeError(name)
        return getattr(self.task, name)  # name, measure, problems, perceive, ...

    def cost_batch(self, X: np.ndarray, U: np.ndarray, k0: int) -> np.ndarray:
        out = np.zeros(len(U))
        m = min(self.steps, len(U))
        if hasattr(self.task, "cost_batch"):
            out[:m] = self.task.cost_batch(X[:m], U[:m], k0)
        else:
            out[:m] = [self.task.l(X[i], U[i], k0 + i) for i in range(m)]
        return out

    def derivs_batch(self, X: np.ndarray, U: np.ndarray, k0: int) -> tuple[np.ndarray, ...]:
        n, nx, nu = len(U), X.shape[1], U.shape[1]
        out = (np.zeros((n, nx)), np.zeros((n, nu)), np.zeros((n, nx, nx)), np.zeros((n, nu, nu)),
               np.zeros((n, nu, nx)))
        m = min(self.steps, n)
        if hasattr(self.task, "derivs_batch"):
            parts = self.task.derivs_batch(X[:m], U[:m], k0)
        else:
            got = [self.task.derivs(X[i], U[i], k0 + i) for i in range(m)]
            parts = [np.stack([g[j] for g in got]) for j in range(5)]
        for whole, part in zip(out, parts):
            whole[:m] = part
        return out

    def terminal(self, x: np.ndarray, k: int) -> float:
        return 0.0

    def terminal_derivs(self, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(len(x)), np.zeros((len(x), len(x)))

    def l(self, x, u, k):
        raise TypeError("a look-ahead task is costed per window (cost_batch), not per step")

    def derivs(self, x, u, k):
        raise TypeError("a look-ahead task is costed per window (derivs_batch), not per step")


def limit(task, window: int, h: float):
    """``task`` as :class:`Lookahead` where it declares a ``look_ahead_s`` shorter than a window of
    ``window`` steps of ``h``; otherwise the task itself (its every call as before)."""
    ahead = getattr(task, "look_ahead_s", None)
    if ahead is None:
        return task
    steps = max(1, int(round(ahead / h)))
    return Lookahead(task, steps) if window > steps else task
