"""The stepping stones of the second seed (section 7) on the MuJoCo body, authored in the stage and
measured on the WRITTEN layer by UsdSkel forward kinematics: an excerpt of the CMU walk (1.0-2.5 s)
with a stone at each reference footfall, found from the toes' height and speed in the capture, the
right foot's swing stone displaced 15 cm; the feet measured against the stones on the written layer
(the bar, four directions, is not met in all of them: docs/physics.md). The stones' verdict, their
cost's derivatives against central differences, and a solve with both tasks (stones and obstacles)
whose cost decreases. The whole bar in one coupled shot: test_physics_stones_bar.py; the obstacles:
test_physics_obstacles.py.
"""

from __future__ import annotations

import re

from types import SimpleNamespace

import numpy as np
import pytest
from pxr import Sdf

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc, obstacles, stones
from usdgaze.physics.tasks import judge_tasks

from . import measure
from .attend_support import compose
from .differences import central, rel
from .obstacle_stages import add_objects, cut

SKEL = "/root/Body/BodySkel"
SPAN = (1.0, 2.5)  # seconds of the walk: the right foot's 0.8 s swing lands at 1.9 s
OPTIONS = mpc.Options(h=0.03, horizon_s=0.6, stones_horizon_s=None)  # the window these figures are of
TOES = ("LeftToe", "RightToe")
# The right foot reaches its stone in a 0.8 s swing: displaced the bar's 15 cm. The left foot only
# shuffles here (lifts of 80 ms, footfalls 7-12 cm apart): its stones stay at the footfalls
# (displaced 10 cm, its first shuffle lands 7-13 cm off: docs/physics.md).
SHIFT = {"LeftToe": 0.0, "RightToe": 0.15}
TOWARD = np.array([-0.975, 0.0, 0.223])  # the stage's -X, 13 deg toward +Z


def contacts(posed: measure.Posed, toe: str, tcps: float) -> list[tuple[int, int]]:
    """Frame spans with the toe within 6 cm of its lowest and slower than 0.6 m/s, >= 50 ms."""
    p = posed.position(toe)
    h = p @ posed.up
    flat = p - np.outer(h, posed.up)
    speed = np.linalg.norm(np.gradient(flat, axis=0), axis=1) * tcps
    low = (h < h.min() + 0.06) & (speed < 0.6)
    edges = np.flatnonzero(np.diff(np.r_[0, low.astype(int), 0]))
    return [(a, b) for a, b in zip(edges[::2], edges[1::2]) if (b - a) / tcps >= 0.05]


@pytest.fixture(scope="module")
def stepped(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("stones")
    src = cut(tmp / "stones.usda", *SPAN)
    tcps = Sdf.Layer.FindOrOpen(str(src)).timeCodesPerSecond
    ref = measure.posed(str(src), SKEL)
    # A stone at each footfall; the right foot's, first stood on mid-excerpt, displaced by SHIFT.
    placed, moved = [], []
    for toe in TOES:
        for a, b in contacts(ref, toe, tcps):
            foot = ref.position(toe)[a:b].mean(axis=0)
            foot -= (foot @ ref.up) * ref.up
            size = SHIFT[toe] if 0.3 <= a / tcps <= SPAN[1] - SPAN[0] - 0.3 else 0.0
            placed.append(foot + TOWARD * size)
            moved.append(size > 0)
    add_objects(src, "stone", "Stone", placed, 0.15, seen=False)  # body only: the coupled loop is 3x slower
    before = measure.sha256(src)
    out = tmp / "walked.usda"
    reports = physics_pass.run(src, out, OPTIONS)
    return dict(src=src, out=out, composed=compose(tmp, src, out), stones=np.array(placed), moved=np.array(moved),
                reports=reports, before=before, tcps=tcps)


def landings(posed: measure.Posed, toe: str, tcps: float) -> list[tuple[int, int]]:
    """Touchdowns: frame spans with the toe within 6 cm of its lowest for >= 50 ms (height only, so
    a foot sliding on the ground is one landing, not several)."""
    h = posed.position(toe) @ posed.up
    low = h < h.min() + 0.06
    edges = np.flatnonzero(np.diff(np.r_[0, low.astype(int), 0]))
    return [(a, b) for a, b in zip(edges[::2], edges[1::2]) if (b - a) / tcps >= 0.05]


def test_a_stone_displaced_15_cm_is_stood_on_and_the_report_agrees_with_fk(stepped):
    """The issue's bar in one of its four directions: the right foot's stone displaced 15 cm (toward
    -X) is stood on within 5 cm by UsdSkel FK (3.4 cm measured) and the shot does not fall; the feet
    the shot starts on stay on their stones, and the report calls a contact missed where FK measures
    it over 5 cm (far from its stone, or not down on it within 0.3 s: a sample with the controls in
    closed form landed the left foot 5.9 cm off late, said as not down) and never far where FK measures
    under 5 cm (outside a 0.5 cm band: the report measures MuJoCo's toe body). The
    bar is NOT met in all four directions (5.4 cm toward +Z: docs/physics.md), so the other
    directions are not asserted."""
    sim = measure.posed(str(stepped["composed"]), SKEL)
    ref = measure.posed(str(stepped["src"]), SKEL)
    stones_at, moved, tcps = stepped["stones"], stepped["moved"], stepped["tcps"]
    report = stepped["reports"][0]
    assert moved.sum() >= 1 and not report.fell and report.window_s == 0.6
    i = 0
    for toe in TOES:
        for a, b in contacts(ref, toe, tcps):
            off = sim.position(toe)[a:b] - stones_at[i]
            off -= np.outer(off @ sim.up, sim.up)
            miss = float(np.linalg.norm(off, axis=1).mean())  # over the reference's contact
            ankle = toe.replace("Toe", "Ankle")
            far = [p for p in report.problems if p.startswith(ankle) and " from its stone over " in p
                   and abs(float(p.split(" over ")[1].split("-")[0]) - a / tcps) < 0.05]
            not_down = [p for p in report.problems if p.startswith(f"{ankle} not down on ")  # its contact's start
                        and abs(float(re.findall(r"(?:of|from) ([0-9.]+) s", p)[-1]) - a / tcps) < 0.05]
            if a == 0:
                assert miss <= 0.05  # standing on it from the start
            if moved[i]:
                assert miss <= 0.05, (toe, miss, report.problems)
            if miss > 0.055:  # missed by FK: the report says so, far from it or not down on it in time
                assert far or not_down, (toe, a, miss, report.problems)
            if miss < 0.045:  # on it by FK: never called far ('not down' also judges height and stillness)
                assert not far, (toe, a, miss, report.problems)
            i += 1


def test_stone_terms_are_in_the_layer_and_the_input_is_untouched(stepped):
    assert measure.sha256(stepped["src"]) == stepped["before"]
    frames = Sdf.Layer.FindOrOpen(str(stepped["out"])).customLayerData["usdgaze:physics"][SKEL]["frames"]
    keys = [k for k in frames if k.startswith("stones.")]
    assert sorted(keys) == ["stones.LeftAnkle.stoneDistanceM", "stones.RightAnkle.stoneDistanceM"]
    assert all(len(frames[k]) == len(frames["seconds"]) for k in keys)


def test_stone_cost_gradient_matches_central_differences(stone_walk):
    dyn, ref_q, frames = stone_walk
    task = stones.StoneTask(dyn, ref_q, np.array([[0.45, 1.55, 0], [0.0, 1.5, 0], [0.1, 1.84, 0]]), frames=frames)
    both = np.flatnonzero((task.stone >= 0).all(axis=0))
    one = np.flatnonzero((task.stone >= 0).sum(axis=0) == 1)
    assert len(both) and len(one) and (task.stone < 0).any()  # double and single support, and swing
    rng = np.random.default_rng(0)
    for k in (both[0], one[len(one) // 2]):
        x = dyn.to_state(ref_q[k], rng.normal(0, 0.3, dyn.nv))
        x[:dyn.nv] += rng.normal(0, 0.05, dyn.nv)  # away from the reference: residuals are not zero
        u = np.zeros(dyn.nu)
        lx, lu, lxx, luu, lux = task.derivs(x, u, k)
        assert task.l(x, u, k) > 0.01 and not lu.any()
        assert rel(lx, central(lambda z: task.l(z, u, k), x)) <= 1e-4
        assert rel(task.terminal_derivs(x, k)[0], central(lambda z: task.terminal(z, k), x)) <= 1e-4
        # Gauss-Newton: 2 w J'J with J the residuals' Jacobian, itself checked against differences.
        for r, J in task._residuals(x[dyn.xs], k, True):
            num = central(lambda z: task._residuals(np.r_[z, x[dyn.nv:]], k, False)[0][0], x[:dyn.nv]).T
            assert rel(J, num) <= 1e-4
            break
        assert np.all(np.linalg.eigvalsh(lxx) > -1e-9)


def _pinned(dyn, qpos: np.ndarray, foot: int) -> np.ndarray:
    """``qpos`` lowered at each step by the height of foot ``foot``'s lowest capsule point (the foot's
    body and its toes', by MuJoCo's kinematics): that foot on the ground throughout (CMU's right foot
    stands 2-4 cm over it here, which the verdict, wanting the sole within 2 cm, calls not down)."""
    import mujoco

    mj, m = dyn.mj, dyn.model
    top = m.feet[foot]
    geoms = np.flatnonzero(np.isin(mj.geom_bodyid - 1, [top] + [b for b in m.toes if m.body_parent[b] == top]))
    d = mujoco.MjData(mj)
    out = qpos.copy()
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(mj, d)
        out[k, 2] -= min(d.geom_xpos[g, 2] - abs(d.geom_xmat[g, 8]) * mj.geom_size[g, 1] - mj.geom_size[g, 0]
                         for g in geoms)
    return out


def _contacts(task) -> list[tuple[int, int]]:
    """(foot, first step) of each reference contact on a stone."""
    return [(f, a) for f in range(len(task.feet)) for a in np.flatnonzero(np.diff(np.r_[-1, task.stone[f]]) != 0)
            if task.stone[f, a] >= 0]


def test_a_stone_out_of_every_footfalls_reach_is_no_target_and_is_said(stone_walk):
    """A stone metres from the walk pulled the nearest footfall onto it (the report said "399 cm from
    its stone"): now no footfall takes a stone further than ``REACH_M`` from it, the stones near the
    footfalls keep theirs, and the shot's notes say which footfalls have none (or that none has)."""
    dyn, ref_q, frames = stone_walk
    spots = np.array([[0.45, 1.55, 0], [0.0, 1.5, 0], [0.1, 1.84, 0]])
    near = stones.StoneTask(dyn, ref_q, spots, frames=frames, names=["/A", "/B", "/C"])
    far = np.array([[4.5, 1.5, 0.0]])  # 4 m beside the walk (its footfalls lie within 0.5 m of the spots)
    both = stones.StoneTask(dyn, ref_q, np.vstack([spots, far]), frames=frames, names=["/A", "/B", "/C", "/Far"])
    assert np.array_equal(both.stone, near.stone) and (near.stone >= 0).any()
    assert both.notes(10.0) == near.notes(10.0) == []
    alone = stones.StoneTask(dyn, ref_q, far, frames=frames, names=["/Far"])
    assert (alone.stone < 0).all()
    said = alone.notes(10.0)
    assert len(said) == 1 and said[0].startswith("no stone within 35 cm of any footfall")
    assert 350 <= int(said[0].split("(the nearest ")[1].split(" cm")[0]) <= 450  # 4 m less the walk's 0-0.5 m
    seconds = 10.0 + dyn.h * np.arange(len(ref_q))
    assert alone.problems(ref_q, seconds) == []  # nothing to land on: no "far from its stone"
    # One footfall's stone moved 1 m off: that footfall keeps none, and is said with its time.
    first = [(f, a) for f in range(len(near.feet)) for a in np.flatnonzero(np.diff(np.r_[-1, near.stone[f]]) > 0)
             if near.stone[f, a] >= 0 and a > 0][0]
    moved = spots.copy()
    moved[near.stone[first]] += [1.0, 0.0, 0.0]
    off = stones.StoneTask(dyn, ref_q, moved, frames=frames, names=["/A", "/B", "/C"])
    assert not (off.stone == near.stone[first]).any()
    (line,) = off.notes(10.0)
    assert line.startswith("footfalls with no stone within 35 cm") and near.feet[first[0]][0] in line


def test_a_foot_held_over_its_stone_is_not_down_though_its_ground_distance_is_a_hit(stone_walk):
    """The run's verdict (``StoneTask.problems``): the reference with a foot put on the ground (each
    in turn) comes down with that foot for each of its contacts, the capture as it is does not with
    its floating right foot; raised 15 cm it never does, each contact on a stone said once, by foot
    and stone, although its toe's ground-plane distance (the per-step measure) is unchanged."""
    import mujoco

    dyn, ref_q, frames = stone_walk
    spots = np.array([[0.45, 1.55, 0], [0.0, 1.5, 0], [0.1, 1.84, 0]])
    task = stones.StoneTask(dyn, ref_q, spots, frames=frames, names=["/A", "/B", "/C"])
    seconds = 10.0 + dyn.h * np.arange(len(ref_q))
    starts = _contacts(task)
    assert len(starts) >= 3 and {f for f, _ in starts} == {0, 1}
    assert any(p.startswith("RightAnkle not down on ") for p in task.problems(ref_q, seconds))
    for f, (name, _, _) in enumerate(task.feet):
        pinned = _pinned(dyn, ref_q, f)
        assert not [p for p in task.problems(pinned, seconds) if p.startswith(name)]
        raised = pinned.copy()
        raised[:, 2] += 0.15
        said = [p for p in task.problems(raised, seconds) if p.startswith(name)]
        mine = [a for g, a in starts if g == f]
        assert len(said) == len(mine), said
        for a, line in zip(mine, said):
            assert line.startswith(f"{name} not down on /{'ABC'[task.stone[f, a]]} ")
            assert f"of {seconds[a]:.2f} s" in line or f"contact from {seconds[a]:.2f} s" in line  # (by the shot's end)
    d = mujoco.MjData(dyn.mj)

    def measured(q, k):
        d.qpos[:] = q
        mujoco.mj_kinematics(dyn.mj, d)
        return task.measure(k, d)

    k = starts[-1][1]
    assert measured(raised[k], k) == pytest.approx(measured(pinned[k], k), abs=1e-9)


def test_a_floating_foot_is_pulled_down_onto_its_stone(stone_walk):
    """The capture's right foot stands 3.7-4.4 cm over the floor here: the stone's height target
    over each contact is the toe's height with the foot on the ground (at the contact's lowest
    step, the toe of the reference lowered onto that foot), not the floating toe's; a contact whose
    foot reaches into the ground keeps the reference toe's heights."""
    import mujoco

    dyn, ref_q, frames = stone_walk
    spots = np.array([[0.45, 1.55, 0], [0.0, 1.5, 0], [0.1, 1.84, 0]])
    task = stones.StoneTask(dyn, ref_q, spots, frames=frames, names=["/A", "/B", "/C"])
    d = mujoco.MjData(dyn.mj)

    def toe_z(q, f):
        d.qpos[:] = q
        mujoco.mj_kinematics(dyn.mj, d)
        return float(d.xpos[task.feet[f][2], 2])

    floats = []
    for f in range(len(task.feet)):
        pinned = _pinned(dyn, ref_q, f)
        float_m = ref_q[:, 2] - pinned[:, 2]  # the foot's lowest capsule point over the ground
        on = np.flatnonzero(task.stone[f] >= 0)
        for span in np.split(on, np.flatnonzero(np.diff(on) > 1) + 1):
            k = span[np.argmin(float_m[span])]
            floats.append((task.feet[f][0], float_m[k]))
            want = toe_z(pinned[k] if float_m[k] > 0 else ref_q[k], f)
            assert task.ref_height[f][k] == pytest.approx(want, abs=1e-9), (f, k)
    assert any(name == "RightAnkle" and m > 0.03 for name, m in floats), floats
    assert any(m <= 0 for _, m in floats), floats


def test_a_toe_that_only_brushes_the_ground_for_a_step_is_not_down(stone_walk):
    """A footfall lasts: the motion raised 15 cm but dipped to the reference's height for one step at
    a contact's start is said to miss that stone (a swing's toe passing through the contact band, or
    skidding across the ground, is no footfall); dipped for two steps (0.06 s at h 0.03), it comes
    down on it. Each contact on its own."""
    dyn, ref_q, frames = stone_walk
    spots = np.array([[0.45, 1.55, 0], [0.0, 1.5, 0], [0.1, 1.84, 0]])
    task = stones.StoneTask(dyn, ref_q, spots, frames=frames, names=["/A", "/B", "/C"])
    seconds = 10.0 + dyn.h * np.arange(len(ref_q))
    starts = [(f, a) for f, a in _contacts(task) if a + 2 < len(ref_q)]
    assert len(starts) >= 3 and dyn.h == pytest.approx(0.03)
    for f, a in starts:
        pinned = _pinned(dyn, ref_q, f)
        line = f"{task.feet[f][0]} not down on /{'ABC'[task.stone[f, a]]} "
        for steps, said in ((1, True), (2, False)):
            dipped = pinned.copy()
            dipped[:, 2] += 0.15
            dipped[a:a + steps, 2] = pinned[a:a + steps, 2]
            lines = [p for p in task.problems(dipped, seconds) if p.startswith(line) and f"{seconds[a]:.2f} s" in p]
            assert bool(lines) is said, (f, a, steps)


def test_each_solve_with_both_tasks_decreases_the_cost(stone_walk):
    dyn, ref_q, (qpos, frames) = stone_walk
    # A stone 10 cm off each foot's footfall and an obstacle coming at the root: both terms are active.
    probe = stones.StoneTask(dyn, ref_q, np.zeros((0, 3)))
    feet = np.array([probe.points.pose(dyn.to_state(ref_q[0]))[0][toe] for _, _, toe in probe.feet])
    placed = feet * [1, 1, 0] + [0.1, 0.0, 0.0]
    t = 0.03 * np.arange(len(ref_q))
    centre = ref_q[:1, :3] + np.outer(t - 0.3, [0.0, -1.0, 0.0]) + [0.3, 0.0, 0.0]
    tasks = [stones.factory(placed, (qpos, frames)), obstacles.factory(lambda s: centre[:len(s), None], np.array([0.25]))]
    model = dyn.model
    result = mpc.simulate(model, qpos[:13], frames[:13], mpc.Options(h=0.03, horizon_s=0.3), tasks=tasks)
    assert len(result.solve_costs) == 4
    for costs in result.solve_costs:
        assert all(b <= a for a, b in zip(costs, costs[1:]))
    assert result.solve_costs[0][-1] < 0.9 * result.solve_costs[0][0]
    assert {"stones.LeftAnkle.stoneDistanceM", "obstacles.proximity", "obstacles.clearanceM"} <= set(result.task_terms)


def test_an_unknown_task_is_one_line_exit_2_nothing_written(tmp_path, capsys):
    from usdgaze.console.main import main

    src = cut(tmp_path / "bad.usda", 1.0, 1.1)
    add_objects(src, "stepping", "Stone", [np.zeros(3)], 0.15)
    assert main(["attend", str(src), "--out", str(tmp_path / "sim.usda"), "--physics", "--window", "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "/Stones/Stone0.usdgaze:physics:task: 'stepping' is not one of" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.usda"]


def test_a_foot_down_for_the_shots_last_steps_is_down(stone_walk):
    """The last step has no next one to give the toe's speed: it takes the step before's, so a foot
    that comes down on its stone for the shot's last two steps (0.06 s) is down; one that does not
    is said not down by the shot's end."""
    dyn, ref_q, frames = stone_walk
    spots = np.array([[0.45, 1.55, 0], [0.0, 1.5, 0], [0.1, 1.84, 0]])
    task = stones.StoneTask(dyn, ref_q, spots, frames=frames, names=["/A", "/B", "/C"])
    seconds = 10.0 + dyn.h * np.arange(len(ref_q))
    f, a = max(_contacts(task), key=lambda fa: fa[1])
    assert a + round(0.3 / dyn.h) >= len(ref_q) - 1  # the shot's end is within its landing window
    line = f"{task.feet[f][0]} not down on /{'ABC'[task.stone[f, a]]} by the shot's end at {seconds[-1]:.2f} s"
    dipped = _pinned(dyn, ref_q, f)
    dipped[:-2, 2] += 0.15
    assert not any(p.startswith(line) for p in task.problems(dipped, seconds))
    dipped[-2:, 2] += 0.15
    said = [p for p in task.problems(dipped, seconds) if p.startswith(line)]
    assert len(said) == 1 and f"the reference's contact from {seconds[a]:.2f} s" in said[0], said
    sole = float(said[0].split("its sole then ")[1].split(" cm up")[0])
    assert sole == pytest.approx(15.0, abs=0.06), said  # the pinned sole raised 15 cm
    # Another simulation has no more of the shot to land that foot in: it is not simulated again for
    # it. A footfall missed mid-shot can be mended.
    raised = _pinned(dyn, ref_q, f)
    raised[:, 2] += 0.15
    problems, unmendable = judge_tasks([task], SimpleNamespace(qpos=raised, seconds=seconds))
    mid = [p for p in problems if " within 0.3 s of " in p]
    assert mid and unmendable == [p for p in problems if p.startswith(line)], problems
