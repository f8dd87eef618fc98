"""An override whose ``customLayerData["usdgaze"]`` record was hand-edited (or written by another tool)
into values of the wrong kind: ``validate`` and the usdview menu stopped on them with Python's own
error (``validate`` exit 1, ``'int' object is not iterable``); ``plot`` and ``preview`` refuse them in
one line (docs/bad-inputs.md, ``plot-layer-record-*`` and ``preview-layer-record-*``), and validate
says the same as a ``GazeLayerSchedule.BadRecord`` problem (exit 3)."""

from __future__ import annotations

import pytest
from pxr import Sdf, Usd

from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review import usdview

from . import synthetic as syn
from .usdview_standin import UsdviewApiStandIn


def _edited(tmp_path, **record):
    """A rig, apply's layer for it and its --preview root; the layer's record given ``record``'s values."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=48, time_codes_per_second=24, mesh=False)
    layer_path = tmp_path / "gaze.usda"
    api.apply(str(rig.path), ["0.5s:30:0"], layer_path, preview=tmp_path / "preview.usda")
    layer = Sdf.Layer.FindOrOpen(str(layer_path))
    data = dict(layer.customLayerData)
    data["usdgaze"] = {**dict(data["usdgaze"]), **record}
    layer.customLayerData = data
    layer.Save()
    return rig.path, layer_path


@pytest.mark.parametrize("record, said", [
    ({"shifts": 7}, "customLayerData usdgaze.shifts is not a list of strings"),
    ({"directives": 5}, "customLayerData usdgaze.directives is not a dictionary of SkelRoot paths"),
    ({"bind": 7}, "customLayerData usdgaze.bind 7: expected ROLE=JOINT strings"),
    ({"fixation": "far"}, "customLayerData usdgaze.fixation is 'far', expected a finite number > 0"),
], ids=["shifts", "directives", "bind", "fixation"])
def test_validate_says_a_malformed_record_in_one_line(tmp_path, capsys, record, said):
    src, layer = _edited(tmp_path, **record)
    assert main(["validate", str(src), "--layer", str(layer), "--only-usdgaze"]) == 3
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert err == "" and len(lines) == 1, (out, err)
    assert f"gaze.usda: {said}" in lines[0] and lines[0].endswith("(usdgaze.review.validators:GazeLayerSchedule.BadRecord)")


def test_the_usdview_menu_goes_on_past_a_malformed_record(tmp_path):
    _edited(tmp_path, directives=5, bind=7)
    stage = Usd.Stage.Open(str(tmp_path / "preview.usda"))
    view = UsdviewApiStandIn(stage)
    text = usdview.summary(view)
    assert "record unreadable (gaze.usda: customLayerData usdgaze.directives is not a dictionary" in text
    assert "lines of sight shown for 1 character(s)" in usdview.show_lines_of_sight(view)
    assert "selected 8 gaze chain joint markers" in usdview.select_chain_joints(view)
