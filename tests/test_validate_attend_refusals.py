"""``usdgaze validate`` says what ``attend --physics`` refuses of an obstacle's size, in its words, from
the one check both use (``usd.objects.obstacle_radius_problem``): an obstacle with no authored
``gaze:object:radius`` (simulated, before that refusal, as the schema's 0.1 m sphere) or one outside
(0, 10] m. validate had said nothing of it (exit 0); an obstacle of a proper size stays clean."""

from __future__ import annotations

from pathlib import Path

import pytest
from pxr import Sdf

from usdgaze.console.main import main

from .bad_cases_sweep import _obstacle, _physics, _task

VALIDATOR = "usdgaze.review.validators:PhysicsObstacles.Radius"


def _no_radius(api: bool):
    """An obstacle sphere (a GazeObjectAPI object or not) whose size is its own ``radius`` only."""
    def author(layer, r):
        if api:
            _obstacle(0.0)(layer, r)
            prim = layer.GetPrimAtPath("/Obstacles/A")
            prim.RemoveProperty(prim.properties["gaze:object:radius"])
        else:
            _task(lambda r: "/Obstacles/A", kind="obstacle", type_name="Sphere", at=(1.0, 0.0, 0.5))(layer, r)
        Sdf.AttributeSpec(layer.GetPrimAtPath("/Obstacles/A"), "radius", Sdf.ValueTypeNames.Double).default = 0.4
    return author


def _in_an_instance(d: Path):
    """The obstacle (no radius) inside an instanceable group: attend reads objects inside instances."""
    (d / "group.usda").write_text('#usda 1.0\n\ndef Xform "Group"\n{\n    def Sphere "A"\n    {\n'
                                  '        double radius = 0.4\n        token usdgaze:physics:task = "obstacle"\n'
                                  '        double3 xformOp:translate = (1, 0, 0.5)\n'
                                  '        uniform token[] xformOpOrder = ["xformOp:translate"]\n    }\n}\n')

    def author(layer, r):
        prim = Sdf.CreatePrimInLayer(layer, "/Obstacles")
        prim.specifier, prim.typeName = Sdf.SpecifierDef, "Xform"
        prim.referenceList.Prepend(Sdf.Reference("./group.usda", "/Group"))
        prim.SetInfo("instanceable", True)
    return author


def _sampled_apart():
    """A radius keyed 0.4 then 0.6: one value for the whole shot, attend says (the default time read
    the schema's fallback)."""
    def author(layer, r):
        _obstacle(0.4)(layer, r)
        spec = layer.GetPrimAtPath("/Obstacles/A").properties["gaze:object:radius"]
        spec.ClearDefaultValue()
        for t, v in ((0.0, 0.4), (10.0, 0.6)):
            layer.SetTimeSample(spec.path, t, v)
    return author


CASES = {"not-authored": lambda d: _no_radius(True), "not-authored-no-api": lambda d: _no_radius(False),
         "zero": lambda d: _obstacle(0.0), "negative": lambda d: _obstacle(-0.5), "huge": lambda d: _obstacle(1e6),
         "not-authored-in-an-instance": _in_an_instance, "sampled-apart": lambda d: _sampled_apart()}


@pytest.mark.parametrize("case", list(CASES))
def test_an_obstacle_of_no_proper_size_is_flagged_as_attend_physics_refuses_it(tmp_path, capsys, case):
    argv = _physics(tmp_path, CASES[case](tmp_path))
    stage = argv[1]
    capsys.readouterr()
    assert main(argv) == 2
    (refusal,) = capsys.readouterr().err.strip().splitlines()
    site, problem = refusal.removeprefix(f"usdgaze: error: {stage}:").split(": ", 1)
    assert site == "/Obstacles/A.gaze:object:radius", refusal
    assert not (tmp_path / "gaze.usdc").exists()
    assert main(["validate", stage, "--only-usdgaze"]) == 3
    lines = capsys.readouterr().out.splitlines()
    # One line in attend's words; a negative radius was GazeObject's Range line alone. Sited on the
    # attribute where the prim has it (GazeObjectAPI's), else on the prim (USD finds no site there).
    at = site if "no-api" not in case and "instance" not in case else site.split(".", 1)[0]
    assert lines == [f"{stage}:{at}: error: gaze:object:radius: {problem} ({VALIDATOR})"], lines


def test_an_obstacle_with_its_size_authored_stays_clean(tmp_path, capsys):
    argv = _physics(tmp_path, _obstacle(0.4))
    capsys.readouterr()
    assert main(["validate", argv[1], "--only-usdgaze"]) == 0
    assert capsys.readouterr().out == ""


def test_an_obstacle_radius_of_the_wrong_type_is_one_line(tmp_path, capsys):
    """A string radius: GazeObject's Type line, which attend's refusal says too; not a second line."""
    def author(layer, r):
        _obstacle(0.4)(layer, r)
        prim = layer.GetPrimAtPath("/Obstacles/A")
        prim.RemoveProperty(prim.properties["gaze:object:radius"])
        Sdf.AttributeSpec(prim, "gaze:object:radius", Sdf.ValueTypeNames.String).default = "big"
    argv = _physics(tmp_path, author)
    capsys.readouterr()
    assert main(argv) == 2
    (refusal,) = capsys.readouterr().err.strip().splitlines()
    assert refusal.endswith("/Obstacles/A.gaze:object:radius: is a string, expected a float or double"), refusal
    assert main(["validate", argv[1], "--only-usdgaze"]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    assert line.endswith("gaze:object:radius: is a string, expected a float or double "
                         "(usdgaze.review.validators:GazeObject.Type)"), line
