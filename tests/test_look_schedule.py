"""GazeScheduleAPI schedules, USD look-at targets, and the eye-movement functions.

Target positions are checked against the values authored in the test stage (plain numbers, not
usdgaze's reading); main-sequence and pursuit figures against the published relations.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel

from usdgaze import api
from usdgaze.errors import UsdGazeError
from usdgaze.gaze import saccade
from usdgaze.passes.requests import parse_look, parse_release, parse_shift
from usdgaze.usd import schedule
from usdgaze.usd.targets import sample_target

from . import stages

TCPS = 120.00479955795427
FLAGS = dict(shifts=["60:30:0", "400:-20:5:weight=0.6:blend=12"],
             look_at=["/World/Ball@150:weight=0.8:blend=24", "0.5,1.2,3@600", "/World/Box@800"],
             release=["700", "1000:blend=60"])


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("schedule")
    standing = stages.standing(d / "standing.usdc", 1200)
    centre = stages.eye_height(standing)
    root = stages.with_targets(d / "scene.usda", standing, centre, 2.0, 30.0, 1200, TCPS)
    return d, root, centre


def _with_schedule(d, root, requests, name):
    path = d / f"{name}.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.GetRootLayer().subLayerPaths.append(str(root))
    stage.SetTimeCodesPerSecond(TCPS)  # as the layers below: no rescaled samples
    below = Usd.Stage.Open(str(root))  # and their units: a stage's are its root layer's
    UsdGeom.SetStageUpAxis(stage, UsdGeom.GetStageUpAxis(below))
    UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.GetStageMetersPerUnit(below))
    prim = stage.OverridePrim("/root/Body")
    schedule.write_schedule(prim, requests)
    stage.GetRootLayer().Save()
    return path


def test_schedule_and_the_same_flags_give_byte_identical_layers(scene):
    d, root, _ = scene
    requests = ([parse_shift(s) for s in FLAGS["shifts"]] + [parse_look(s) for s in FLAGS["look_at"]]
                + [parse_release(s) for s in FLAGS["release"]])
    scheduled = _with_schedule(d, root, requests, "scheduled")
    from_schedule = api.apply(scheduled, [], d / "from_schedule.usdc")
    from_flags = api.apply(scheduled, FLAGS["shifts"], d / "from_flags.usdc", look_at=FLAGS["look_at"],
                           release=FLAGS["release"])
    assert (d / "from_schedule.usdc").read_bytes() == (d / "from_flags.usdc").read_bytes()
    assert from_schedule.directives == from_flags.directives
    assert len(from_schedule.directives["/root/Body"]) == 7
    # The schedule as authored: a relationship to the prims, parallel arrays.
    stage = Usd.Stage.Open(str(scheduled))
    prim = stage.GetPrimAtPath("/root/Body")
    assert prim.HasAPI("GazeScheduleAPI") and prim.IsA(UsdSkel.Root)
    assert [str(p) for p in prim.GetRelationship(schedule.TARGETS_REL).GetTargets()] == ["/World/Ball", "/World/Box"]
    assert list(prim.GetAttribute(schedule.KIND).Get()) == ["shift", "look", "shift", "look", "release", "look", "release"]


def test_schedule_read_back_and_refused_on_other_prims(scene):
    d, root, _ = scene
    requests = [parse_look("/World/Ball@150:weight=0.3:blend=12"), parse_release("300:blend=24")]
    stage = Usd.Stage.Open(str(_with_schedule(d, root, requests, "read_back")))
    prim = stage.GetPrimAtPath("/root/Body")
    assert [str(r) for r in schedule.read_schedule(prim, "x")] == ["/World/Ball@150:weight=0.3:blend=12",
                                                                   "300:blend=24"]
    memory = Usd.Stage.CreateInMemory()
    other = memory.DefinePrim("/X", "Xform")
    with pytest.raises(UsdGazeError, match="applies only to SkelRoot"):
        schedule.write_schedule(other, requests)


def test_targets_bbox_centre_pivot_and_animation(scene):
    _, root, centre = scene
    stage = Usd.Stage.Open(str(root))
    times = np.arange(1.0, 1201.0, 97.0)
    ball = sample_target(stage, "/World/Ball", times, "scene")
    assert np.abs(ball - stages.orbit_positions(centre, 2.0, 30.0, times, TCPS)).max() < 1e-9
    box = sample_target(stage, "/World/Box", times, "scene")  # a Cube: the centre of its bounds
    assert np.abs(box - (centre + [0.0, 0.0, 3.0])).max() < 1e-9
    # translate (1, 0, 0), pivot (0, 2, 0), rotateY 90: the pivot lands at (1, 2, 0), whatever the turn.
    lamp = sample_target(stage, "/World/Lamp", times[:2], "scene")
    assert np.abs(lamp - [1.0, 2.0, 0.0]).max() < 1e-9


def test_main_sequence_figures():
    a = np.array([5.0, 10.0, 30.0, 60.0, 120.0, 1000.0])
    assert np.allclose(saccade.duration(a), 0.025 + 0.0024 * a)
    peak = saccade.peak_speed(a)
    assert np.all(np.diff(peak) > 0) and peak.max() < 800.0  # rises with amplitude, saturates under 800
    assert 300 <= saccade.peak_speed(10.0) <= 400  # the main sequence's exponential fits put a 10 deg saccade's peak near 300-400 deg/s
    # The profile itself: sampled finely, its steepest slope is the stated peak speed.
    t = np.linspace(0.0, float(saccade.duration(30.0)), 20001)
    p = saccade.progress(t, 30.0) * 30.0
    assert np.gradient(p, t).max() == pytest.approx(float(saccade.peak_speed(30.0)), rel=1e-3)
    assert p[0] == 0.0 and p[-1] == pytest.approx(30.0)


def test_pursuit_latency_cap_and_vor():
    seconds = np.arange(0.0, 2.0, 1 / 120)
    eye = np.zeros((len(seconds), 3))
    # A target crossing 2 m in front at 200 deg/s (as seen from the eye): pursuit caps at 100.
    ang = np.radians(200.0) * seconds
    target = 2.0 * np.column_stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)])
    tracked = saccade.pursue(target, eye, seconds, 0, 0.0)
    d = tracked / np.linalg.norm(tracked, axis=1, keepdims=True)
    speed = np.degrees(np.arccos(np.clip(np.sum(d[1:] * d[:-1], 1), -1, 1))) * 120
    assert speed.max() <= 100.5 and speed[60:].min() > 95.0
    assert np.all(speed[:17] < 0.1)  # nothing before the 150 ms latency
    # A still target while the viewer moves: held exactly (the eyes cancel self-motion at once).
    walking = np.column_stack([np.zeros_like(seconds), 0.05 * np.sin(12 * seconds), 1.2 * seconds])
    still = np.tile([1.0, 1.6, 5.0], (len(seconds), 1))
    assert np.abs(saccade.pursue(still, walking, seconds, 10, 0.0) - still[10:]).max() < 1e-12


def test_cli_look_at_release_and_eye_timing(scene, capsys):
    import json

    from usdgaze.console.main import main

    d, root, _ = scene
    code = main(["apply", str(root), "--look-at", "/World/Ball@100:weight=0.5", "--release", "300:blend=0.25s",
                 "--eye-timing", "model", "--no-guides", "--out", str(d / "cli.usda"), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["characters"][0]["directives"] == ["--look-at /World/Ball@100:weight=0.5", "--release 300:blend=0.25s"]
    text = (d / "cli.usda").read_text()
    assert "gazeGuides" not in text and 'eyeTiming = "model"' in text


def test_catch_up_saccades_keep_a_fast_target_in_sight():
    from usdgaze.passes import eyes
    from usdgaze.passes.look import LookOptions

    seconds = np.arange(0.0, 3.0, 1 / 120)
    eye = np.zeros((len(seconds), 3))
    # A target crossing at 160 deg/s, faster than pursuit's 100: catch-up saccades must make up the rest.
    ang = np.radians(160.0) * seconds - np.radians(120.0)
    target = 3.0 * np.column_stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)])
    scene = eyes.Scene(seconds, eye, np.tile([0.0, 0.0, 2.0], (len(seconds), 1)))
    sight = eyes.point_of_sight(scene, [(12, eyes.Goal("target", target))], LookOptions())
    d = sight.point / np.linalg.norm(sight.point, axis=1, keepdims=True)
    u = target / 3.0
    err = np.degrees(np.arccos(np.clip(np.sum(d * u, 1), -1, 1)))
    catch_ups = [s for s in sight.saccades if s[0] > seconds[12]]
    assert len(catch_ups) >= 5
    assert err[60:].max() < 1.0 + 0.2 * 60.0 + 5.0  # bounded: refractory 200 ms at a 60 deg/s shortfall
    speed = np.degrees(np.arccos(np.clip(np.sum(d[1:] * d[:-1], 1), -1, 1))) * 120
    assert speed.max() <= 800.0
    assert np.median(speed[~sight.saccading[1:]][60:]) == pytest.approx(100.0, abs=2.0)  # pursuit at its cap
