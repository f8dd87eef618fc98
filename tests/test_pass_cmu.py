"""The gaze pass on real CMU capture (Y-up Blender export, 120.0048 tc/s, starts at 1, no eyes).

These check the paper's model (``eye_timing model``: the eyes follow the map's gaze progress, with
its overshoot); tests/test_look.py checks the default saccadic eyes.

Every number here is measured on the composed result with UsdSkel's own forward kinematics
(tests/measure.py), not with usdgaze's math.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel, UsdValidation

import usdgaze
from usdgaze import api
from usdgaze.passes.look import LookOptions

from . import measure

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu"
SKEL = "/root/Body/BodySkel"
ANIM = "/root/Body/BodySkel/scaled_131_02"
HEAD = "Head"
SHIFTS = ["150:60:0", "400:-120:10", "700:0:0", "950:30:-20"]
CHAIN_LEAVES = {"Hips", "lowerback", "Chest", "Chest2", "lowerneck", "Neck", "Head", "LeftEye", "RightEye"}
LEG_ROOTS = {"LHipJoint", "RHipJoint"}
MODEL = LookOptions(eye_timing="model")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("cmu")
    src = d / "cmu_131_02.usdc"
    shutil.copy(CMU / "cmu_131_02.usdc", src)
    before = measure.sha256(src)
    report = api.apply(src, SHIFTS, d / "gaze.usdc", preview=d / "preview.usda", look=MODEL)
    base = measure.posed(str(src), SKEL)
    new = measure.posed(str(d / "preview.usda"), SKEL)
    fwd = measure.character_forward_skel(base, "LeftHip", "RightHip")
    return dict(dir=d, src=src, before=before, report=report, base=base, new=new, fwd=fwd)


def _sight(r):
    """Achieved line-of-sight change (yaw, pitch) per frame, against the base head's line of sight."""
    return measure.gaze_change(r["base"], r["new"], r["fwd"], HEAD)


def _frames(r):
    times = r["base"].times
    timing = r["report"].characters[0].result.shift_timing
    return times, timing


def test_eyes_added_and_skeleton_stays_valid(run):
    new = run["new"]
    assert len(new.joints) == 33
    assert new.joints[:31] == run["base"].joints
    assert new.joints[31].endswith("Head/LeftEye") and new.joints[32].endswith("Head/RightEye")


def test_hold_phase_gaze_matches_request_within_half_a_degree(run):
    change, _, _ = _sight(run)
    times, timing = _frames(run)
    tcps = 120.00479955795427
    checked = 0
    for k, s in enumerate(timing):
        start_tc = 1.0 + s["time_s"] * tcps
        settled_tc = start_tc + s["duration"] * tcps
        end_tc = 1.0 + timing[k + 1]["time_s"] * tcps if k + 1 < len(timing) else np.inf
        hold = (times >= settled_tc) & (times < end_tc)
        assert hold.sum() > 30, "each shift must settle before the next one in this scenario"
        err = np.abs(change[hold] - [s["yaw"], s["pitch"]])
        assert err.max() <= 0.5, (s, err.max(axis=0))
        checked += hold.sum()
    # Before the first shift the eyes look where the head looks.
    pre = times < 150
    assert np.abs(change[pre]).max() <= 0.5
    assert checked > 500


def test_onset_order_eyes_neck_upper_lower_pelvis(run):
    base, new = run["base"], run["new"]
    times = base.times
    window = (times >= 400) & (times < 700)
    _, base_dir, sight = _sight(run)
    base_sight = measure.angle_between(sight[window], base_dir[window])
    pre_shift = measure.angle_between(sight[times == 399], base_dir[times == 399])[0]

    def onset(curve, reference=0.0):
        # Relative threshold: a joint that turns little crosses a fixed angle late.
        change = np.abs(curve - reference)
        moved = np.flatnonzero(change > max(0.05, 0.02 * change.max()))
        return times[window][moved[0]]

    def local_change(leaf):
        i = base.index(leaf)
        parent = base.joints.index(base.joints[i].rsplit("/", 1)[0])
        local_b = base.world[window, i, :3, :3] @ np.linalg.inv(base.world[window, parent, :3, :3])
        local_n = new.world[window, i, :3, :3] @ np.linalg.inv(new.world[window, parent, :3, :3])
        return measure.rotation_angle_deg(local_b, local_n)

    def pelvis_change():
        i = base.index("Hips")
        return measure.rotation_angle_deg(base.world[window, i, :3, :3], new.world[window, i, :3, :3])

    eyes = onset(base_sight, pre_shift)
    neck = onset(local_change("Neck"), local_change("Neck")[0])
    upper = onset(local_change("Chest2"), local_change("Chest2")[0])
    lower = onset(local_change("lowerback"), local_change("lowerback")[0])
    pelvis = onset(pelvis_change(), pelvis_change()[0])
    assert eyes < neck < upper < lower < pelvis, (eyes, neck, upper, lower, pelvis)


def test_overshoot_visible_in_achieved_gaze(run):
    change, _, _ = _sight(run)
    times = run["base"].times
    first = (times >= 150) & (times < 400)
    assert change[first, 0].max() > 60 * 1.03  # beyond the request ...
    assert abs(change[first, 0][-1] - 60) < 0.5  # ... then settles on it
    second = (times >= 400) & (times < 700)
    assert change[second, 0].min() < -120 - 120 * 0.03


def test_gaze_is_continuous(run):
    change, _, sight = _sight(run)
    step = measure.angle_between(sight[1:], sight[:-1])
    # 5 deg per frame at 120 fps is 600 deg/s, saccade territory; the map's fastest shift stays well under.
    assert step.max() < 5.0
    for leaf in CHAIN_LEAVES - {"LeftEye", "RightEye"}:
        i = run["new"].index(leaf)
        m = run["new"].world[:, i, :3, :3]
        assert measure.rotation_angle_deg(m[1:], m[:-1]).max() < 5.0, leaf


def test_eyes_within_the_eye_range(run):
    new, fwd = run["new"], run["fwd"]
    up_s = np.linalg.solve(new.skel_to_world[:3, :3].T, new.up)
    up_s /= np.linalg.norm(up_s)
    left_s = np.cross(up_s, fwd)
    for eye in ("LeftEye", "RightEye"):
        yaw, pitch = measure.eye_in_head(new, HEAD, eye, fwd, left_s, up_s)
        assert np.abs(yaw).max() <= 44.2 + 1e-3
        assert pitch.max() <= 27.7 + 1e-3 and pitch.min() >= -47.1 - 1e-3
        assert np.abs(yaw).max() > 20  # the eyes really carry part of the shifts


def test_feet_keep_their_world_position(run):
    base, new = run["base"], run["new"]
    for leaf in ("LeftAnkle", "RightAnkle", "LeftToe", "RightToe", "LeftKnee", "RightKnee"):
        moved = np.linalg.norm(new.position(leaf) - base.position(leaf), axis=1)
        assert moved.max() < 1e-3, leaf  # metres: 1 mm


def test_joints_outside_the_chain_are_bit_identical(run):
    src_stage = Usd.Stage.Open(str(run["src"]))
    out_layer = Sdf.Layer.FindOrOpen(str(run["dir"] / "gaze.usdc"))
    src_anim = UsdSkel.Animation(src_stage.GetPrimAtPath(ANIM))
    joints = [str(j) for j in src_anim.GetJointsAttr().Get()]
    out_joints = [str(j) for j in out_layer.GetAttributeAtPath(ANIM + ".joints").default]
    assert out_joints[: len(joints)] == joints
    untouched = [i for i, j in enumerate(joints) if j.rsplit("/", 1)[-1] not in CHAIN_LEAVES | LEG_ROOTS]
    assert len(untouched) == 31 - 7 - 2
    for name in ("rotations", "translations", "scales"):
        path = Sdf.Path(ANIM + "." + name)
        src_attr = src_anim.GetPrim().GetAttribute(name)
        times = out_layer.ListTimeSamplesForPath(path)
        assert len(times) == 1247
        for t in times[::97]:
            a = np.asarray(src_attr.Get(t))[untouched]
            b = np.asarray(out_layer.QueryTimeSample(path, t))[untouched]
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (name, t)


def test_input_untouched_and_mute_restores_exactly(run):
    assert measure.sha256(run["src"]) == run["before"]
    preview = Usd.Stage.Open(str(run["dir"] / "preview.usda"))
    override = Sdf.Layer.FindOrOpen(str(run["dir"] / "gaze.usdc"))
    preview.MuteLayer(override.identifier)
    original = Usd.Stage.Open(str(run["src"]))
    for name in ("rotations", "translations", "scales"):
        a = original.GetPrimAtPath(ANIM).GetAttribute(name)
        b = preview.GetPrimAtPath(ANIM).GetAttribute(name)
        assert a.GetTimeSamples() == b.GetTimeSamples()
        for t in a.GetTimeSamples()[::50]:
            assert np.asarray(a.Get(t)).tobytes() == np.asarray(b.Get(t)).tobytes()
    skel_a = original.GetPrimAtPath(SKEL).GetAttribute("joints").Get()
    skel_b = preview.GetPrimAtPath(SKEL).GetAttribute("joints").Get()
    assert list(skel_a) == list(skel_b)


def test_override_layer_metadata_and_only_overs(run):
    layer = Sdf.Layer.FindOrOpen(str(run["dir"] / "gaze.usdc"))
    src = Sdf.Layer.FindOrOpen(str(run["src"]))
    assert layer.timeCodesPerSecond == src.timeCodesPerSecond == pytest.approx(120.00479955795427)
    assert layer.framesPerSecond == src.framesPerSecond
    assert (layer.startTimeCode, layer.endTimeCode) == (src.startTimeCode, src.endTimeCode)
    data = layer.customLayerData["usdgaze"]
    assert data["version"] == usdgaze.__version__
    assert list(data["shifts"]) == SHIFTS
    assert "built-in default" in data["maps"][0]

    specs = []
    layer.Traverse(Sdf.Path.absoluteRootPath, lambda p: specs.append(p))
    prims = [layer.GetPrimAtPath(p) for p in specs if p.IsPrimPath()]
    # Only overs, apart from the review guides the layer defines under the skeleton.
    guides = SKEL + "/gazeGuides"
    assert prims and all(p.specifier == Sdf.SpecifierOver for p in prims if not str(p.path).startswith(guides))
    assert {str(p.path) for p in prims if not str(p.path).startswith(guides)} == {"/root", "/root/Body", SKEL, ANIM}
    assert {str(p.path) for p in prims if str(p.path).startswith(guides)} == {
        guides, guides + "/leftEyeSight", guides + "/rightEyeSight"}


def test_composed_result_passes_the_validators_the_input_passes(run):
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())

    def failing(path):
        return {e.GetValidator().GetMetadata().name for e in ctx.Validate(Usd.Stage.Open(str(path))) if e.GetValidator()}

    assert failing(run["dir"] / "preview.usda") <= failing(run["src"])


def test_same_inputs_give_byte_identical_layers(run, tmp_path):
    api.apply(run["src"], SHIFTS, tmp_path / "again.usdc", look=MODEL)
    assert (tmp_path / "again.usdc").read_bytes() == (run["dir"] / "gaze.usdc").read_bytes()
