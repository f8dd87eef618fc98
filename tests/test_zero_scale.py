"""A character, or a joint of its gaze chain, scaled to nothing on some frames: how animators hide one.

Such a frame has no inverse for the matrices the passes invert: ``apply`` and ``attend`` failed with
``internal error: LinAlgError: Singular matrix`` (exit 1) on a SkelRoot whose ``xformOp:scale`` was 0
on frames 40-44, or whose hips, neck or head ``scales`` were (0, 0, 0) for 10 frames; a static zero
scale failed ``inspect`` too. Those frames are written as the input's samples (the base motion), the
gaze holds elsewhere, one warning names the prim and attribute; a zero scale on every frame is one
exit-2 line. Measured from the written files by UsdSkel FK (tests/measure.py), nothing from usdgaze.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)

from . import attend_support as att
from . import bad_common as bad
from . import measure
from . import synthetic as syn

RATE, FRAMES, LOOK_S, SHIFT_S = 24.0, 120, 0.5, 2.5
HIDDEN = range(40, 45)  # time codes (1.67 to 1.83 s): inside the look's hold


def _rig(tmp_path) -> syn.Rig:
    return syn.make_rig(tmp_path / "in.usda", frames=FRAMES, time_codes_per_second=RATE, mesh=False)


def _hide_root(rig: syn.Rig, frames) -> None:
    """Key the SkelRoot's scale to 0 on ``frames`` (1 elsewhere), or to 0 for good (``frames`` None)."""
    stage = Usd.Stage.Open(str(rig.path))
    op = UsdGeom.Xformable(stage.GetPrimAtPath(rig.skel_root)).AddScaleOp()
    if frames is None:
        op.Set(Gf.Vec3f(0.0))
    else:
        for t in rig.times:
            op.Set(Gf.Vec3f(0.0 if int(t) in frames else 1.0), Usd.TimeCode(float(t)))
    stage.GetRootLayer().Save()


def _hide_joint(rig: syn.Rig, key: str, frames) -> None:
    """Set the animation's scales of joint ``key`` to (0, 0, 0) on ``frames``."""
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    column = rig.anim_joints.index(rig.joint(key))
    path = Sdf.Path(rig.animation + ".scales")
    if not layer.ListTimeSamplesForPath(path):  # scales held by a default: sample them on every frame
        held = np.array(layer.GetAttributeAtPath(path).default, dtype=np.float32)
        for t in rig.times:
            layer.SetTimeSample(path, float(t), Vt.Vec3hArray.FromNumpy(held.astype(np.float16)))
    for t in frames:
        s = np.array(layer.QueryTimeSample(path, float(t)), dtype=np.float32)
        s[column] = 0.0
        layer.SetTimeSample(path, float(t), Vt.Vec3hArray.FromNumpy(s.astype(np.float16)))
    layer.Save()


def _samples(path, animation: str, t: float) -> dict[str, dict[str, bytes]]:
    """The composed animation's joints and each array's bytes at time code ``t``, per joint token."""
    stage = Usd.Stage.Open(str(path))  # held: a prim outlives no stage
    anim = UsdSkel.Animation(stage.GetPrimAtPath(animation))
    joints = [str(j) for j in anim.GetJointsAttr().Get()]
    out = {}
    for name, attr in (("rotations", anim.GetRotationsAttr()), ("translations", anim.GetTranslationsAttr()),
                       ("scales", anim.GetScalesAttr())):
        values = np.array(attr.Get(Usd.TimeCode(t)))
        out[name] = {j: values[i].tobytes() for i, j in enumerate(joints)}
    return out


def _target(base: measure.Posed, rig: syn.Rig, fwd: np.ndarray) -> np.ndarray:
    up = np.array([0.0, 1.0, 0.0])
    look = int(LOOK_S * RATE)
    return base.position(rig.leaf["head"])[look] + 5.0 * (np.cos(0.5) * fwd + np.sin(0.5) * np.cross(up, fwd))


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")  # the hidden frames measure as 0 / 0
@pytest.mark.parametrize("hide", ["root", "pelvis", "neck", "head"])
def test_hidden_frames_keep_the_base_motion_and_the_gaze_holds_elsewhere(tmp_path, hide):
    rig = _rig(tmp_path)
    base = measure.posed(str(rig.path), rig.skeleton)  # before hiding: the eyes' axes and the target from it
    fwd = measure.character_forward_skel(base, rig.leaf["thigh_l"], rig.leaf["thigh_r"])
    target = _target(base, rig, fwd)
    if hide == "root":
        _hide_root(rig, HIDDEN)
        said = f"{rig.skel_root}.xformOp:scale"
    else:
        _hide_joint(rig, hide, HIDDEN)
        said = f"{rig.animation}.scales: joint '{rig.leaf[hide]}'"
    preview = tmp_path / "preview.usda"
    argv = ["apply", str(rig.path), "--shift", f"{SHIFT_S}s:40:10", "--out", str(tmp_path / "gaze.usdc"),
            "--preview", str(preview), "--look-at", ",".join(f"{v:.6f}" for v in target) + f"@{LOOK_S}s"]
    code, _, err = bad.run_inprocess(argv, tmp_path)
    assert code == 0, err
    warned = [line for line in err.splitlines() if said in line]
    assert len(warned) == 1 and "40 to 44" in warned[0], err

    for t in HIDDEN:  # the input's samples, to the bit, for every joint the input animates
        before, after = _samples(rig.path, rig.animation, t), _samples(preview, rig.animation, t)
        for name in before:
            assert all(after[name][j] == v for j, v in before[name].items()), (t, name)

    new = measure.posed(str(preview), rig.skeleton)
    seconds = (new.times - rig.start_time) / RATE
    seen = ~np.isin(new.times.astype(int), list(HIDDEN))
    looking = seen & (seconds >= LOOK_S + 0.8) & (seconds < SHIFT_S)
    assert looking[int(HIDDEN[-1]) + 1:].any()  # frames after the hidden ones are measured
    for eye in rig.eye_leaves:
        miss = measure.eye_miss_deg(new, eye, fwd, target)[looking]
        assert miss.max() < 0.5, (eye, miss.max())
    change, _, _ = measure.gaze_change(measure.posed(str(rig.path), rig.skeleton), new, fwd, rig.leaf["head"],
                                       rig.eye_leaves)
    held = np.abs(change[seconds >= SHIFT_S + 1.2] - [40.0, 10.0]).max()
    assert held < 0.5, held


def test_attend_keeps_the_hidden_frames_as_the_input(tmp_path):
    rig = _rig(tmp_path)
    _hide_root(rig, HIDDEN)
    scene = att.over(tmp_path / "scene.usda", rig.path)
    head = measure.posed(str(rig.path), rig.skeleton, times=[0.0]).position(rig.leaf["head"])[0]
    att.still_ball(scene, "/World/Ball", tuple(head + [1.0, 0.0, 2.0]), 0.1)
    scene.Save()
    out = tmp_path / "attend.usda"
    code, _, err = bad.run_inprocess(["attend", str(tmp_path / "scene.usda"), "--out", str(out)], tmp_path)
    assert code == 0, err
    composed = att.compose(tmp_path, tmp_path / "scene.usda", out)
    for t in HIDDEN:
        before, after = _samples(rig.path, rig.animation, t), _samples(composed, rig.animation, t)
        assert all(after["rotations"][j] == v for j, v in before["rotations"].items()), t
    moved = [t for t in (30, 60) if _samples(composed, rig.animation, t)["rotations"]
             != _samples(rig.path, rig.animation, t)["rotations"]]
    assert moved, "attend wrote no gaze outside the hidden frames"


@pytest.mark.parametrize("hide", ["root", "neck"])
def test_a_zero_scale_on_every_frame_is_one_line(tmp_path, hide):
    rig = _rig(tmp_path)
    if hide == "root":
        _hide_root(rig, None)
        said = f"{rig.skel_root}.xformOp:scale"
    else:
        _hide_joint(rig, hide, [int(t) for t in rig.times])
        said = f"{rig.animation}.scales: joint '{rig.leaf[hide]}'"
    before = bad.snapshot(tmp_path)
    code, out, err = bad.run_inprocess(bad.apply_argv(tmp_path, rig.path), tmp_path)
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("Warning")]
    assert code == 2 and len(lines) == 1 and said in lines[0] and "every" in lines[0], (code, err)
    assert bad.snapshot(tmp_path) == before  # nothing written
    if hide == "root":  # inspect says it for the skeleton, and exits 2 as apply does
        code, out, err = bad.run_inprocess(["inspect", str(rig.path)], tmp_path)
        assert code == 2 and f"cannot bind: {rig.path}:{said}" in out and "cannot bind" in err, (code, out, err)


def test_hidden_from_the_first_frame_applies_and_previews(tmp_path):
    """The first frame is what the stage's up and the preview's camera were read from."""
    rig = _rig(tmp_path)
    _hide_root(rig, range(0, 5))
    out = tmp_path / "gaze.usdc"
    code, _, err = bad.run_inprocess(["apply", str(rig.path), "--shift", "1s:30:10", "--out", str(out)], tmp_path)
    assert code == 0 and "at time codes 0 to 4;" in err, err
    composed = att.compose(tmp_path, rig.path, out)
    for t in range(0, 5):
        before = _samples(rig.path, rig.animation, t)["rotations"]
        assert _samples(composed, rig.animation, t)["rotations"] == before, t
    code, _, err = bad.run_inprocess(["preview", str(rig.path), "--layer", str(out), "--out",
                                      str(tmp_path / "p.png"), "--size", "64"], tmp_path)
    assert code == 0 and (tmp_path / "p.png").is_file(), err


@pytest.mark.parametrize("scale", [0.0, 1e-5])
def test_a_bind_transform_is_singular_by_its_shape_not_its_size(tmp_path, scale):
    """A bind transform with a zero scale has no inverse: one exit-2 line naming the joint. One scaled
    uniformly by 1e-5 (its determinant 1e-15, under the absolute 1e-12 the check once used) is a
    rotation times a scale, invertible: it is not refused as singular."""
    rig = _rig(tmp_path)
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    path = Sdf.Path(rig.skeleton + ".bindTransforms")
    mats = np.array(layer.GetAttributeAtPath(path).default)
    head = rig.joints.index(rig.joint("head"))
    mats[head, :3, :3] *= scale
    layer.GetAttributeAtPath(path).default = Vt.Matrix4dArray.FromNumpy(mats)
    layer.Save()
    code, out, err = bad.run_inprocess(bad.apply_argv(tmp_path, rig.path), tmp_path)
    if scale == 0.0:
        lines = [line for line in err.splitlines() if line.strip() and not line.startswith("Warning")]
        assert code == 2 and len(lines) == 1 and "bindTransforms" in lines[0] and rig.leaf["head"] in lines[0] \
            and "singular" in lines[0], (code, err)
    else:
        assert code == 0 and "singular" not in err, (code, err)
