"""The task terms of the full-body planner (catch, stones, obstacles): what one is, and the per-step
measures and whole-run verdicts the loop (``physics.mpc.run``) collects from them."""

from __future__ import annotations

from typing import Callable, Protocol, Sequence

import numpy as np

from usdgaze.physics.dynamics import MujocoBody


class Task(Protocol):
    """A task term of the paper's cost (catch, stones, obstacles): a ``ddp.Cost`` over the planner's
    state, summed with the tracking cost, plus what it measures on the simulated body after each step
    (``data``: a ``mujoco.MjData`` at the new state, kinematics done) for the shot's report. It may
    also judge the whole run (``problems(qpos, seconds)``: :class:`Problem`s, or plain strings, which
    another simulation could mend)."""

    name: str

    def l(self, x: np.ndarray, u: np.ndarray, k: int) -> float: ...

    def measure(self, k: int, data) -> dict[str, float]: ...


class Problem(str):
    """A task's problem with a whole run, in words (it is the string the report says), and whether
    another simulation of the shot could mend it."""

    mendable: bool

    def __new__(cls, text: str, mendable: bool = True) -> "Problem":
        problem = super().__new__(cls, text)
        problem.mendable = mendable
        return problem


# A task is made once the planner's body exists: ``factory(plan, ref_qpos_at_h)``.
TaskFactory = Callable[[MujocoBody, np.ndarray], Task]


def judge_tasks(tasks, result) -> tuple[list[str], list[str]]:
    """The problems each task with a ``problems(qpos, seconds)`` finds in the simulated states (an
    ``mpc.Result``), and those of them another simulation of the shot cannot mend (``Problem.mendable``),
    as plain strings (what the report says)."""
    found = [p for task in tasks if hasattr(task, "problems") for p in task.problems(result.qpos, result.seconds)]
    return [str(p) for p in found], [str(p) for p in found if not getattr(p, "mendable", True)]


def task_prefix(names: Sequence[str], i: int) -> str:
    """The per-frame key prefix of the ``i``-th task: its name, numbered from its second instance on
    (two balls to catch report ``catch.*`` and ``catch2.*``)."""
    n = list(names[:i]).count(names[i])
    return names[i] if n == 0 else f"{names[i]}{n + 1}"


def measure_tasks(tasks, k: int, data, measured: dict[str, list[float]]) -> None:
    """Append every task's measures after step ``k`` (NaN-padded where a key first appears)."""
    names = [t.name for t in tasks]
    for i, task in enumerate(tasks):
        prefix = task_prefix(names, i)
        for key, value in task.measure(k, data).items():
            measured.setdefault(f"{prefix}.{key}", [np.nan] * k).append(float(value))
