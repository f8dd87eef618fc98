"""A keyed animation, its keys several frames apart (a layout or blocking pass, not a baked capture).

UsdSkel interpolates between the keys; a saccade lasts a frame or two, so a gaze written only at the
keys would be smeared over each gap. The pass writes every frame between the first and the last key
(and the keys themselves, exactly), as it would on the keys baked by USD at those frames; by UsdSkel
FK the shift has its own shape between the keys.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from pxr import Sdf, Usd

from usdgaze import api

from . import measure

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc"
SKEL, ANIM = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_02"
KEY_EVERY = 20  # time codes: four frames at the stage's 24 frames/s (120 time codes/s)
SHIFTS = ["1.3s:40:0", "2.9s:-30:10"]


def keyed(path: Path) -> tuple[Path, list[float]]:
    """CMU 131_02 cut to 4.2 s, with only every KEY_EVERY-th time sample kept (the last one too)."""
    shutil.copy(CMU, path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    kept = {}
    with Sdf.ChangeBlock():
        for name in ("rotations", "translations", "scales"):
            attr = Sdf.Path(f"{ANIM}.{name}")
            samples = list(layer.ListTimeSamplesForPath(attr))
            kept[name] = [t for t in samples if t <= 505 and (int(t) - 1) % KEY_EVERY == 0]
            for t in samples:
                if t not in kept[name]:
                    layer.EraseTimeSample(attr, t)
    layer.Save()
    assert len(kept["rotations"]) == 26
    return path, kept["rotations"]


def _sight(base, new):
    return measure.gaze_change(base, new, measure.character_forward_skel(base, "LeftHip", "RightHip"))[0]


def test_a_keyed_animation_gets_the_gaze_on_every_frame_between_its_keys(tmp_path):
    src, keys = keyed(tmp_path / "keyed.usdc")
    before = measure.sha256(src)
    api.apply(src, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda")
    assert measure.sha256(src) == before

    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "gaze.usdc"))
    written = np.array(layer.ListTimeSamplesForPath(Sdf.Path(f"{ANIM}.rotations")))
    frame = 120.00479955795427 / 24.0
    assert set(keys) <= set(written.tolist())  # every key, exactly
    assert written[0] == keys[0] and written[-1] == keys[-1]
    gaps = np.diff(written)
    assert gaps.max() <= 1.5 * frame and gaps.min() >= 0.5 * frame  # a frame next to a key gives way to it
    assert len(written) > 3 * len(keys)

    # What the pass on the keys writes is what it writes on those keys baked by USD at every written
    # frame (UsdSkel's own interpolation between them): bit for bit.
    baked = tmp_path / "baked.usdc"
    shutil.copy(src, baked)
    stage = Usd.Stage.Open(str(src))
    out = Sdf.Layer.FindOrOpen(str(baked))
    with Sdf.ChangeBlock():
        for name in ("rotations", "translations", "scales"):
            attr = stage.GetPrimAtPath(ANIM).GetAttribute(name)
            if attr.GetNumTimeSamples():
                for t in written:
                    out.SetTimeSample(attr.GetPath(), float(t), attr.Get(float(t)))
    out.Save()
    api.apply(baked, SHIFTS, tmp_path / "baked_gaze.usdc")
    mine, theirs = Sdf.Layer.FindOrOpen(str(tmp_path / "gaze.usdc")), Sdf.Layer.FindOrOpen(str(tmp_path / "baked_gaze.usdc"))
    for name in ("rotations", "translations"):
        path = Sdf.Path(f"{ANIM}.{name}")
        assert mine.ListTimeSamplesForPath(path) == theirs.ListTimeSamplesForPath(path)
        for t in written:
            assert np.asarray(mine.QueryTimeSample(path, t)).tobytes() == np.asarray(theirs.QueryTimeSample(path, t)).tobytes()

    # Between the keys the shift has its own shape, not a line from key to key: by UsdSkel FK the
    # line of sight at the frames between two keys strays from the line joining the keys' by > 5 deg.
    change = _sight(measure.posed(str(src), SKEL, times=written), measure.posed(str(tmp_path / "preview.usda"), SKEL))
    at_keys = np.isin(written, keys)
    joined = np.column_stack([np.interp(written, written[at_keys], change[at_keys, k]) for k in range(2)])
    assert np.abs(change - joined)[~at_keys].max() > 5.0
    # And once settled it holds the request (the second shift's 10 deg up included).
    late = written > 1 + 3.6 * 120.00479955795427
    assert np.abs(change[late] - [-30.0, 10.0]).max() <= 0.5
