"""The reader takes time samples from the one layer that holds them, and gives what USD's own value
resolution gives for every composition it meets (offsets, stronger layers, defaults)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel

from usdgaze.usd import skelio
from usdgaze.usd.stage import open_stage

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
ANIM = "/root/Body/BodySkel/scaled_131_01"


def _usd_reference(path: Path, times: np.ndarray) -> dict[str, np.ndarray]:
    """Rotations and translations by per-frame ``Usd.Attribute.Get`` (USD's value resolution)."""
    stage = Usd.Stage.Open(str(path))
    anim = UsdSkel.Animation(stage.GetPrimAtPath(ANIM))
    return {name: np.stack([np.asarray(attr.Get(float(t)), dtype=np.float32) for t in times])
            for name, attr in (("rotations", anim.GetRotationsAttr()), ("translations", anim.GetTranslationsAttr()))}


def _read(path: Path):
    stage = open_stage(str(path))
    root = stage.GetPrimAtPath("/root/Body")
    return skelio.read_clip(stage, stage.GetPrimAtPath("/root/Body/BodySkel"), root, str(path))


def _union_times(path: Path) -> np.ndarray:
    stage = Usd.Stage.Open(str(path))
    anim = UsdSkel.Animation(stage.GetPrimAtPath(ANIM))
    attrs = (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr())
    return np.array(sorted({t for a in attrs for t in a.GetTimeSamples()}))


STRONGER = """#usda 1.0
over "root"
{
    over "Body"
    {
        over "BodySkel"
        {
            over "scaled_131_01"
            {
                quatf[] rotations.timeSamples = { %s }
            }
        }
    }
}
"""


@pytest.mark.parametrize("case", ["plain", "offset", "stronger samples", "stronger default"])
def test_reader_matches_usd_value_resolution(tmp_path, case):
    shutil.copy(CMU, tmp_path / "walk.usdc")
    n = len(_read(tmp_path / "walk.usdc").anim_joints)
    quats = "(1, 0, 0, 0), " * n
    layers = {"plain": ["@./walk.usdc@"],
              "offset": ["@./walk.usdc@ (offset = 24; scale = 0.5)"],
              "stronger samples": ["@./over.usda@", "@./walk.usdc@"],
              "stronger default": ["@./over.usda@", "@./walk.usdc@"]}[case]
    # Same time codes per second as the walk, so the offset is the only time mapping (a layer without
    # its own would be read at 24 and its samples scaled by five).
    tcps = Usd.Stage.Open(str(CMU)).GetTimeCodesPerSecond()
    over = STRONGER.replace("#usda 1.0\n", f"#usda 1.0\n(\n    timeCodesPerSecond = {tcps!r}\n)\n", 1)
    if case == "stronger samples":  # three samples at times the base has and has not: USD holds/slerps
        (tmp_path / "over.usda").write_text(over % f"10: [{quats}], 100.5: [{quats}], 400: [{quats}]")
    if case == "stronger default":
        (tmp_path / "over.usda").write_text(over.replace("rotations.timeSamples = { %s }", f"rotations = [{quats}]"))
    (tmp_path / "shot.usda").write_text(
        f"#usda 1.0\n(\n    timeCodesPerSecond = {tcps!r}\n    metersPerUnit = 1\n    upAxis = \"Y\"\n"
        f"    subLayers = [{', '.join(layers)}]\n)\n")

    clip = _read(tmp_path / "shot.usda")
    expected_times = _union_times(tmp_path / "shot.usda")
    np.testing.assert_array_equal(clip.times, expected_times)
    reference = _usd_reference(tmp_path / "shot.usda", expected_times)
    np.testing.assert_array_equal(clip.rotations, reference["rotations"])
    np.testing.assert_array_equal(clip.translations, reference["translations"])
    if case == "offset":
        base = _read(tmp_path / "walk.usdc")
        np.testing.assert_allclose(clip.times, 24 + 0.5 * base.times)
        np.testing.assert_array_equal(clip.rotations, base.rotations)


def test_reader_reads_each_sample_once_from_its_layer(tmp_path, monkeypatch):
    """No per-frame Usd.Attribute.Get when one layer holds the samples."""
    calls = []
    original = Usd.Attribute.Get

    def counting(self, *args):
        if args:
            calls.append(str(self.GetPath()))
        return original(self, *args)

    monkeypatch.setattr(Usd.Attribute, "Get", counting)
    clip = _read(CMU)
    assert len(clip.times) == 994 and not [c for c in calls if c.startswith(ANIM)]


def _thin(path: Path, keep) -> None:
    """Erase the animation's samples at the times ``keep(name, t)`` rejects."""
    layer = Sdf.Layer.FindOrOpen(str(path))
    with Sdf.ChangeBlock():
        for name in ("rotations", "translations", "scales"):
            attr = Sdf.Path(f"{ANIM}.{name}")
            for t in list(layer.ListTimeSamplesForPath(attr)):
                if not keep(name, t):
                    layer.EraseTimeSample(attr, t)
    layer.Save()


THINNED = {
    # keys every 5 frames: the reader adds the frames between them, which USD interpolates
    "keys every 5 frames": lambda name, t: (int(round(t)) - 1) % 5 == 0,
    # translations keyed every other frame, rotations every frame: the union is every frame
    "translations on fewer frames": lambda name, t: name != "translations" or (int(round(t)) - 1) % 2 == 0,
    # rotations end early: USD holds the last one over the rest of the take
    "rotations end early": lambda name, t: name != "rotations" or t <= 400,
}


@pytest.mark.parametrize("case", sorted(THINNED))
def test_samples_the_layer_lacks_are_what_usd_gives_and_only_those_are_interpolated(tmp_path, monkeypatch, case):
    """Each authored sample comes from its layer; USD is asked only for the times strictly between two
    of the attribute's samples (its interpolation), never for a time at or beyond its samples."""
    path = tmp_path / "walk.usdc"
    shutil.copy(CMU, path)
    _thin(path, THINNED[case])
    rotations_at = set(Sdf.Layer.FindOrOpen(str(path)).ListTimeSamplesForPath(Sdf.Path(f"{ANIM}.rotations")))
    asked: list[tuple[str, float]] = []
    original = Usd.Attribute.Get

    def counting(self, *args):
        if args and str(self.GetPath()).startswith(ANIM):
            asked.append((self.GetName(), float(args[0])))
        return original(self, *args)

    monkeypatch.setattr(Usd.Attribute, "Get", counting)
    clip = _read(path)
    monkeypatch.setattr(Usd.Attribute, "Get", original)

    reference = _usd_reference(path, clip.times)
    np.testing.assert_array_equal(clip.rotations, reference["rotations"])
    np.testing.assert_array_equal(clip.translations, reference["translations"])
    first, last = min(rotations_at), max(rotations_at)
    asked_rotations = {t for name, t in asked if name == "rotations"}
    assert not asked_rotations & rotations_at  # an authored sample is never resolved through USD
    assert all(first < t < last for t in asked_rotations)
    if case == "rotations end early":
        assert not asked_rotations and clip.times.max() > last  # held past its last sample without USD


def test_one_sample_held_over_the_range_is_read_once(tmp_path, monkeypatch):
    """A pose held by one time sample is read from the layer once for the whole range."""
    path = tmp_path / "walk.usdc"
    shutil.copy(CMU, path)
    middle = Sdf.Layer.FindOrOpen(str(path)).ListTimeSamplesForPath(Sdf.Path(f"{ANIM}.rotations"))[300]
    _thin(path, lambda name, t: t == middle)
    assert Usd.Stage.Open(str(path)).GetPrimAtPath(ANIM).GetAttribute("rotations").GetNumTimeSamples() == 1
    asked = []
    original = Usd.Attribute.Get
    monkeypatch.setattr(Usd.Attribute, "Get",
                        lambda self, *args: (asked.append(args) if args and str(self.GetPath()).startswith(ANIM) else None)
                        or original(self, *args))
    clip = _read(path)
    monkeypatch.setattr(Usd.Attribute, "Get", original)
    assert clip.held_pose and len(clip.times) > 150 and not asked
    reference = _usd_reference(path, clip.times[[0, len(clip.times) // 2, -1]])
    for name in ("rotations", "translations"):
        np.testing.assert_array_equal(getattr(clip, name)[[0, len(clip.times) // 2, -1]], reference[name])
        assert np.all(getattr(clip, name) == getattr(clip, name)[0])
