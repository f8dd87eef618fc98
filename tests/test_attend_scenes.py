"""``usdgaze attend``: field of view, stepping stones, determinism, bad inputs (one line, exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pxr import Gf, Sdf

from tests import measure
from tests.attend_support import ATTEND, angle_to, compose, gaze, inspection, positions
from tests.stone_stages import copy_animation
from usdgaze.console.main import main

CMU = ATTEND.parent / "cmu"


def _stage_with(tmp, name, sublayers, build, start=None, end=None, tcps=None):
    layer = Sdf.Layer.CreateNew(str(tmp / name))
    layer.subLayerPaths[:] = [str(s) for s in sublayers]
    src = Sdf.Layer.FindOrOpen(str(sublayers[0]))
    layer.startTimeCode = src.startTimeCode if start is None else start
    layer.endTimeCode = src.endTimeCode if end is None else end
    layer.timeCodesPerSecond = layer.framesPerSecond = tcps or src.timeCodesPerSecond
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)  # USD's fallback would be centimetres
    build(layer)
    layer.Save()
    return tmp / name


def _object(layer, path, samples, type_name="Sphere"):
    for parent in Sdf.Path(path).GetAncestorsRange():
        if parent.pathElementCount == 1 or parent == Sdf.Path(path):
            spec = Sdf.CreatePrimInLayer(layer, parent)
            spec.specifier = Sdf.SpecifierDef
            spec.typeName = "Xform" if parent != Sdf.Path(path) else type_name
    prim = layer.GetPrimAtPath(path)
    prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    if type_name in ("Sphere", "Xform"):
        tr = Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3)
        for t, p in samples:
            layer.SetTimeSample(tr.path, float(t), Gf.Vec3d(*p))
        Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    return prim


def test_an_object_outside_the_field_of_view_is_not_looked_at_before_it_enters(tmp_path):
    """A ball comes from behind the character's right, passes it and goes ahead."""
    base = [ATTEND / "standing.usdc", CMU / "cmu_131_01.usdc"]
    p = measure.posed(str(ATTEND / "ball_throw.usda"), "/root/Body/BodySkel")
    eyes = p.position("Head")[0]
    fwd = p.skel_to_world[:3, :3].T @ measure.character_forward_skel(p, "LeftHip", "RightHip")
    fwd = fwd - fwd[1] * np.array([0, 1.0, 0])
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0, 1.0, 0])
    start = eyes - 3.0 * fwd + 1.2 * right
    end = eyes + 4.0 * fwd + 1.2 * right
    samples = [(1 + 4 * i, tuple(start + (end - start) * i / 60)) for i in range(61)]
    stage = _stage_with(tmp_path, "behind.usda", base, lambda l: _object(l, "/Objects/Passing", samples))
    out = tmp_path / "behind_out.usdc"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.6"]) == 0
    g = gaze(compose(tmp_path, stage, out))
    ball = positions(g.stage, "/Objects/Passing", g.times)
    to = ball - g.eyes
    in_view = np.degrees(np.arccos(np.clip((to / np.linalg.norm(to, axis=1, keepdims=True) * g.head_fwd).sum(1), -1, 1))) <= 60
    first = int(np.argmax(in_view))
    assert 5 < first < len(g.times) - 10
    assert angle_to(g, ball)[:first].min() > 20.0
    assert angle_to(g, ball)[first:].min() < 5.0  # and it is looked at once seen


@pytest.mark.parametrize("radius", [0.25, None])
def test_a_sphere_is_seen_when_its_edge_enters_the_field_of_view(tmp_path, radius):
    """A still 25 cm sphere 1.2 m from the eyes, its centre 66 deg off the head's forward: its edge is
    asin(0.25 / 1.2) = 12 deg nearer, 54 deg, inside the +-60 deg field of view, so it is seen from the
    first frame and turned to; without an authored radius it is a point 66 deg off, never seen."""
    base = [ATTEND / "standing.usdc", CMU / "cmu_131_01.usdc"]
    p = measure.posed(str(ATTEND / "ball_throw.usda"), "/root/Body/BodySkel")
    eyes = p.position("Head")[0]  # the source has no eyes yet: placed from the head, measured from the eyes
    fwd = p.axis("Head", measure.local_forward(p, "Head", measure.character_forward_skel(p, "LeftHip", "RightHip")))[0]
    fwd = fwd - fwd[1] * np.array([0, 1.0, 0])
    fwd /= np.linalg.norm(fwd)
    left = np.cross([0, 1.0, 0], fwd)
    a = np.radians(66.0)
    at = tuple(eyes + 1.2 * (np.cos(a) * fwd + np.sin(a) * left))

    def build(layer):
        prim = _object(layer, "/Objects/Side", [(1, at), (241, at)])
        if radius is not None:
            Sdf.AttributeSpec(prim, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = radius

    stage = _stage_with(tmp_path, "side.usda", base, build, end=241)
    out = tmp_path / "side_out.usdc"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.6"]) == 0
    g = gaze(compose(tmp_path, stage, out))
    ball = positions(g.stage, "/Objects/Side", g.times)
    to = ball - g.eyes
    off_head = np.degrees(np.arccos(np.clip((to / np.linalg.norm(to, axis=1, keepdims=True) * g.head_fwd).sum(1), -1, 1)))
    edge = np.degrees(np.arcsin(0.25 / np.linalg.norm(to[0])))
    assert 60 < off_head[0] < 60 + edge  # at the first frame only its edge is in view (by UsdSkel FK)
    off = angle_to(g, ball)  # the line of sight's
    if radius is None:
        assert off_head.min() > 60 and off.min() > 50  # a point stays out of view: never looked at
    else:
        assert off[:10].min() < 20  # seen, and turned to within 0.3 s (66 deg is past the eyes' 44 deg range)


def _circling(eyes, fwd, keys_s, tcps):
    """Samples every 4 codes of a point 2 m from ``eyes`` at eye height, at the angle (deg, + left of
    ``fwd``) interpolated between ``keys_s`` [(seconds from the stage start, deg)]."""
    left = np.cross([0, 1.0, 0], fwd)
    out = []
    for code in range(1, 242, 4):
        a = np.radians(np.interp((code - 1) / tcps, *zip(*keys_s)))
        out.append((code, tuple(eyes + 2.0 * (np.cos(a) * fwd + np.sin(a) * left))))
    return out


@pytest.mark.parametrize("start", [None, 133.0])
def test_first_seen_is_when_it_enters_the_view_in_seconds_from_the_stage_start(tmp_path, capsys, start):
    """A ball circles in from behind (in view from ~0.3 s), out behind again (~0.76 s) and back in (~1.7 s).
    Over the whole stage it is first seen when it first enters; over a range of 1.1-1.9 s (codes 133-229) it is
    first seen when it enters after the range starts, in seconds from the stage's start (from the take's
    first frame it was reported at -0.8 s: the pass planned the take before the range). The entry is
    measured on the written layer by UsdSkel FK: the ball's direction from the eyes within 60 deg of
    the head's forward (docs/attend.md)."""
    base = [ATTEND / "standing.usdc", CMU / "cmu_131_01.usdc"]
    p = measure.posed(str(ATTEND / "ball_throw.usda"), "/root/Body/BodySkel")
    fwd = p.axis("Head", measure.local_forward(p, "Head", measure.character_forward_skel(p, "LeftHip", "RightHip")))[0]
    fwd = fwd - fwd[1] * np.array([0, 1.0, 0])
    tcps = Sdf.Layer.FindOrOpen(str(base[0])).timeCodesPerSecond
    keys = [(0.0, 120.0), (0.5, 20.0), (0.6, 20.0), (1.0, 120.0), (1.4, 120.0), (1.9, 20.0), (2.0, 20.0)]
    samples = _circling(p.position("Head")[0], fwd / np.linalg.norm(fwd), keys, tcps)
    end = None if start is None else 229.0  # the take goes on after it (to 241): the planner's last windows see it
    stage = _stage_with(tmp_path, "circling.usda", base, lambda l: _object(l, "/Objects/Ball", samples), start, end)
    out = tmp_path / "circling_out.usdc"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.6", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    reported = report["characters"][0]["objects"][0]["first_seen_s"]
    t0 = 1.0 if start is None else start
    codes = np.arange(t0, (end or 241.0) + 1e-9)  # every time code: the entry to 1/120 s
    g = gaze(compose(tmp_path, stage, out), times=codes)
    to = positions(g.stage, "/Objects/Ball", codes) - g.eyes
    off = np.degrees(np.arccos(np.clip((to / np.linalg.norm(to, axis=1, keepdims=True) * g.head_fwd).sum(1), -1, 1)))
    entry = g.seconds[int(np.argmax(off <= 60.0))]
    assert 0.25 < entry < 0.35 if start is None else 0.55 < entry < 0.65  # the path's own 0.3 s, 1.7 - 1.1 s
    # The planner senses every 25 ms: first seen at its first step inside the view.
    assert entry - 0.01 <= reported <= entry + 0.025 + 0.01, (reported, entry)
    # The inspection prims say the same: no estimate before the ball is seen, one from the next frame.
    frames = np.array(g.stage.GetPrimAtPath("/UsdGazeAttend/root_Body/Objects_Ball")
                      .GetAttribute("gaze:attend:estimate").GetTimeSamples())
    assert frames[0] == t0 and frames[-1] == (end or 241.0)  # the range's frames only
    est = inspection(g.stage, "/Objects/Ball", "estimate", frames)
    tracked = (frames[np.isfinite(est[:, 0])][0] - t0) / tcps
    assert reported <= tracked <= reported + 4 / tcps + 1e-6
    if start is not None:  # outside the range the layer gives back the take's own pose, as --physics does
        outside = np.r_[np.arange(1.0, start, 4.0), np.arange(end + 4.0, 242.0, 4.0)]
        head = [measure.posed(str(f), "/root/Body/BodySkel", times=outside).world[:, p.index("Head")]
                for f in (stage, compose(tmp_path, stage, out, "again.usda"))]
        assert np.allclose(head[0], head[1], atol=1e-6)


@pytest.fixture(scope="module")
def stones(tmp_path_factory):
    """The stepping-stone walk cropped to frames 480-800 (the walk), at 30 fps."""
    tmp = tmp_path_factory.mktemp("stones")
    src = Sdf.Layer.FindOrOpen(str(CMU / "cmu_131_01.usdc"))
    anim = "/root/Body/BodySkel/scaled_131_01"
    codes = np.arange(480.0, 800.0 + 1e-6, 4.0)

    def crop(layer):
        copy_animation(layer, src, anim, codes)

    stage = _stage_with(tmp, "walk.usda", [ATTEND / "stepping_stones.usda"], crop, 480.0, 800.0)
    out = tmp / "walk_out.usdc"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.6"]) == 0
    return gaze(compose(tmp, stage, out))


def test_line_of_sight_reaches_the_next_stone_before_its_foot_lifts(stones):
    g = stones
    checked, missed = 0, []
    for prim in g.stage.Traverse():
        land = prim.GetAttribute("userProperties:landing")
        if not land:
            continue
        swing = prim.GetAttribute("userProperties:swingStart").Get()
        if not (g.times[0] + 48 <= swing <= g.times[-1]):  # give the planner 0.4 s to start
            continue
        stone = positions(g.stage, str(prim.GetPath()), g.times)
        before = g.times <= swing
        dist = np.linalg.norm(g.sight - stone, axis=1)
        if not ((angle_to(g, stone)[before] < 5.0).any() or dist[before].min() < 0.3):
            missed.append(str(prim.GetPath()))
        checked += 1
    # 5 of the 6 footfalls in the crop are fixated in time; the miss is Stone14, the foot shuffled
    # beside the other as the walk stops (its importance overlaps two other stones').
    assert checked >= 6 and len(missed) <= 1, missed


def test_same_seed_same_bytes_other_seed_differs(tmp_path):
    outs = []
    for i, seed in enumerate(("3", "3", "4")):
        out = tmp_path / f"s{i}.usda"
        assert main(["attend", str(ATTEND / "ball_throw.usda"), "--out", str(out), "--window", "0.1",
                     "--seed", seed]) == 0
        outs.append(out.read_bytes())
    assert outs[0] == outs[1] and outs[0] != outs[2]


def _typeless(layer):
    spec = Sdf.CreatePrimInLayer(layer, "/Objects/Marker")
    spec.specifier = Sdf.SpecifierDef
    spec.typeName = "Scope"
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))


@pytest.mark.parametrize("case", ["no objects", "no transform", "alpha", "alpha huge", "window", "window inf",
                                  "missing prim"])
def test_bad_inputs_one_line_exit_2_nothing_written(tmp_path, capsys, case):
    stage, extra = ATTEND / "ball_throw.usda", []
    if case == "no objects":
        stage = CMU / "cmu_131_01.usdc"
        want = "no objects to look at"
    elif case == "no transform":
        stage = _stage_with(tmp_path, "bad.usda", [ATTEND / "ball_throw.usda"], _typeless)
        want = "/Objects/Marker: is a Scope without a transform"
    elif case == "alpha":
        extra, want = ["--alpha", "-0.1"], "--alpha -0.1: the process noise must be >= 0"
    elif case == "alpha huge":  # ran to exit 0 under 30 lines of numpy overflow warnings
        extra, want = ["--alpha", "1e300"], "--alpha 1e+300: over 100 an unwatched object's position spreads"
    elif case == "window":
        extra, want = ["--window", "0.03"], "--window 0.03 s: shorter than two planner steps"
    elif case == "window inf":  # was called shorter than two planner steps
        extra, want = ["--window", "inf"], "--window inf s: expected 0.05 to 5 s"
    else:
        extra, want = ["--objects", "/Objects/Nope"], "/Objects/Nope: no such prim"
    out = tmp_path / "out.usda"
    args = ["attend", str(stage), "--out", str(out)] + (extra if case != "window" else extra)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and want in err, err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]
