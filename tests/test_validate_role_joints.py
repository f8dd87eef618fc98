"""``validate``'s ``GazeMapRoleJoints`` finds a bound joint as ``apply`` binds it: by its path or its own
name. An audit found ``gaze:binding:head = ["mixamorig_Head"]`` (the joint's own name, as docs/binding.md
allows) bound by ``apply`` and called 'not a joint' (exit 3) by ``validate``."""

from __future__ import annotations

import pytest
from pxr import Sdf, Usd

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.console.main import main

from . import synthetic as syn


@pytest.mark.parametrize("value, clean", [("mixamorig_Head", True), ("HEAD", True), (None, True), ("Skull", False)])
def test_a_binding_by_own_name_validates_as_apply_binds_it(tmp_path, capsys, value, clean):
    rig = syn.make_rig(tmp_path / "in.usda", frames=30, mesh=False)
    gaze_map = tmp_path / "map.usda"
    assert main(["dump-map", str(gaze_map)]) == 0
    stage = Usd.Stage.Open(str(rig.path))
    root = stage.GetPrimAtPath(rig.skel_root)
    root.GetReferences().AddReference("./map.usda")  # its defaultPrim, the map
    bound = value or rig.joint("head")  # None: the joint's path
    root.CreateAttribute("gaze:binding:head", Sdf.ValueTypeNames.TokenArray, variability=Sdf.VariabilityUniform).Set([bound])
    stage.GetRootLayer().Save()
    capsys.readouterr()
    code = main(["validate", str(rig.path), "--only-usdgaze"])
    out = capsys.readouterr().out.strip().splitlines()
    if clean:
        assert code == 0, out
        report = api.apply(rig.path, ["0.2s:20:0"], tmp_path / "g.usda")
        assert report.characters[0].chain["head"] == [rig.joint("head")]
    else:
        assert code == 3 and len(out) == 1 and "GazeMapRoleJoints.UnknownJoint" in out[0] and "'Skull'" in out[0], out
