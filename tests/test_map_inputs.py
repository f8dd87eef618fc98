"""Trial sheets and gaze maps: TOML values of the wrong type are one-line sheet errors, and `validate`
checks every GazeMapAPI attribute's type as `apply` does."""

from __future__ import annotations

import pytest

from usdgaze.console.main import main
from usdgaze.ingest.sheet import SheetError, load_sheet

_TRIAL = '[[trial]]\nfile = "a.usda"\nyaw = 30\npitch = 0\n'


@pytest.mark.parametrize("extra, message", [
    ("skeleton = 5\n", "trial 1: skeleton 5 is not a Skeleton prim path"),
    ('skeleton = ["/Rig/Skel"]\n', "trial 1: skeleton ['/Rig/Skel'] is not a Skeleton prim path"),
    ('name = ["a"]\n', "trial 1: trial ['a'] is not a name"),
    ("crop = [true, 40]\n", "trial 1: crop_start true is not a number"),
])
def test_toml_values_of_the_wrong_type_name_the_trial_and_key(tmp_path, extra, message):
    sheet = tmp_path / "sheet.toml"
    sheet.write_text(_TRIAL + extra)
    with pytest.raises(SheetError) as info:
        load_sheet(sheet)
    assert str(info.value) == f"{sheet} {message}"


def test_a_boolean_yaw_is_not_read_as_one_degree(tmp_path):
    sheet = tmp_path / "sheet.toml"
    sheet.write_text('[[trial]]\nfile = "a.usda"\nyaw = true\npitch = 0\n')
    with pytest.raises(SheetError, match="yaw true is not a number"):
        load_sheet(sheet)


def test_build_map_exits_2_on_a_non_string_skeleton_and_writes_nothing(tmp_path, capsys):
    sheet = tmp_path / "sheet.toml"
    (tmp_path / "a.usda").write_text("#usda 1.0\n")
    sheet.write_text(_TRIAL + "skeleton = 5\n")
    out = tmp_path / "map.usda"
    assert main(["build-map", str(sheet), "--out", str(out), "--quiet", "--min-trials", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [f"usdgaze: error: {sheet} trial 1: skeleton 5 is not a Skeleton prim path"]
    assert not out.exists()


@pytest.mark.parametrize("name, type_name, value, authored, expected", [
    ("gaze:synthesis:samples", "Float", 50.5, "float", "int"),
    ("gaze:binding:forward", "Float2", (0.0, 1.0), "Vec2f", "float3"),
    ("gaze:binding:head", "String", "Head", "str", "token[]"),
])
def test_validate_names_a_map_setting_binding_or_forward_of_the_wrong_type(tmp_path, name, type_name, value, authored,
                                                                           expected):
    """apply refuses these maps (read_map checks every attribute's type); validate must say so too."""
    from pxr import Sdf

    from usdgaze.gaze.defaults import default_definition
    from usdgaze.review.validation import run
    from usdgaze.usd.schema import dump_map

    path = tmp_path / "map.usda"
    dump_map(default_definition(), path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    prim = layer.GetPrimAtPath("/GazeMap")
    prim.RemoveProperty(prim.attributes[name])
    Sdf.AttributeSpec(prim, name, getattr(Sdf.ValueTypeNames, type_name), Sdf.VariabilityUniform).default = value
    layer.Save()
    problems = run(path, only_usdgaze=True)
    assert [(p["site"], p["error"], p["message"]) for p in problems] == [
        (f"/GazeMap.{name}", "WrongType", f"{name}: authored as {authored}, expected {expected}")]
