"""The stones' task looks 0.6 s into the planner's window and no further (``physics.lookahead``): on a
longer window it is costed on the first 0.6 s only, each step's value and derivatives the task's own
per-step ones (computed here by the task's ``l`` and ``derivs``, not by the wrapper), its terminal
dropped; on a 0.6 s window (any other shot's default) the task is used as it is."""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.physics import lookahead, mpc, stones
from usdgaze.planning import ddp
from usdgaze.planning.compose import CostSum

from . import stone_stages

H = 0.03


@pytest.fixture(scope="module")
def walk():
    dyn, ref_q, (qpos, frames) = stone_stages.walk_body(H)
    # a stone 10 cm off each footfall: the task's terms are not zero wherever a foot is down
    probe = stones.StoneTask(dyn, ref_q, np.zeros((0, 3)))
    feet = np.array([probe.points.pose(dyn.to_state(ref_q[0]))[0][toe] for _, _, toe in probe.feet])
    placed = feet * [1, 1, 0] + [0.1, 0.0, 0.0]
    return dyn.model, dyn, ref_q, (qpos, frames), stones.StoneTask(dyn, ref_q, placed, frames=(qpos, frames))


def _window(dyn, ref_q, k0: int, n: int):
    rng = np.random.default_rng(1)
    X = np.array([dyn.to_state(ref_q[k0 + i], rng.normal(0, 0.2, dyn.nv)) for i in range(n + 1)])
    X[:, :dyn.nv] += rng.normal(0, 0.03, (n + 1, dyn.nv))
    return X, np.zeros((n, dyn.nu))


def test_a_longer_window_costs_the_stones_on_its_first_0_6_s_only(walk):
    model, dyn, ref_q, _, task = walk
    window = 40  # 1.2 s
    limited = lookahead.limit(task, window, H)
    ahead = int(round(stones.LOOK_AHEAD_S / H))
    assert isinstance(limited, lookahead.Lookahead) and limited.steps == ahead == 20
    k0 = 10
    X, U = _window(dyn, ref_q, k0, window)
    own = np.array([task.l(X[i], U[i], k0 + i) for i in range(window)])
    assert (own[:ahead] > 0).sum() >= 10 and (own[ahead:] > 0).sum() >= 10  # both parts have terms to drop
    got = limited.cost_batch(X[:window], U, k0)
    assert np.array_equal(got[:ahead], own[:ahead]) and not got[ahead:].any()
    lx, lu, lxx, luu, lux = limited.derivs_batch(X[:window], U, k0)
    for i in (0, ahead - 1, ahead, window - 1):
        want = task.derivs(X[i], U[i], k0 + i)
        if i < ahead:
            assert all(np.array_equal(a, b) for a, b in zip((lx[i], lu[i], lxx[i], luu[i], lux[i]), want))
        else:
            assert np.abs(want[0]).max() > 0 and not (lx[i].any() or lxx[i].any())
    assert task.terminal(X[window], k0 + window) > 0 and limited.terminal(X[window], k0 + window) == 0.0
    assert not any(a.any() for a in limited.terminal_derivs(X[window], k0 + window))
    # in the planner's sum: the tracking's window cost plus the stones' first 20 steps, nothing more
    tracking = mpc.prepare(model, *walk[3], mpc.Options(h=H, horizon_s=1.2)).tracking
    total = ddp.total_cost(CostSum([tracking, limited]), X, U, k0)
    assert total == pytest.approx(ddp.total_cost(tracking, X, U, k0) + own[:ahead].sum(), rel=1e-12)
    # its name, per-step measure and verdict are the task's; per-step costing has no window: refused
    assert limited.name == "stones" and limited.problems is not None and limited.stone is task.stone
    with pytest.raises(TypeError):
        limited.l(X[0], U[0], k0)


def test_the_default_window_and_tasks_without_a_look_ahead_are_left_as_they_are(walk):
    _, _, _, _, task = walk
    assert lookahead.limit(task, 20, H) is task  # 0.6 s at h 0.03: the whole window, terminal included
    assert lookahead.limit(task, 30, 0.02) is task  # 0.6 s at h 0.02
    assert isinstance(lookahead.limit(task, 40, 0.02), lookahead.Lookahead)  # 0.8 s at h 0.02
    other = object()
    assert lookahead.limit(other, 400, H) is other


def test_a_long_window_shot_makes_the_stones_look_ahead_and_still_measures_them(walk):
    model, _, _, (qpos, frames), task = walk
    placed = task.stones
    shot = mpc.prepare(model, qpos[:13], frames[:13], mpc.Options(h=H, horizon_s=0.9),
                       tasks=[stones.factory(placed, (qpos, frames))])
    assert shot.n == 30 and isinstance(shot.tasks[0], lookahead.Lookahead) and shot.tasks[0].steps == 20
    result = mpc.simulate(model, qpos[:13], frames[:13], mpc.Options(h=H, horizon_s=0.9),
                          tasks=[stones.factory(placed, (qpos, frames))])
    for costs in result.solve_costs:
        assert all(b <= a for a, b in zip(costs, costs[1:]))
    assert np.isfinite(result.task_terms["stones.LeftAnkle.stoneDistanceM"][1:]).any()
