"""``usdgaze validate`` on a hand-edited gaze map says what ``apply --map`` refuses in it, in the same
words: a setting past its upper bound, a forward that is no direction, an array keyed in time. Each
was clean to validate (or said 'missing' for the keyed array) while apply refused the map."""

from __future__ import annotations

import pytest
from pxr import Gf, Sdf, Usd

from usdgaze.console.main import main
from usdgaze.review import usdview

from . import synthetic as syn
from .usdview_standin import UsdviewApiStandIn


def _keyed(spec: Sdf.PrimSpec, name: str) -> None:
    attr = spec.attributes[name]
    value = attr.default
    attr.ClearDefaultValue()
    spec.layer.SetTimeSample(attr.path, 1.0, value)


def _set(name, value):
    return lambda spec: setattr(spec.attributes[name], "default", value) if name in spec.attributes else \
        setattr(Sdf.AttributeSpec(spec, name, Sdf.ValueTypeNames.Int if isinstance(value, int) else Sdf.ValueTypeNames.Float3,
                                  Sdf.VariabilityUniform), "default", value)


EDITS = {
    "blend-size-past-its-bound": (_set("gaze:synthesis:blendSize", 99), "gaze:synthesis:blendSize"),
    "forward-nan": (_set("gaze:binding:forward", Gf.Vec3f(float("nan"), 0.0, 0.0)), "gaze:binding:forward"),
    "yaw-keyed-in-time": (lambda spec: _keyed(spec, "gaze:examples:yaw"), "gaze:examples:yaw"),
}


@pytest.mark.parametrize("case", sorted(EDITS))
def test_validate_says_what_apply_refuses_in_a_map(tmp_path, capsys, case):
    edit, attr = EDITS[case]
    map_path = tmp_path / "map.usda"
    assert main(["dump-map", str(map_path)]) == 0
    layer = Sdf.Layer.FindOrOpen(str(map_path))
    (spec,) = [s for s in layer.rootPrims]
    edit(spec)
    layer.Save()
    rig = syn.make_rig(tmp_path / "rig.usda", frames=20, mesh=False)
    capsys.readouterr()
    assert main(["apply", str(rig.path), "--map", str(map_path), "--shift", "0.1s:20:0", "--out", str(tmp_path / "o.usda")]) == 2
    (refusal,) = capsys.readouterr().err.strip().splitlines()
    prefix = f"usdgaze: error: {map_path}:{spec.path}.{attr}: "
    assert refusal.startswith(prefix), refusal
    assert not (tmp_path / "o.usda").exists()
    assert main(["validate", str(map_path), "--only-usdgaze"]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    said = refusal[len(prefix):]
    assert line.startswith(f"{map_path}:{spec.path}.{attr}: error: {attr}: {said} (usdgaze.review.validators:"), line


@pytest.mark.parametrize("arc", ["references", "sublayer"])
def test_a_bad_value_in_a_composed_map_file_is_named_in_that_file(tmp_path, capsys, arc):
    """A map a character brings in from a map file (the shared-map workflow) or a sublayer: apply named
    the stage, which holds no such value; it names the file that authors it, as validate does."""
    map_path = tmp_path / "map.usda"
    assert main(["dump-map", str(map_path)]) == 0
    layer = Sdf.Layer.FindOrOpen(str(map_path))
    (spec,) = layer.rootPrims
    spec.attributes["gaze:synthesis:neckShare"].default = 2.0
    layer.Save()
    rig = syn.make_rig(tmp_path / "rig.usda", frames=20, mesh=False)
    stage_layer = Sdf.Layer.FindOrOpen(str(rig.path))
    if arc == "references":
        stage_layer.GetPrimAtPath(rig.skel_root).referenceList.Prepend(Sdf.Reference("map.usda", spec.path))
    else:  # the map's prim spec renamed to the character's SkelRoot, in a sublayer of the stage
        spec.name = rig.skel_root.strip("/")
        spec.specifier = Sdf.SpecifierOver
        layer.Save()
        stage_layer.subLayerPaths.append("map.usda")
    stage_layer.Save()
    capsys.readouterr()
    assert main(["apply", str(rig.path), "--shift", "0.1s:20:0", "--out", str(tmp_path / "o.usda")]) == 2
    (refusal,) = capsys.readouterr().err.strip().splitlines()
    site = f"{map_path}:{rig.skel_root}.gaze:synthesis:neckShare"
    assert refusal == f"usdgaze: error: {site}: 2.0, expected a number in [0, 1]"
    assert main(["validate", str(rig.path), "--only-usdgaze"]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    assert line.startswith(f"{site}: error: gaze:synthesis:neckShare: 2.0, expected a number in [0, 1] ("), line


@pytest.mark.parametrize("onto", ["skeleton", "parent"])
def test_a_map_referenced_onto_the_skeleton_or_a_parent_is_refused_not_ignored(tmp_path, capsys, onto):
    """A map file referenced one prim too deep (onto the Skeleton) or too high (onto the Xform holding the
    character): apply used the built-in map without a word (exit 0) and inspect said 'none (the built-in
    map is used)', while validate flagged it. All three now name the prim."""
    map_path = tmp_path / "map.usda"
    assert main(["dump-map", str(map_path)]) == 0
    rig = syn.make_rig(tmp_path / "rig.usda", frames=20, mesh=False, root_path="/World/Character")
    stage_layer = Sdf.Layer.FindOrOpen(str(rig.path))
    map_layer = Sdf.Layer.FindOrOpen(str(map_path))
    (spec,) = map_layer.rootPrims
    target = rig.skeleton if onto == "skeleton" else "/World"
    stage_layer.GetPrimAtPath(target).referenceList.Prepend(Sdf.Reference("map.usda", spec.path))
    stage_layer.Save()
    kind = "Skeleton" if onto == "skeleton" else stage_layer.GetPrimAtPath("/World").typeName or "typeless prim"
    capsys.readouterr()
    out = tmp_path / "o.usda"
    assert main(["apply", str(rig.path), "--shift", "0.1s:20:0", "--out", str(out)]) == 2
    said = (f"{rig.path}:{target}: GazeMapAPI is applied to a {kind}; it applies only to SkelRoot "
            f"(this character's is {rig.skel_root}): apply it there")
    assert capsys.readouterr().err.strip().splitlines() == [f"usdgaze: error: {said}"]
    assert not out.exists()
    assert main(["inspect", str(rig.path)]) == 2
    assert f"SkelRoot {rig.skel_root}  gaze map: none usable: {said}" in capsys.readouterr().out
    assert main(["validate", str(rig.path), "--only-usdgaze"]) == 3
    assert capsys.readouterr().out.splitlines() == [
        f"{rig.path}:{target}: error: GazeMapAPI is applied to a {kind}; it applies only to SkelRoot "
        "(usdgaze.review.validators:GazeMapRoleJoints.NotSkelRoot)"]
    # usdview's Print Map and Schedule said 'no GazeMapAPI (the built-in map is used)'
    text = usdview.summary(UsdviewApiStandIn(Usd.Stage.Open(str(rig.path))))
    assert f"{rig.skel_root}: GazeMapAPI unreadable (rig.usda:{target}: GazeMapAPI is applied to a {kind};" in text
