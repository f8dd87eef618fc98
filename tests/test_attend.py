"""``usdgaze attend`` end to end: behaviours measured on the WRITTEN layer by UsdSkel FK.

Stages: sample_stages/attend (made by its make_stages.py). Windows are 0.6 s to keep the runs short.
Fixation: the line of sight within FIX_DEG of an object's true position (read with UsdGeom).
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Vt

from tests import measure
from tests.attend_support import ATTEND, angle_to, compose, episodes, gaze, inspection, positions
from usdgaze.console.main import main

FIX_DEG = 5.0
SPEED_TOL = 1.02  # frame sampling of linear interpolation between planner steps never adds speed


def _run(tmp_path, stage, *args, name="out.usdc"):
    out = tmp_path / name
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.6", *args]) == 0
    return out, gaze(compose(tmp_path, stage, out, name + ".usda"))


PROGRESS: list[tuple[int, int]] = []
"""The planner's progress calls of the "per step" run (see test_the_planner_reports_every_step)."""


def _api_run(tmp, stage, name, progress=None, **settings):
    """A run through the Python API, for settings the command line does not expose."""
    from usdgaze.attend import AttendSettings, attend

    out = tmp / name
    attend(stage, out, settings=AttendSettings(window_s=0.6, **settings), progress=progress)
    return gaze(compose(tmp, stage, out, name + ".usda"))


@pytest.fixture(scope="module")
def two_balls(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("two")
    runs = {}
    stage = ATTEND / "two_balls.usda"
    seeds = [(f"uncertainty seed {n}", ("--seed", str(n))) for n in SEEDS]
    for key, args in [("distance", ("--cost", "distance")), ("sequential", ("--cost", "sequential"))] + seeds:
        runs[key] = _run(tmp, stage, *args, name=f"{key.replace(' ', '_')}.usdc")[1]
    runs["per step"] = _api_run(tmp, stage, "per_step.usdc", progress=lambda k, n: PROGRESS.append((k, n)),
                                alpha_per_second=False)
    for key, g in runs.items():
        runs[key] = (g, positions(g.stage, "/Objects/BallLeft", g.times), positions(g.stage, "/Objects/BallRight", g.times))
    return runs


@pytest.fixture(scope="module")
def catch_balls(tmp_path_factory):
    """The two throws to be caught (two_balls_catch.usda: a catch point in front, importance by time to
    arrival), seeds 0-3."""
    tmp = tmp_path_factory.mktemp("catch")
    stage = ATTEND / "two_balls_catch.usda"
    runs = {}
    for n in SEEDS:
        g = _run(tmp, stage, "--seed", str(n), name=f"catch{n}.usdc")[1]
        runs[n] = (g, positions(g.stage, "/Objects/BallLeft", g.times), positions(g.stage, "/Objects/BallRight", g.times))
    return runs


INPUTS = [ATTEND / "ball_throw.usda", ATTEND / "standing.usdc", ATTEND.parent / "cmu" / "cmu_131_01.usdc"]
SEEDS = (0, 1, 2, 3)  # Figure 4c's switching is a close call between plans: measured over four seeds
ARRIVAL_S = (1.3, 1.4)  # BallLeft, BallRight (make_stages.py); the single ball arrives at 1.4 s


def _fingerprints():
    return [(measure.sha256(p), p.stat().st_mode) for p in INPUTS]


@pytest.fixture(scope="module")
def one_ball(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("one")
    before = _fingerprints()
    runs = {"before": before}
    for alpha in ("0", "0.2", "0.4"):
        out, g = _run(tmp, ATTEND / "ball_throw.usda", "--alpha", alpha, name=f"a{alpha}.usdc")
        runs[alpha] = (out, g, positions(g.stage, "/Objects/Ball", g.times))
    before = runs.pop("before")
    runs["inputs_unchanged"] = before == _fingerprints()
    return runs


def _flight(g, until_s=1.2):
    return (g.seconds >= 0.1) & (g.seconds <= until_s)


def _on_ball(g, b1, b2):
    """Per frame: 0 on BallLeft, 1 on BallRight, -1 on neither (the nearer in angle when on both)."""
    a1, a2 = angle_to(g, b1), angle_to(g, b2)
    return np.where(np.minimum(a1, a2) < FIX_DEG, np.where(a1 <= a2, 0, 1), -1)


def _switches(on, min_frames=3):
    """Changes of ball between fixations of at least ``min_frames`` frames (0.1 s at 30 fps): a
    frame or two on a ball, a saccade passing over it or a pursuit catching up, is not a switch."""
    edges = np.flatnonzero(np.diff(np.r_[-2, on, -2]))
    seq = [on[a] for a, b in zip(edges[:-1], edges[1:]) if on[a] >= 0 and b - a >= min_frames]
    return int(sum(x != y for x, y in zip(seq, seq[1:])))


def _min_frames(g, seconds):
    return int(round(seconds / np.median(np.diff(g.seconds))))


def test_the_planner_reports_every_step(two_balls):
    """``attend`` shows a bar of the planner's steps on a terminal (it was silent for minutes on a long
    shot): the loop reports each step done of all of them."""
    steps = PROGRESS[-1][1]
    assert steps > 10 and PROGRESS == [(k, steps) for k in range(1, steps + 1)]


def test_distance_cost_keeps_the_point_of_sight_between_the_balls(two_balls):
    g, b1, b2 = two_balls["distance"]
    f = _flight(g)
    mid = np.linalg.norm(g.sight - 0.5 * (b1 + b2), axis=1)[f]
    half = 0.5 * np.linalg.norm(b1 - b2, axis=1)[f]  # 1.5 m at the start, 0.25 m at the arrival
    near = np.minimum(np.linalg.norm(g.sight - b1, axis=1), np.linalg.norm(g.sight - b2, axis=1))[f]
    assert np.median(mid) < 0.15 and np.median(near / half) > 0.8  # measured 0.07 m and 0.99
    assert np.mean(_on_ball(g, b1, b2)[f] >= 0) < 0.1


def test_uncertainty_cost_switches_back_and_forth(two_balls):
    """Figure 4c: the point of sight on a ball (not between them) most of the flight, both balls
    watched in turns, switching back and forth. Measured to the first arrival (seeds 0-3): switches
    between fixations of >= 0.1 s 3, 3, 4, 3; the less watched ball's share 20-42 %; on a ball 72-95 %.
    (Seed 0's 28 % was 20 % once no saccade could start at 1.0 s, in a recharge window: 8 of 40 frames.)"""
    switches = []
    for n in SEEDS:
        g, b1, b2 = two_balls[f"uncertainty seed {n}"]
        whole = g.seconds <= ARRIVAL_S[0]
        on = _on_ball(g, b1, b2)[whole]
        assert np.mean(on >= 0) > 0.65, n
        assert min(np.mean(on == 0), np.mean(on == 1)) > 0.15, n
        mid = np.linalg.norm(g.sight - 0.5 * (b1 + b2), axis=1)[whole]
        half = 0.5 * np.linalg.norm(b1 - b2, axis=1)[whole]
        assert np.median(mid / half) > 0.8, n  # at a ball, half their separation from the midpoint (1.0)
        # and in depth too: the eyes' vergence point a median few cm from the ball they fixate
        gap = np.stack([np.linalg.norm(g.sight - b1, axis=1), np.linalg.norm(g.sight - b2, axis=1)], 1)[whole]
        assert np.median(gap[np.arange(len(on)), np.maximum(on, 0)][on >= 0]) < 0.15, n  # 0.06-0.09 m
        switches.append(_switches(on))
    assert min(switches) >= 3, switches


def _last_shares(g, b1, b2, span_s=0.3):
    """Share of the frames of the last ``span_s`` s before the first arrival on BallLeft, on BallRight."""
    f = (g.seconds > ARRIVAL_S[0] - span_s - 1e-6) & (g.seconds <= ARRIVAL_S[0] + 1e-6)
    on = _on_ball(g, b1, b2)[f]
    return np.mean(on == 0), np.mean(on == 1)


def test_the_ball_to_catch_first_holds_the_eyes_before_it_arrives(catch_balls, two_balls):
    """Figure 4c's dwell on the nearer ball near the arrival, where the balls are thrown to be caught.
    Measured over the last 0.3 s (9 frames) before BallLeft arrives (seeds 0-3): on BallLeft 78, 100,
    100, 78 %, on BallRight 0, 0, 0, 0 %; before it, back and forth (2, 4, 4, 2 switches). The same
    throws arriving at the chest with a constant importance (two_balls.usda): on BallLeft 11, 0, 33, 0 %
    (the later ball is taken)."""
    for n, (g, b1, b2) in catch_balls.items():
        first, other = _last_shares(g, b1, b2)
        assert first >= 0.6 and other <= 0.25, (n, first, other)
        assert _switches(_on_ball(g, b1, b2)[g.seconds <= ARRIVAL_S[0]]) >= 2, n
    assert max(_last_shares(*two_balls[f"uncertainty seed {n}"])[0] for n in SEEDS) <= 0.4


def test_the_literal_per_step_process_noise_holds_one_ball(two_balls):
    """The paper's alpha read as a variance added every step (not per second): the unwatched ball's
    noise saturates in ~4 steps, so coming back buys little and the planner holds one ball, where the
    per-second reading switches three or four times and watches each ball 20-60 % (docs/attend.md).
    Measured, seeds 0-3: 2, 0, 1, 1 switches, the held ball 88, 88, 60, 60 %, the other 7, 3, 12, 7 %
    (seed 0's second switch is one 0.1 s glance at the other ball and back). With the head's turn
    priced 20 times the paper's w_trk it was 0, 1, 0, 1 switches, the other ball up to 35 %."""
    g, b1, b2 = two_balls["per step"]
    on = _on_ball(g, b1, b2)[g.seconds <= ARRIVAL_S[0]]
    shares = sorted([np.mean(on == 0), np.mean(on == 1)])
    assert _switches(on) <= 2 and shares[1] > 0.55 and shares[0] < 0.15, (_switches(on), shares)  # 2, 0.88, 0.07


def test_sequential_tracks_one_ball_then_the_other(two_balls):
    g, b1, b2 = two_balls["sequential"]
    f = (g.seconds >= 0.3) & (g.seconds <= 1.2)
    on = _on_ball(g, b1, b2)[f]
    assert np.mean(on == 0) > 0.8 and not (on == 1).any()  # the first ball all the way to its arrival


def _fixation_episodes(g, ball, until_s=ARRIVAL_S[1]):
    """Fixations of at least 0.1 s before the ball arrives, as (start s, end s)."""
    on = (angle_to(g, ball) < FIX_DEG) & (g.seconds <= until_s)
    return [(g.seconds[a], g.seconds[b - 1]) for a, b in episodes(on) if b - a >= _min_frames(g, 0.1)]


def test_alpha_zero_glances_once_alpha_positive_tracks(one_ball):
    """0: one glance, then the ball is left for most of its flight (it is looked at again only as it
    arrives, the last 0.2 s); 0.2 and 0.4: one fixation from the first glance to the arrival."""
    eps = {alpha: _fixation_episodes(one_ball[alpha][1], one_ball[alpha][2]) for alpha in ("0", "0.2", "0.4")}
    first = eps["0"][0]
    assert first[0] < 0.2 and first[1] < 0.9  # measured 0.03-0.77 s
    after = [a for a, _ in eps["0"][1:]]
    assert not after or min(after) - first[1] > 0.4  # measured: again at 1.20-1.30 s
    for alpha in ("0.2", "0.4"):
        assert len(eps[alpha]) == 1 and eps[alpha][0][0] < 0.2 and eps[alpha][0][1] > 1.3  # 0.03-1.37 s


def test_alpha_04_estimate_follows_the_noisy_observations_more(one_ball):
    """The paper: a larger alpha gives a larger gain, so the estimate relies more on the noisy
    observation. Measured as the frame-to-frame roughness (second difference) of the written estimate
    while fixated: 25.1 mm at 0.4 against 22.8 mm at 0.2 (seed 0; 19.6 against 18.5 mm with seed 1)."""
    rough = {}
    for alpha in ("0.2", "0.4"):
        _, g, ball = one_ball[alpha]
        est = inspection(g.stage, "/Objects/Ball", "estimate", g.times)
        d2 = np.linalg.norm(est[2:] - 2 * est[1:-1] + est[:-2], axis=1)
        fixated = (_flight(g) & (angle_to(g, ball) < FIX_DEG))[1:-1]
        rough[alpha] = np.median(d2[fixated])
    assert rough["0.4"] > 1.03 * rough["0.2"]


def test_estimate_converges_while_fixated(one_ball):
    _, g, ball = one_ball["0.2"]
    est = inspection(g.stage, "/Objects/Ball", "estimate", g.times)
    err = np.linalg.norm(est - ball, axis=1)
    (a, b), *_ = episodes(angle_to(g, ball) < FIX_DEG)
    assert b - a > 10
    late = err[b - (b - a) // 4:b]  # the last quarter of the fixation
    assert late.mean() < 0.1 and late.mean() < 0.5 * err[a:b].max()


def test_uncertainty_grows_while_not_looked_at(two_balls):
    """Every time a ball is left for at least 0.1 s after being fixated, its written sigma_p rises
    during the neglect to at least 1.3 x its value when it was left. Not in the first 0.3 s: while a
    new track's velocity is still being learned its sigma_p falls even in the periphery."""
    g, b1, b2 = two_balls["uncertainty seed 1"]
    on = _on_ball(g, b1, b2)
    checked = 0
    for obj, j in (("/Objects/BallLeft", 0), ("/Objects/BallRight", 1)):
        unc = inspection(g.stage, obj, "uncertainty", g.times)
        for a, b in episodes((on != j) & (g.seconds < ARRIVAL_S[0])):
            if b - a >= _min_frames(g, 0.1) and g.seconds[a] > 0.3 and on[a - 1] == j:
                assert unc[a:b].max() > 1.3 * unc[a - 1], (obj, g.seconds[a])
                checked += 1
    assert checked >= 2
    # and while fixated it falls: the watched ball's sigma_p at the end of each fixation of >= 0.2 s is
    # below its value when the fixation began
    for obj, j in (("/Objects/BallLeft", 0), ("/Objects/BallRight", 1)):
        unc = inspection(g.stage, obj, "uncertainty", g.times)
        for a, b in episodes(on == j):
            if b - a >= _min_frames(g, 0.2) and a > 0:
                assert unc[b - 1] < unc[a - 1]


def test_eye_range_and_speed_limits(one_ball, two_balls, catch_balls):
    runs = [r[0] for r in list(two_balls.values()) + list(catch_balls.values())]
    for g in [one_ball[a][1] for a in ("0", "0.2", "0.4")] + runs:
        assert np.abs(g.yaw).max() <= 44.2 + 0.5
        assert -47.1 - 0.5 <= g.pitch.min() and g.pitch.max() <= 27.7 + 0.5
        # eye-in-head angular speed between frames
        yaw, pitch = np.radians(g.yaw), np.radians(g.pitch)
        d = np.stack([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)], -1)
        step = np.degrees(np.arccos(np.clip((d[1:] * d[:-1]).sum(-1), -1, 1)))
        speed = step / np.diff(g.seconds)
        assert speed.max() <= 800 * SPEED_TOL
        # Windows from the frame times with a tolerance: 1.0 % 0.4 is 0.19999999999999996, which left
        # the windows at 1.0 s (30 fps) out of this check while a saccade ran in them.
        period = np.floor((g.seconds + 1e-6) / 0.4)
        phase = g.seconds - 0.4 * period
        recharge = (phase[:-1] >= 0.2 - 1e-6) & (period[:-1] == period[1:])  # both ends inside one recharge window
        assert recharge.sum() > 10 and speed[recharge].max() <= 100 * SPEED_TOL


def test_input_untouched_and_muting_restores(one_ball):
    assert one_ball["inputs_unchanged"]  # bytes and modes of every input file, before and after three runs
    out, g, _ = one_ball["0.2"]
    plain = measure.posed(str(ATTEND / "ball_throw.usda"), "/root/Body/BodySkel")
    assert plain.world.shape[1] == 31  # no eye joints in the input; the override adds two
    layer = g.stage.GetRootLayer()
    muted = measure.posed(layer.realPath, "/root/Body/BodySkel", mute=[str(out)])
    assert np.array_equal(muted.world, plain.world)


def test_realize_map_looks_at_the_planners_fixations_through_the_gaze_map(tmp_path, one_ball):
    """--realize map: the fixations become look directives; the map's cascade moves the whole chain."""
    _, direct, ball = one_ball["0.2"]
    out, g = _run(tmp_path, ATTEND / "ball_throw.usda", "--realize", "map", name="map.usdc")
    f = _flight(g, 1.2)
    on_map = angle_to(g, ball)[f] < FIX_DEG
    on_direct = angle_to(direct, ball)[_flight(direct, 1.2)] < FIX_DEG
    assert on_map.mean() > 0.6 and on_direct.mean() > 0.8
    plain = measure.posed(str(ATTEND / "ball_throw.usda"), "/root/Body/BodySkel")
    moved = measure.posed(str(g.stage.GetRootLayer().realPath), "/root/Body/BodySkel")
    head = plain.index("Head")
    turn = measure.rotation_angle_deg(moved.world[:, head, :3, :3], plain.world[:, head, :3, :3])
    assert turn.max() > 2.0  # the head took part (the ball comes from nearly straight ahead)


def test_a_mirrored_character_looks_at_the_balls_as_the_plain_one_does(tmp_path):
    """The character's SkelRoot parent scaled (-1, 1, 1) (a mirrored copy): the planner's world turns
    and eye yaw are carried into the skeleton with their sense reversed, so the eyes still find the
    balls (measured by UsdSkel FK on the written layer against the balls' true positions)."""
    stage = ATTEND / "two_balls.usda"
    mirrored = tmp_path / "mirrored.usda"
    layer = Sdf.Layer.CreateNew(str(mirrored))
    layer.subLayerPaths.append(str(stage))
    src = Sdf.Layer.FindOrOpen(str(stage))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(layer, key, getattr(src, key))
    for key in ("upAxis", "metersPerUnit"):  # stage metadata is the root layer's alone
        layer.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    root = Sdf.CreatePrimInLayer(layer, "/root")
    root.specifier = Sdf.SpecifierOver
    Sdf.AttributeSpec(root, "xformOp:scale", Sdf.ValueTypeNames.Float3).default = Gf.Vec3f(-1.0, 1.0, 1.0)
    order = Sdf.AttributeSpec(root, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
    order.default = Vt.TokenArray(["xformOp:scale", "xformOp:rotateXYZ"])  # the walk's own rotation kept
    layer.Save()
    medians = []
    for name, src_stage in (("plain.usdc", stage), ("mirrored.usdc", mirrored)):
        _, g = _run(tmp_path, src_stage, name=name)
        near = np.min([angle_to(g, positions(g.stage, b, g.times)) for b in ("/Objects/BallLeft", "/Objects/BallRight")],
                      axis=0)
        medians.append(np.median(near))
    assert max(medians) <= FIX_DEG, medians  # the plain one beside it (unfixed, the mirrored one was 53-78 deg)
