"""Trial sheets and gaze maps: TOML values of the wrong type are one-line sheet errors, and `validate`
checks every GazeMapAPI attribute's type as `apply` does."""

from __future__ import annotations

from pathlib import Path

import pytest
from pxr import Gf

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
    ("gaze:binding:forward", "Float2", (0.0, 1.0), "float2", "float3"),
    ("gaze:binding:head", "String", "Head", "string", "token[]"),
    # a string or a pair where a number is compared with its range: validate's internal error (exit 1)
    ("gaze:synthesis:neighbors", "String", "4", "string", "int"),
    ("gaze:synthesis:neckShare", "String", "0.5", "string", "float"),
    ("gaze:synthesis:refine", "Int2", Gf.Vec2i(1, 2), "int2", "int"),
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


def _dumped(tmp_path, edit=None):
    out = tmp_path / "map.usda"
    assert main(["dump-map", str(out)]) == 0
    if edit is not None:
        from pxr import Sdf

        layer = Sdf.Layer.FindOrOpen(str(out))
        edit(layer)
        layer.Save()
    return out


def test_a_map_file_passes_its_own_validate_and_inspect_says_what_it_is(tmp_path, capsys):
    """Every map the tool wrote failed `validate` (exit 3: no upAxis, no metersPerUnit, which a file of
    classes alone does not need), and `inspect` said only "no SkelRoot on the stage"."""
    out = _dumped(tmp_path)
    capsys.readouterr()
    assert main(["validate", str(out)]) == 0, capsys.readouterr().out
    assert main(["inspect", str(out)]) == 2
    assert "only the class /GazeMap (a gaze map file: give it to apply --map" in capsys.readouterr().err


def test_an_inactive_map_prim_is_refused(tmp_path, capsys):
    """`apply --map` used a map switched off with active = false, without a word."""
    out = _dumped(tmp_path, lambda layer: setattr(layer.GetPrimAtPath("/GazeMap"), "active", False))
    cmu = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_02.usdc"
    capsys.readouterr()
    assert main(["apply", str(cmu), "--map", f"{out}:/GazeMap", "--shift", "1s:30:0", "--out",
                 str(tmp_path / "gaze.usda")]) == 2
    assert "/GazeMap: is inactive (active = false)" in capsys.readouterr().err
    assert not (tmp_path / "gaze.usda").exists()


def test_a_trial_that_never_reached_its_target_is_said(tmp_path, capsys):
    """A clip labelled with a target its head never turned toward was stored with the eyes far past
    their range in the head, silently; the map then fell short wherever it was used."""
    from . import ingest_synth as synth

    session = synth.write_skel_session(tmp_path / "s")
    text = session.sheet.read_text()
    first = session.trials[1]  # relabel one trial: the same motion, a target 120 deg further round
    wrong = first.yaw + 120.0 if first.yaw <= 0 else first.yaw - 120.0
    text = text.replace(f'name = "{first.name}"\nfile = "{first.file.name}"\nyaw = {first.yaw:g}',
                        f'name = "{first.name}"\nfile = "{first.file.name}"\nyaw = {wrong:g}')
    session.sheet.write_text(text)
    capsys.readouterr()
    assert main(["build-map", str(session.sheet), "--out", str(tmp_path / "map.usda")]) == 0
    said = [line for line in capsys.readouterr().out.splitlines() if "past their range" in line]
    assert len(said) == 1 and said[0].split()[0] == first.name, said


def test_a_long_occlusion_filled_with_a_straight_line_is_said(tmp_path, capsys):
    """A marker unseen for 0.4 s across a trial's head turn was filled linearly and the trial marked ok:
    the only sign was the count of filled samples in the report."""
    import numpy as np

    from . import ingest_synth as synth

    session = synth.write_c3d_session(tmp_path / "s")
    trial = next(t for t in session.trials if t.yaw != 0)
    rng = np.random.default_rng(3)
    points, onset = synth.simulate_trial(trial.motion, rng, rate=synth.RATE)
    gap = slice(onset, onset + int(0.4 * synth.RATE))
    points[gap, 0] = np.nan
    synth.write_points(trial.file, synth.LABELS, points, synth.RATE)
    capsys.readouterr()
    assert main(["build-map", str(session.sheet), "--markers", str(session.markerset), "--out",
                 str(tmp_path / "map.usda")]) == 0
    said = [line for line in capsys.readouterr().out.splitlines() if "filled with a straight line" in line]
    assert len(said) == 1 and said[0].split()[0] == trial.name and f"'{synth.LABELS[0]}'" in said[0], said
