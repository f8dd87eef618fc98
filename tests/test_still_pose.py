"""A character that holds one pose: a SkelAnimation with default values and no time samples (or one
time sample, which USD holds at every time), and a Skeleton with no animation bound (UsdSkel shows
its rest pose).

UsdSkel shows that pose at every time, so ``apply`` adds the gaze over the frames of the stage's
playback range; for the unbound skeleton the layer defines and binds the animation. The still pose
is CMU 131_02's frame 500 (real capture), the rest pose Blender's export frame, measured by UsdSkel's
own forward kinematics against the input posed at the same frames.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel

from usdgaze import api

from . import measure

ROOT = Path(__file__).resolve().parents[1]
SKEL = "/root/Body/BodySkel"
ANIM = SKEL + "/scaled_131_02"
START, END, FPS = 0.0, 96.0, 24.0  # 4 s at 24 frames/s, one time code a frame
SHIFT = (12.0, 40.0, 0.0)  # at 0.5 s, 40 deg to the left


def still_stage(path: Path, frame: float = 500.0, held_as: str = "default") -> Path:
    """CMU 131_02 with its animation replaced by the pose at ``frame``, as defaults or as one time
    sample (at 5: USD holds it at every time), at the Sdf level."""
    shutil.copy(ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc", path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    with Sdf.ChangeBlock():
        for name in ("rotations", "translations", "scales"):
            attr = Sdf.Path(f"{ANIM}.{name}")
            samples = layer.ListTimeSamplesForPath(attr)
            if not samples:
                continue
            held = layer.QueryTimeSample(attr, min(samples, key=lambda t: abs(t - frame)))
            for t in samples:
                layer.EraseTimeSample(attr, t)
            if held_as == "default":
                layer.GetAttributeAtPath(attr).default = held
            else:
                layer.SetTimeSample(attr, 5.0, held)
        layer.timeCodesPerSecond = layer.framesPerSecond = FPS
        layer.startTimeCode, layer.endTimeCode = START, END
    layer.Save()
    return path


def unbound_stage(path: Path) -> Path:
    """CMU 131_02 with its skel:animationSource emptied (an explicit empty target list), so UsdSkel
    poses the skeleton at restTransforms (Blender's export frame, a standing pose)."""
    shutil.copy(ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc", path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    with Sdf.ChangeBlock():
        layer.GetRelationshipAtPath(SKEL + ".skel:animationSource").targetPathList.explicitItems = []
        layer.timeCodesPerSecond = layer.framesPerSecond = FPS
        layer.startTimeCode, layer.endTimeCode = START, END
    layer.Save()
    return path


def _shot(d: Path, src: Path, out: str) -> dict:
    """Apply ``SHIFT`` to ``src``; the input and the preview posed by UsdSkel at the range's frames."""
    before = measure.sha256(src)
    t, yaw, pitch = SHIFT
    report = api.apply(src, [f"{t:g}:{yaw:g}:{pitch:g}"], d / out, preview=d / "preview.usda")
    frames = np.arange(START, END + 1.0)
    return dict(dir=d, src=src, before=before, report=report, frames=frames,
                base=measure.posed(str(src), SKEL, times=frames), new=measure.posed(str(d / "preview.usda"), SKEL))


def _sight_change(shot: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Achieved line-of-sight change (yaw, pitch) per frame against the input head's line of sight,
    the frames before the shift and after it settled, and the input head's direction."""
    base, new = shot["base"], shot["new"]
    fwd = measure.character_forward_skel(base, "LeftHip", "RightHip")
    change, head_dir, _ = measure.gaze_change(base, new, fwd)
    timing = shot["report"].characters[0].result.shift_timing[0]
    settled = START + (timing["time_s"] + timing["duration"]) * FPS
    return change, shot["frames"] < SHIFT[0], shot["frames"] > settled + 1, head_dir


@pytest.fixture(scope="module", params=["default", "one sample"])
def run(request, tmp_path_factory):
    d = tmp_path_factory.mktemp("still")
    return _shot(d, still_stage(d / "still.usdc", held_as=request.param), "gaze.usdc")


@pytest.fixture(scope="module")
def unbound(tmp_path_factory):
    d = tmp_path_factory.mktemp("unbound")
    return _shot(d, unbound_stage(d / "rest.usdc"), "gaze.usda")


# -- an animation that holds one pose ------------------------------------------------------------

def test_gaze_is_sampled_at_every_frame_of_the_range(run):
    layer = Sdf.Layer.FindOrOpen(str(run["dir"] / "gaze.usdc"))
    times = layer.ListTimeSamplesForPath(Sdf.Path(f"{ANIM}.rotations"))
    assert np.array_equal(times, run["frames"])
    assert np.array_equal(run["new"].times, run["frames"])


def test_line_of_sight_turns_as_asked_and_holds(run):
    change, before, hold, head_dir = _sight_change(run)
    assert hold.sum() > 40
    assert np.abs(change[before]).max() <= 0.5
    assert np.abs(change[hold] - SHIFT[1:]).max() <= 0.5
    # The head turned too (not the eyes alone): a 40 deg shift recruits the neck.
    base, new = run["base"], run["new"]
    fwd = measure.character_forward_skel(base, "LeftHip", "RightHip")
    head_now = new.axis("Head", measure.local_forward(base, "Head", fwd))
    assert measure.angle_between(head_now[hold], head_dir[hold]).min() > 5.0


def test_joints_off_the_chain_keep_the_held_pose_bit_for_bit(run):
    stage = Usd.Stage.Open(str(run["src"]))
    anim = stage.GetPrimAtPath(ANIM)
    joints = [str(j) for j in anim.GetAttribute("joints").Get()]
    held = np.asarray(anim.GetAttribute("rotations").Get(START))
    layer = Sdf.Layer.FindOrOpen(str(run["dir"] / "gaze.usdc"))
    path = Sdf.Path(f"{ANIM}.rotations")
    written = np.stack([np.asarray(layer.QueryTimeSample(path, t)) for t in run["frames"]])
    driven = {"Hips", "LHipJoint", "RHipJoint", "lowerback", "Chest", "Chest2", "lowerneck", "Neck", "Head"}
    off_chain = [i for i, j in enumerate(joints) if j.rsplit("/", 1)[-1] not in driven]
    assert len(off_chain) == len(joints) - len(driven) == 22
    assert written[:, off_chain].tobytes() == np.broadcast_to(held[off_chain], written[:, off_chain].shape).tobytes()


def test_input_untouched_and_muting_gives_the_still_pose_back(run):
    assert measure.sha256(run["src"]) == run["before"]
    stage = Usd.Stage.Open(str(run["dir"] / "preview.usda"))
    stage.MuteLayer(str(run["dir"] / "gaze.usdc"))
    rotations = stage.GetPrimAtPath(ANIM).GetAttribute("rotations")
    input_stage = Usd.Stage.Open(str(run["src"]))
    source = input_stage.GetPrimAtPath(ANIM).GetAttribute("rotations")
    assert rotations.GetTimeSamples() == source.GetTimeSamples()
    assert np.asarray(rotations.Get(30.0)).tobytes() == np.asarray(source.Get(30.0)).tobytes()


# -- a Skeleton with no animation bound: UsdSkel shows its rest pose -----------------------------

def test_unbound_skeleton_gets_a_new_bound_animation_that_turns_the_gaze(unbound):
    base, new = unbound["base"], unbound["new"]
    assert np.array_equal(new.times, unbound["frames"])
    change, before, hold, _ = _sight_change(unbound)
    assert np.abs(change[before]).max() <= 0.5
    assert np.abs(change[hold] - SHIFT[1:]).max() <= 0.5
    # The legs keep their rest pose in the world (the new animation holds it in float32).
    off = [i for i, j in enumerate(base.joints) if j.rsplit("/", 1)[-1] in ("LeftKnee", "RightAnkle", "LeftToe")]
    assert np.abs(new.world[:, off] - base.world[:, off]).max() < 1e-4


def test_unbound_input_untouched_and_muting_leaves_it_unbound(unbound):
    assert measure.sha256(unbound["src"]) == unbound["before"]
    stage = Usd.Stage.Open(str(unbound["dir"] / "preview.usda"))
    skel = stage.GetPrimAtPath(SKEL)
    assert UsdSkel.BindingAPI(skel).GetAnimationSourceRel().GetTargets() == [Sdf.Path(SKEL + "/gazeAnimation")]
    stage.MuteLayer(str(unbound["dir"] / "gaze.usda"))
    assert UsdSkel.BindingAPI(skel).GetAnimationSourceRel().GetTargets() == []
    assert not stage.GetPrimAtPath(SKEL + "/gazeAnimation")


def test_inspect_says_which_poses_are_held_and_what_the_layer_would_define(tmp_path):
    from usdgaze.review.inspection import inspect_stage

    for make, bound in ((still_stage, True), (unbound_stage, False)):
        src = make(tmp_path / f"{make.__name__}.usdc")
        (skel,) = inspect_stage(str(src))["skel_roots"][0]["skeletons"]
        assert skel["held_pose"] and skel["animation_bound"] == bound
        assert (skel["frames"], skel["first"], skel["last"]) == (97, START, END)
        assert skel["animation"] == (ANIM if bound else SKEL + "/gazeAnimation")
    (skel,) = inspect_stage(str(ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc"))["skel_roots"][0]["skeletons"]
    assert not skel["held_pose"] and skel["animation_bound"]


def test_one_sample_without_a_range_says_to_author_the_range(tmp_path, capsys):
    """One time sample and no playback range: the request 'lies outside the animation (time codes 5 to
    5)', which said nothing of why; the line now says to author the shot's range."""
    from usdgaze.console.main import main

    src = still_stage(tmp_path / "still.usdc", held_as="one sample")
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.ClearStartTimeCode()
    layer.ClearEndTimeCode()
    layer.Save()
    out = tmp_path / "gaze.usda"
    assert main(["apply", str(src), "--shift", "0.5s:40:0", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "lies outside the animation" in err[0] and "author startTimeCode/endTimeCode" in err[0], err
    assert not out.exists()
