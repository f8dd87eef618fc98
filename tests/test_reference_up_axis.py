"""A character brought in by a reference or payload from a layer in another upAxis than the stage's.

USD takes the stage's up for it and does not turn it: a Z-up export referenced into a Y-up stage lies
on its back. It is refused (docs/bad-inputs.md, `up-axis-only-in-a-reference`), and `validate` says
it; a reference in the stage's axis, and one rotated -90 deg about X (Z onto Y) on the referencing
prim, are accepted. Reaching a target is measured by UsdSkel FK (tests/measure.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review.validation import run as validate

from . import arc_shots
from . import attend_support as A
from . import measure
from . import synthetic as syn

RATE = 24.0


def _shot(tmp_path, rig_up: str | None, shot_up: str | None, rotate_x: float = 0.0, arc: str = "reference",
          via: bool = False, walk_speed: float = 1.2):
    """``shot.usda`` bringing a synthetic rig built ``rig_up`` up in at /Character through ``arc``;
    ``None``: upAxis not authored (the rig is then built Y up). ``rotate_x`` (deg) on the referencing
    prim; ``via``: through a middle layer that authors none; ``walk_speed`` (m/s) of the rig."""
    rig = syn.make_rig(tmp_path / "char.usda", frames=72, time_codes_per_second=RATE, mesh=False,
                       up_axis=rig_up or "Y", walk_speed=walk_speed)
    if rig_up is None:
        syn.edit(rig.path, lambda layer: layer.pseudoRoot.ClearInfo("upAxis"))
    op = ("xformOp:rotateX", Sdf.ValueTypeNames.Float, rotate_x) if rotate_x else None
    return rig, arc_shots.shot_over(tmp_path, rig, arc, via, {"upAxis": shot_up,
                                                         "metersPerUnit": rig.meters_per_unit}, op)


def _up_problems(path) -> list[dict]:
    return [p for p in validate(path, only_usdgaze=True) if p["validator"].endswith("SkeletonUpAxis")]


def _refused(tmp_path, capsys, argv: list[str]) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert not (tmp_path / "gaze.usdc").exists()
    return err[0]


@pytest.mark.parametrize("rig_up, shot_up, arc, via, rotate_x", [
    ("Z", "Y", "reference", False, 0.0), ("Z", None, "payload", False, 0.0), ("Z", "Y", "reference", True, 0.0),
    ("Y", "Z", "reference", False, 0.0),
    ("Z", "Y", "reference", False, 90.0),  # turned the wrong way: the character stands on its head
])
def test_a_character_in_another_up_axis_is_refused_and_validate_says_it(tmp_path, capsys, rig_up, shot_up, arc,
                                                                         via, rotate_x):
    rig, shot = _shot(tmp_path, rig_up, shot_up, rotate_x=rotate_x, arc=arc, via=via)
    stage_up = shot_up or "Y"
    line = _refused(tmp_path, capsys,
                    ["apply", str(shot), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc")])
    assert f"{shot}:/Character: is defined through a {arc} of {tmp_path / 'char.usda'}, which says upAxis {rig_up}, " \
           f"but the stage's up is {stage_up}" in line, line
    assert f"author upAxis = {rig_up} on {shot} or rotate the {arc}" in line, line
    assert f"off {stage_up}" in line and ("180 deg off" if rotate_x else "90 deg off") in line, line
    problems = _up_problems(shot)
    assert len(problems) == 1 and f"upAxis {rig_up}" in problems[0]["message"], problems


def _with_ball(rig, shot):
    """A still GazeObjectAPI ball 2 m ahead of the head and 20 deg to its left, at its first frame,
    placed by UsdSkel FK (the asset's axes as USD composes them); where it is."""
    base = measure.posed(str(shot), rig.skeleton)
    turn = base.skel_to_world[:3, :3] / np.cbrt(np.linalg.det(base.skel_to_world[:3, :3]))
    aside = np.cos(np.radians(20)) * (rig.forward @ turn) + np.sin(np.radians(20)) * (rig.left @ turn)
    where = base.position(rig.leaf["head"])[0] + 2.0 / rig.meters_per_unit * aside
    layer = Sdf.Layer.FindOrOpen(str(shot))
    A.still_ball(layer, "/Objects/Ball", where, 0.1 / rig.meters_per_unit)
    layer.Save()
    return where


def test_attend_refuses_a_character_in_another_up_axis(tmp_path, capsys):
    rig, shot = _shot(tmp_path, "Z", "Y")
    _with_ball(rig, shot)
    line = _refused(tmp_path, capsys, ["attend", str(shot), "--out", str(tmp_path / "gaze.usdc")])
    assert f"{shot}:/Character: is defined through a reference of {tmp_path / 'char.usda'}, which says upAxis Z, " \
           "but the stage's up is Y (authored on it)" in line, line


def test_attend_looks_at_a_ball_from_a_reference_turned_to_the_stages_up(tmp_path):
    """The same Z-up rig rotated -90 deg about X: attend runs and writes, and the eyes (FK on the
    composed result) hold the ball within 5 deg once they have found it (measured: from the second
    frame, on every frame, median 0.2 deg)."""
    rig, shot = _shot(tmp_path, "Z", "Y", rotate_x=-90.0, walk_speed=0.0)  # the ball stays ahead
    where = _with_ball(rig, shot)
    out = tmp_path / "gaze.usdc"
    assert main(["attend", str(shot), "--out", str(out)]) == 0
    composed = tmp_path / "composed.usda"
    layer = Sdf.Layer.CreateNew(str(composed))
    layer.subLayerPaths[:] = [str(out), str(shot)]
    layer.Save()
    new = measure.posed(str(composed), rig.skeleton)
    off = []
    for eye in rig.eye_leaves:
        to_ball = where - new.position(eye)
        to_ball /= np.linalg.norm(to_ball, axis=-1, keepdims=True)
        off.append(measure.angle_between(new.axis(eye, measure.local_forward(new, eye, rig.forward)), to_ball))
    off = np.max(off, axis=0)
    found = int(np.argmax(off < 5.0))
    held = off[found:] < 5.0
    assert off[found] < 5.0 and held.mean() > 0.9 and np.median(off[found:]) < 1.0, (found, held.mean())


@pytest.mark.parametrize("rig_up, shot_up, rotate_x", [
    ("Z", "Z", 0.0), ("Y", None, 0.0), (None, "Z", 0.0),
    ("Y", "Z", 90.0),  # the turn the refusal of a Y-up asset in a Z-up stage asks for
])
def test_a_character_in_the_stages_up_axis_is_accepted(tmp_path, rig_up, shot_up, rotate_x):
    rig, shot = _shot(tmp_path, rig_up, shot_up, rotate_x=rotate_x)
    assert main(["apply", str(shot), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc")]) == 0
    assert _up_problems(shot) == []


def test_a_reference_turned_to_the_stages_up_is_accepted_and_reaches_its_target(tmp_path):
    """A Z-up rig referenced into a Y-up stage, rotated -90 deg about X (Z onto Y): the eyes land on
    a point 3 m ahead and to the side, by FK."""
    rig, shot = _shot(tmp_path, "Z", "Y", rotate_x=-90.0)
    assert _up_problems(shot) == []
    base = measure.posed(str(shot), rig.skeleton)
    turn = base.skel_to_world[:3, :3]  # the asset's axes in the stage, as USD composes them
    assert np.allclose(rig.up @ turn, [0.0, 1.0, 0.0], atol=1e-6)
    look = int(0.5 * RATE)
    aside = np.cos(-0.4) * (rig.forward @ turn) + np.sin(-0.4) * (rig.left @ turn)
    target = base.position(rig.leaf["head"])[look] + 3.0 / rig.meters_per_unit * aside
    preview = tmp_path / "preview.usda"
    result = api.apply(shot, [], tmp_path / "gaze.usdc", preview=preview,
                       look_at=[",".join(f"{v:.4f}" for v in target) + "@0.5s"])
    assert not result.warnings, result.warnings
    assert (tmp_path / "gaze.usdc").exists()
    new = measure.posed(str(preview), rig.skeleton)
    looking = (new.times - rig.start_time) / RATE >= 1.3
    for eye in rig.eye_leaves:
        miss = measure.eye_miss_deg(new, eye, rig.forward, target)
        assert miss[looking].max() < 1.0, (eye, miss[looking].max())


def test_a_reference_turned_to_the_stages_up_shifts_the_gaze_about_the_stages_up(tmp_path):
    """The rotated reference's 30 deg shift to the character's left, measured about the stage's up
    (Y) by FK against the input's head, once it has settled (measured: 30.0000 deg, pitch 0.0000)."""
    rig, shot = _shot(tmp_path, "Z", "Y", rotate_x=-90.0)
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(shot), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc"),
                 "--preview", str(preview)]) == 0
    base, new = measure.posed(str(shot), rig.skeleton), measure.posed(str(preview), rig.skeleton)
    change, _, _ = measure.gaze_change(base, new, rig.forward, rig.leaf["head"], rig.eye_leaves)
    settled = (new.times - rig.start_time) / RATE >= 1.3
    assert np.abs(change[settled] - [30.0, 0.0]).max() < 0.5, change[settled]
