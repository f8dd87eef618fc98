"""``validate`` judges a layer's span by the frames UsdSkel animates, not by the rotations alone.

An audit found: an animation whose rotations hold one time sample while its translations move (an
export that keys only what changes), or that holds one pose on a single sample (which ``apply`` takes
over the stage's range), got a layer ``plot`` and ``preview`` drew, yet ``validate`` on the very
preview ``apply`` wrote called it another take (``OtherTake``, exit 3): it compared the layer's span
with the first and last time sample of ``rotations`` only, where apply samples every array's keys.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel

from usdgaze.console.main import main

from . import synthetic as syn


def _keep_first_sample(layer: Sdf.Layer, path: str) -> None:
    for t in layer.ListTimeSamplesForPath(path)[1:]:
        layer.EraseTimeSample(path, t)


def _animated_span(path) -> tuple[float, float]:
    """First and last time at which UsdSkel's own animation query samples the joints, or the stage's
    playback range where it holds one pose (one sample or none: the shot shows it over that range)."""
    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/Character")), Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/Character/Skel")))
    times = query.GetAnimQuery().GetJointTransformTimeSamples()
    return (times[0], times[-1]) if len(times) > 1 else (stage.GetStartTimeCode(), stage.GetEndTimeCode())


@pytest.mark.parametrize("held", [("rotations",), ("rotations", "translations", "scales")])
def test_a_layer_over_held_arrays_validates_clean_and_another_take_still_does_not(tmp_path, capsys, held):
    """One array held, the others moving: the input's span is theirs. Every array held (one pose): the
    input has no span of its own, apply took the stage's range."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False, walk_speed=0.5)
    syn.edit(rig.path, lambda layer: [_keep_first_sample(layer, f"{rig.animation}.{name}") for name in held])
    layer, preview = tmp_path / "g.usda", tmp_path / "p.usda"
    assert main(["apply", str(rig.path), "--shift", "0.3s:30:0", "--out", str(layer), "--preview", str(preview)]) == 0
    written = Sdf.Layer.FindOrOpen(str(layer)).ListTimeSamplesForPath(f"{rig.animation}.rotations")
    assert (written[0], written[-1]) == _animated_span(rig.path) == (0.0, 59.0)
    capsys.readouterr()
    assert main(["validate", str(preview), "--only-usdgaze"]) == 0, capsys.readouterr().out
    assert main(["validate", str(rig.path), "--layer", str(layer), "--only-usdgaze"]) == 0, capsys.readouterr().out

    if len(held) == 3:
        return  # one pose has no span to tell one take from another
    # A take cut to its first 30 frames (its range too): the same layer is another take's.
    short = tmp_path / "short.usda"
    syn.make_rig(short, frames=30, mesh=False, walk_speed=0.5)
    syn.edit(short, lambda layer: [_keep_first_sample(layer, f"{rig.animation}.{name}") for name in held])
    assert _animated_span(short) == (0.0, 29.0)
    capsys.readouterr()
    assert main(["validate", str(short), "--layer", str(layer), "--only-usdgaze"]) == 3
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and "OtherTake" in out[0] and "0..59, the input below it 0..29" in out[0], out
