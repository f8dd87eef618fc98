"""Time metadata of the input stage as `usdgaze apply` carries it into its layers.

Measured on the written layers and the composed preview with USD itself (Sdf metadata, UsdSkel FK
through tests/measure.py), not with usdgaze's math.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd

from usdgaze import api

from . import measure
from . import synthetic as syn
from .measure import sight_line

START = 1001.0  # a studio's first frame, with the stage's range left unauthored
TCPS = 30.0


@pytest.mark.parametrize("authored", ["neither", "start only", "end only"])
def test_an_unauthored_time_range_is_not_invented_in_the_layers(tmp_path, authored):
    # An input that authors no startTimeCode/endTimeCode (or one of them) got USD's fallback 0 written
    # for the missing one: the preview played [0, 0], or [1001, 0] with only a start, a range usdgaze
    # itself refuses ("startTimeCode 1001 is after endTimeCode 0") when the preview is read again.
    rig = syn.make_rig(tmp_path / "in.usda", frames=90, mesh=False, time_codes_per_second=TCPS, start_time=START)

    def clear(layer):
        if authored != "start only":
            layer.ClearStartTimeCode()
        if authored != "end only":
            layer.ClearEndTimeCode()

    syn.edit(rig.path, clear)
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    src.Reload(force=True)
    has = (src.HasStartTimeCode(), src.HasEndTimeCode())
    assert has == {"neither": (False, False), "start only": (True, False), "end only": (False, True)}[authored]
    before = measure.sha256(rig.path)

    shift_at = START + 15  # 0.5 s into the animation, in time codes (no stage start to count seconds from)
    api.apply(rig.path, [f"{shift_at:g}:40:0"], tmp_path / "gaze.usda", preview=tmp_path / "preview.usda")
    assert measure.sha256(rig.path) == before

    for name in ("gaze.usda", "preview.usda"):
        layer = Sdf.Layer.FindOrOpen(str(tmp_path / name))
        assert (layer.HasStartTimeCode(), layer.HasEndTimeCode()) == has, name
        if has[0]:
            assert layer.startTimeCode == src.startTimeCode
        if has[1]:
            assert layer.endTimeCode == src.endTimeCode
    preview = Usd.Stage.Open(str(tmp_path / "preview.usda"))
    assert not preview.HasAuthoredTimeCodeRange()

    # The gaze is there at the animation's own time codes, by UsdSkel FK on the composed preview.
    base = measure.posed(str(rig.path), rig.skeleton)
    new = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton)
    assert base.times[0] == START
    change, _, _ = measure.gaze_change(base, new, rig.forward, rig.leaf["head"], rig.eye_leaves, sight_line)
    assert np.abs(change[base.times < shift_at - 1]).max() < 0.5
    hold = base.times >= shift_at + TCPS  # a second after the shift: settled
    assert hold.sum() > 30
    assert np.abs(change[hold] - [40.0, 0.0]).max() <= 0.5

    # The preview is an input usdgaze reads again (a later glance on top).
    api.apply(tmp_path / "preview.usda", [f"{shift_at + 30:g}:-20:0"], tmp_path / "gaze2.usda")
