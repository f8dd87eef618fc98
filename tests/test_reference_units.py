"""A character brought in by a reference or payload from a layer in another metersPerUnit than the stage's.

USD reads it in the stage's unit, whatever the asset says: a metre rig referenced into a stage that
authors none (0.01) is a 1.6 cm character, which `apply` ran on and said only as targets out of reach.
It is refused (docs/bad-inputs.md, `meters-per-unit-only-in-a-reference`), and `validate` says it; a
reference in the stage's unit, one authoring none in a stage that authors none, and one scaled to make
up for the units are accepted. Reaching a target is measured by UsdSkel FK (tests/measure.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review.validation import run as validate

from . import arc_shots
from . import measure
from . import synthetic as syn

RATE = 24.0


def _shot(tmp_path, rig_mpu: float | None, shot_mpu: float | None, scale: float = 1.0, arc: str = "reference",
          via: bool = False):
    """``shot.usda`` bringing a synthetic rig in at /Character through ``arc``; ``None`` units: not
    authored. ``scale`` on the referencing prim; ``via``: through a middle layer that authors none."""
    rig = syn.make_rig(tmp_path / "char.usda", frames=72, time_codes_per_second=RATE, mesh=False,
                       meters_per_unit=rig_mpu or 0.01)
    if rig_mpu is None:
        syn.edit(rig.path, lambda layer: layer.pseudoRoot.ClearInfo("metersPerUnit"))
    op = ("xformOp:scale", Sdf.ValueTypeNames.Double3, Gf.Vec3d(scale, scale, scale)) if scale != 1.0 else None
    return rig, arc_shots.shot_over(tmp_path, rig, arc, via, {"upAxis": "Y", "metersPerUnit": shot_mpu}, op)


def _units_problems(path) -> list[dict]:
    return [p for p in validate(path, only_usdgaze=True) if p["validator"].endswith("SkeletonUnits")]


@pytest.mark.parametrize("rig_mpu, shot_mpu, arc, via", [
    (1.0, None, "reference", False), (1.0, 0.01, "payload", False), (1.0, None, "reference", True),
    (0.01, 1.0, "reference", False),
])
def test_a_character_in_another_unit_is_refused_and_validate_says_it(tmp_path, capsys, rig_mpu, shot_mpu, arc, via):
    rig, shot = _shot(tmp_path, rig_mpu, shot_mpu, arc=arc, via=via)
    capsys.readouterr()
    assert main(["apply", str(shot), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert f"through a {arc} of {tmp_path / 'char.usda'}, which says metersPerUnit {rig_mpu:g}" in err[0], err[0]
    assert f"scale the {arc} by {rig_mpu / (shot_mpu or 0.01):g}" in err[0], err[0]
    assert not (tmp_path / "gaze.usdc").exists()
    problems = _units_problems(shot)
    assert len(problems) == 1 and "metersPerUnit" in problems[0]["message"], problems


@pytest.mark.parametrize("rig_mpu, shot_mpu", [(1.0, 1.0), (None, None), (0.01, None)])
def test_a_character_in_the_stages_unit_is_accepted(tmp_path, capsys, rig_mpu, shot_mpu):
    rig, shot = _shot(tmp_path, rig_mpu, shot_mpu)
    assert main(["apply", str(shot), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc")]) == 0
    assert _units_problems(shot) == []


def test_a_reference_scaled_to_the_stages_unit_is_accepted_and_reaches_its_target(tmp_path):
    """A metre rig referenced into a centimetre stage, scaled by 100: the eyes land on a point 3 m
    ahead given in centimetres, by FK."""
    rig, shot = _shot(tmp_path, 1.0, None, scale=100.0)
    assert _units_problems(shot) == []
    base = measure.posed(str(shot), rig.skeleton)
    look = int(0.5 * RATE)
    target = base.position(rig.leaf["head"])[look] + 300.0 * (np.cos(-0.4) * rig.forward + np.sin(-0.4) * rig.left)
    preview = tmp_path / "preview.usda"
    result = api.apply(shot, [], tmp_path / "gaze.usdc", preview=preview,
                       look_at=[",".join(f"{v:.4f}" for v in target) + "@0.5s"])
    assert not result.warnings, result.warnings
    new = measure.posed(str(preview), rig.skeleton)
    looking = (new.times - rig.start_time) / RATE >= 1.3
    for eye in rig.eye_leaves:
        miss = measure.eye_miss_deg(new, eye, rig.forward, target)
        assert miss[looking].max() < 1.0, (eye, miss[looking].max())
