"""``usdgaze inspect`` on a stage with several SkelRoots: a good character, one SkelRoot without a Skeleton
and one whose GazeMapAPI examples are malformed. Each problem stays with its own SkelRoot's entry (as a
skeleton's binding problem does); the others are still listed, and the text names the SkelRoot with no
Skeleton. The malformed map's own line is what ``apply`` says of it."""

from __future__ import annotations

import json

import numpy as np

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from pxr import Sdf, Vt

from usdgaze.console.main import main

from . import synthetic as syn


def _stage(tmp_path):
    r = syn.make_rig(tmp_path / "in.usda", frames=30, mesh=False)
    assert main(["dump-map", str(tmp_path / "map.usda"), "--prim", "/Map"]) == 0
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    Sdf.CreatePrimInLayer(layer, "/Empty").specifier = Sdf.SpecifierDef
    layer.GetPrimAtPath("/Empty").typeName = "SkelRoot"
    Sdf.CopySpec(layer, "/Character", layer, "/Mapped")
    mapped = layer.GetPrimAtPath("/Mapped")
    mapped.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeMapAPI"]))
    source = Sdf.Layer.FindOrOpen(str(tmp_path / "map.usda"))
    for attr in source.GetPrimAtPath("/Map").attributes:
        Sdf.CopySpec(source, attr.path, layer, mapped.path.AppendProperty(attr.name))
    yaw = layer.GetAttributeAtPath("/Mapped.gaze:examples:yaw")
    yaw.default = Vt.FloatArray(list(yaw.default)[:-3])  # three entries short
    layer.Save()
    return r.path


def test_inspect_lists_every_skel_root_with_its_own_problem(tmp_path, capsys):
    path = _stage(tmp_path)
    assert main(["apply", str(path), "--skel-root", "/Mapped", "--shift", "0.3s:30:0",
                 "--out", str(tmp_path / "g.usdc")]) == 2
    map_line = capsys.readouterr().err.strip().removeprefix("usdgaze: error: ")
    assert "/Mapped.gaze:examples:yaw" in map_line

    # Everything is printed, and the exit says a skeleton cannot bind (a pre-flight check must see it).
    assert main(["inspect", str(path), "--json"]) == 2
    printed = capsys.readouterr()
    err = printed.err.strip().splitlines()
    assert len(err) == 1 and "1 of 2 skeleton(s) cannot bind (/Mapped/" in err[0], err
    roots = {r["path"]: r for r in json.loads(printed.out)["skel_roots"]}
    assert sorted(roots) == ["/Character", "/Empty", "/Mapped"]
    assert roots["/Character"]["skeletons"][0]["chain"]["head"] == ["mixamorig_Head"]
    assert roots["/Empty"]["skeletons"] == []
    assert map_line in roots["/Mapped"]["map"]
    assert roots["/Mapped"]["skeletons"][0]["error"] == map_line

    assert main(["inspect", str(path)]) == 2
    text = capsys.readouterr().out.splitlines()
    empty = text.index("SkelRoot /Empty  gaze map: none (the built-in map is used)")
    assert text[empty + 1] == "  no Skeleton under this SkelRoot"


def test_a_skeleton_belongs_to_its_nearest_skel_root(tmp_path, capsys):
    """A character's SkelRoot inside another (a set's): its skeleton was listed under both, and
    ``apply --skel-root`` the inner one was refused, its animation said to drive the outer one's too."""
    from pxr import Usd, UsdGeom, UsdSkel

    from . import measure

    r = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False)
    stage = Usd.Stage.CreateNew(str(tmp_path / "nested.usda"))
    stage.SetStartTimeCode(0), stage.SetEndTimeCode(59), stage.SetTimeCodesPerSecond(r.time_codes_per_second)
    UsdGeom.SetStageUpAxis(stage, "Y"), UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdSkel.Root.Define(stage, "/Outer")
    stage.DefinePrim("/Outer/Inner").GetReferences().AddReference("./in.usda", "/Character")
    stage.GetRootLayer().defaultPrim = "Outer"
    stage.Save()
    assert main(["inspect", str(tmp_path / "nested.usda"), "--json"]) == 0
    roots = {root["path"]: [s["path"] for s in root["skeletons"]] for root in json.loads(capsys.readouterr().out)["skel_roots"]}
    assert roots == {"/Outer": [], "/Outer/Inner": ["/Outer/Inner/Skel"]}
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(tmp_path / "nested.usda"), "--skel-root", "/Outer/Inner", "--shift", "10:40:0",
                 "--out", str(tmp_path / "g.usdc"), "--preview", str(preview)]) == 0
    base = measure.posed(str(tmp_path / "nested.usda"), "/Outer/Inner/Skel")
    new = measure.posed(str(preview), "/Outer/Inner/Skel")
    head = r.leaf["head"]
    turned = measure.rotation_angle_deg(new.world[:, new.index(head), :3, :3], base.world[:, base.index(head), :3, :3])
    assert turned[-1] > 5.0  # the inner character's head turned (its share of the 40 deg)

    # Without --skel-root: the outer SkelRoot holds no Skeleton of its own, so the stage has one
    # character to pick (it was '2 SkelRoots and none has a GazeMapAPI; pick one with --skel-root').
    again = tmp_path / "again.usda"
    assert main(["apply", str(tmp_path / "nested.usda"), "--shift", "10:40:0", "--out", str(tmp_path / "g2.usdc"),
                 "--preview", str(again)]) == 0
    new = measure.posed(str(again), "/Outer/Inner/Skel")
    turned_again = measure.rotation_angle_deg(new.world[:, new.index(head), :3, :3],
                                              base.world[:, base.index(head), :3, :3])
    assert np.array_equal(turned_again, turned)
