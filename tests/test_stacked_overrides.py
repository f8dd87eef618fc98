"""A pass run on a stage that already composes a usdgaze override starts from the motion with that
override's gaze in it: the new offsets add to the old ones. Every command says so (a warning naming
the composed layer, exit 0); a stage composing none, or only a gaze map usdgaze wrote, gets no such
warning. Checked on the layers the commands actually wrote, and the stacking itself measured by
UsdSkel FK: the rerun's head turns again on top of the first pass's turn."""

from __future__ import annotations

import json

import numpy as np
from pxr import Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import measure
from . import synthetic as syn
from .attend_support import compose
from .test_attend_binding import _scene


def _warnings(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("usdgaze: warning:")]


def _yaw(stage_path, rig: syn.Rig, leaf: str, frame: int) -> float:
    """The joint's forward (its bind-pose axis along the character's forward) as an azimuth about the
    stage's up (Y) at ``frame``, degrees."""
    p = measure.posed(str(stage_path), rig.skeleton)
    d = p.axis(rig.leaf[leaf], measure.local_forward(p, rig.leaf[leaf], rig.forward))[frame]
    return float(np.degrees(np.arctan2(d[0], d[2])))


def test_a_pass_on_a_stage_that_composes_an_override_says_it_adds_to_it(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=48, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    first = tmp_path / "first.usda"
    assert main(["apply", str(rig.path), "--shift", "0.2s:30:0", "--out", str(first)]) == 0
    assert _warnings(capsys) == []
    shot = compose(tmp_path, rig.path, first, "shot.usda")  # the shot with the first pass in it
    second = tmp_path / "second.usda"
    assert main(["apply", str(shot), "--shift", "0.2s:30:0", "--out", str(second)]) == 0
    said = _warnings(capsys)
    assert len(said) == 1 and str(first.resolve()) in said[0] and "adds to the gaze" in said[0]
    # The warning is true: the second pass turns the head again from where the first left it (the
    # eyes' request is against the line of sight the base's head gives them: 29 and 34 deg here).
    base, once, twice = (_yaw(s, rig, "head", 40) for s in (rig.path, shot, compose(tmp_path, shot, second, "both.usda")))
    assert once - base > 2.0 and twice - base > 1.7 * (once - base), (once - base, twice - base)  # 5.1, 10.3

    scene, _ = _scene(tmp_path, rig)
    layer = Sdf.Layer.FindOrOpen(str(scene))
    layer.subLayerPaths.insert(0, str(first))
    layer.Save()
    assert main(["attend", str(scene), "--out", str(tmp_path / "look.usda"), "--window", "0.3", "--json"]) == 0
    out = capsys.readouterr()
    assert str(first.resolve()) in " ".join(json.loads(out.out)["warnings"])


def test_no_warning_for_a_stage_without_overrides_or_with_a_gaze_map(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=24, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    gaze_map = tmp_path / "map.usda"
    assert main(["dump-map", str(gaze_map)]) == 0
    capsys.readouterr()
    shot = compose(tmp_path, rig.path, gaze_map, "shot.usda")
    assert "usdgaze" in Sdf.Layer.FindOrOpen(str(gaze_map)).customLayerData  # usdgaze's, but no override
    assert main(["apply", str(shot), "--shift", "0.2s:30:0", "--out", str(tmp_path / "out.usda")]) == 0
    assert not [w for w in _warnings(capsys) if "adds to the gaze" in w]


def test_the_physics_pass_says_it_too(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=5, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    first = tmp_path / "first.usda"
    assert main(["apply", str(rig.path), "--shift", "0:20:0", "--out", str(first)]) == 0
    shot = compose(tmp_path, rig.path, first, "shot.usda")
    capsys.readouterr()
    assert main(["attend", str(shot), "--physics", "--out", str(tmp_path / "sim.usda"), "--window", "0.1"]) == 0
    said = _warnings(capsys)
    assert len(said) == 1 and str(first.resolve()) in said[0]
