"""Pathological animation data: what a bad sample is called, and the clip's own ends.

* NaN or infinite rotations/translations are refused in one line that names the attribute, the time
  code and the joint (it said "rotations or translations hold NaN or infinite values", naming
  neither which attribute nor where in a clip of thousands of frames); a bad key of a blocked
  animation (keys 10 frames apart, every frame between them filled by USD's interpolation) is named
  at the key, not at the first interpolated frame it spoils; non-unit quaternions say where and how long.
* A directive at the clip's last second as the "outside the animation" message prints it (6 digits:
  89/30 s prints as 2.96667 s, just past the end) was refused by that same message.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Vt

from . import measure
from .bad_common import edited, rig, run_inprocess, snapshot


def _one_line_error(d, argv):
    before = snapshot(d)
    code, _, err = run_inprocess(argv, d)
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert snapshot(d) == before  # nothing written, the input unchanged
    return lines[0]


def _apply(d, src):
    return ["apply", str(src), "--shift", "0.5s:30:0", "--out", str(d / "gaze.usda")]


def _values(layer, path, t):
    return np.array(layer.QueryTimeSample(path, t), dtype=np.float32)


def test_nan_translation_names_the_attribute_time_and_joint(tmp_path):
    picked = {}

    def spoil(layer, r):
        path = Sdf.Path(r.animation + ".translations")
        t = float(r.times[37])
        v = _values(layer, path, t)
        j = len(r.anim_joints) // 3
        v[j, 1] = np.inf
        layer.SetTimeSample(path, t, Vt.Vec3fArray.FromNumpy(v))
        picked.update(t=t, joint=r.anim_joints[j], anim=r.animation)

    src = edited(tmp_path, spoil)
    line = _one_line_error(tmp_path, _apply(tmp_path, src))
    assert line == (f"usdgaze: error: {src}:{picked['anim']}.translations: NaN or infinite values at time code "
                    f"{picked['t']:g} (joint '{picked['joint']}')"), line


def test_nan_key_of_a_blocked_animation_is_named_at_the_key(tmp_path):
    picked = {}

    def block(layer, r):
        keys = [float(t) for t in r.times[::10]]
        for name in ("rotations", "translations", "scales"):
            path = Sdf.Path(f"{r.animation}.{name}")
            for t in r.times:
                if float(t) not in keys:
                    layer.EraseTimeSample(path, float(t))
        path = Sdf.Path(r.animation + ".rotations")
        v = _values(layer, path, keys[4])
        v[2] = np.nan
        layer.SetTimeSample(path, keys[4], Vt.QuatfArray.FromNumpy(v))
        picked.update(t=keys[4], joint=r.anim_joints[2], anim=r.animation)

    src = edited(tmp_path, block, time_codes_per_second=30.0)
    line = _one_line_error(tmp_path, _apply(tmp_path, src))
    assert line == (f"usdgaze: error: {src}:{picked['anim']}.rotations: NaN or infinite values at time code "
                    f"{picked['t']:g} (joint '{picked['joint']}')"), line


def test_non_unit_quaternion_says_where_and_how_long(tmp_path):
    picked = {}

    def double(layer, r):
        path = Sdf.Path(r.animation + ".rotations")
        t = float(r.times[12])
        v = _values(layer, path, t)
        v[5] *= 2.0
        layer.SetTimeSample(path, t, Vt.QuatfArray.FromNumpy(v))
        picked.update(t=t, joint=r.anim_joints[5], anim=r.animation)

    src = edited(tmp_path, double)
    line = _one_line_error(tmp_path, _apply(tmp_path, src))
    assert line == (f"usdgaze: error: {src}:{picked['anim']}.rotations: not unit quaternions at time code "
                    f"{picked['t']:g} (joint '{picked['joint']}') (length 2)"), line


def test_the_last_second_as_the_message_prints_it_is_inside(tmp_path):
    r = rig(tmp_path, frames=90, time_codes_per_second=30.0)
    last = (float(r.times[-1]) - float(r.times[0])) / 30.0
    printed = f"{last:g}"
    assert float(printed) > last  # 2.96667 > 89/30: the printed end lies just past the real one
    before = measure.sha256(r.path)
    code, out, err = run_inprocess(["apply", str(r.path), "--shift", f"{printed}s:30:0", "--out",
                                    str(tmp_path / "gaze.usda")], tmp_path)
    assert code == 0, err
    assert (tmp_path / "gaze.usda").exists()
    assert measure.sha256(r.path) == before
    # Still refused a frame past the end.
    code, _, err = run_inprocess(["apply", str(r.path), "--shift", f"{last + 1 / 30:.6f}s:30:0", "--out",
                                  str(tmp_path / "gaze2.usda")], tmp_path)
    assert code == 2 and "lies outside the animation" in err, err


def test_a_shift_the_animation_ends_before_it_settles_is_said(tmp_path):
    """A shift two frames before the end reaches a little of its request: that was said only as
    "hold error n/a" in the report, nothing on stderr; now one warning with what the last frame shows,
    which UsdSkel FK agrees with."""
    r = rig(tmp_path, frames=60, time_codes_per_second=30.0)
    preview = tmp_path / "preview.usda"
    code, _, err = run_inprocess(["apply", str(r.path), "--shift", f"{float(r.times[-3]):g}:30:-10", "--out",
                                  str(tmp_path / "gaze.usda"), "--preview", str(preview)], tmp_path)
    assert code == 0, err
    line = [w for w in err.splitlines() if "before it settles" in w]
    assert len(line) == 1, err
    yaw, pitch = line[0].split("reached about yaw ")[1].split(" on the last frame")[0].split(", pitch ")
    said = [float(yaw), float(pitch)]
    base, new = measure.posed(str(r.path), r.skeleton), measure.posed(str(preview), r.skeleton)
    change, _, _ = measure.gaze_change(base, new, r.forward, r.leaf["head"], r.eye_leaves, measure.sight_line)
    assert 1.0 < abs(change[-1, 0]) < 29.0  # part of the way
    assert np.abs(change[-1] - said).max() < 0.5, (change[-1], said)
