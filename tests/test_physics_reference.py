"""A reference whose stance feet slide (a procedural or keyframed walk that skates) cannot be followed
by a body on its soles: ``attend --physics`` says so per shot, and says nothing on real capture.

Whether a reference skates is measured here by UsdSkel FK of its toe joints, apart from the model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, UsdGeom, Usd

from usdgaze.console.main import main
from usdgaze.physics import build, feasible, retarget
from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.tracking import resample

from . import measure
from . import synthetic as syn

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"
H = 0.02


def _stance_speed_by_fk(path: Path, skeleton: str, toes: tuple[str, str]) -> float:
    """Median ground-plane speed (m/s) of the lower toe joint over the frames it is within 3 cm of its
    lowest height, by UsdSkel FK of the stage."""
    p = measure.posed(str(path), skeleton)
    stage = Usd.Stage.Open(str(path))
    metres = UsdGeom.GetStageMetersPerUnit(stage)
    seconds = p.times / stage.GetTimeCodesPerSecond()
    pos = np.stack([p.position(t) for t in toes], axis=1) * metres  # (F, 2, 3)
    height = pos @ p.up
    flat = pos - height[..., None] * p.up
    speed = np.linalg.norm(np.gradient(flat, seconds, axis=0), axis=-1)
    lower = np.argmin(height, axis=1)
    k = np.arange(len(pos))
    down = height[k, lower] < height.min() + 0.03
    return float(np.median(speed[k, lower][down]))


def _note(path: Path) -> str | None:
    stage = Usd.Stage.Open(str(path))
    from usdgaze.characters import bind_root, select_roots
    from usdgaze.usd.skelio import read_clip, skeletons_under

    root = select_roots(stage, str(path), None)[0]
    clip = read_clip(stage, skeletons_under(root)[0], root, str(path))
    model, ref = build.body_model(clip, chain_frame=bind_root(clip, root, None))
    dyn = MujocoBody(model, h=H)
    return feasible.sliding_stance(feasible.toe_paths(dyn, resample(retarget.to_qpos(model, ref), clip.seconds, H, dyn)), H)


def test_real_capture_is_not_said_to_slide():
    assert _stance_speed_by_fk(CMU, "/root/Body/BodySkel", ("LeftToe", "RightToe")) < 0.2
    assert _note(CMU) is None


def test_a_skating_walk_is_said_to_slide(tmp_path):
    rig = syn.make_rig(tmp_path / "skate.usda", frames=60, time_codes_per_second=60, mesh=False)
    assert _stance_speed_by_fk(rig.path, "/Character/Skel", ("mixamorig_LeftToeBase", "mixamorig_RightToeBase")) > 0.8
    note = _note(rig.path)
    assert note is not None and note.startswith("the reference's feet slide")


@pytest.mark.parametrize("glide, said", [(0.0, False), (0.05, False), (1.3, True)])
def test_planted_feet_are_not_sliding_and_gliding_ones_are(glide, said):
    """Two toes stepping in turn (each planted for half a 1 s cycle, swinging 15 cm up for the other
    half), the whole pattern carried along at ``glide`` m/s."""
    t = H * np.arange(150)
    toes = np.zeros((len(t), 2, 3))
    for f, phase in enumerate((0.0, 0.5)):
        cycle = (t + phase) % 1.0
        swing = cycle >= 0.5
        step = np.floor(t + phase) * 1.2 + np.where(swing, 1.2 * (cycle - 0.5) / 0.5, 0.0)  # 1.2 m a stride
        toes[:, f, 0] = step * (glide == 0.0) + glide * t
        toes[:, f, 1] = 0.1 * (1 - 2 * f)
        toes[:, f, 2] = 0.03 + 0.15 * np.sin(np.pi * np.clip((cycle - 0.5) / 0.5, 0, 1)) * swing
    assert (feasible.sliding_stance(toes, H) is not None) == said


def test_attend_physics_says_a_sliding_reference_and_records_it(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "skate.usda", frames=13, time_codes_per_second=60, mesh=False)
    out = tmp_path / "sim.usda"
    assert main(["attend", str(rig.path), "--out", str(out), "--physics", "--window", "0.3"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("/Character/Skel:"))
    assert "the reference's feet slide" in line
    shot = Sdf.Layer.FindOrOpen(str(out)).customLayerData["usdgaze:physics"]["/Character/Skel"]
    assert shot["referenceNotes"][0].startswith("the reference's feet slide")
    assert not any("slide" in p for p in shot["problems"])  # said, not a problem of the simulation


def test_animated_joint_scales_are_said_still_ones_are_not():
    """The physics body is built at rest proportions and the layer keeps the input's scales: a thigh
    scaled over the shot (1 -> 1.5) plays back a body that was never simulated, so the shot says so;
    scales that are constant over the shot (any value, float16 as UsdSkel stores them) are not said."""
    frames, joints = 30, ["Hips", "Hips/LeftUpLeg", "Hips/RightUpLeg"]
    still = np.ones((frames, 3, 3), dtype=np.float16) * np.float16(0.93)
    assert feasible.scale_notes(still, joints) == []
    grown = still.copy()
    grown[:, 1, 1] = np.linspace(1.0, 1.5, frames).astype(np.float16)
    (note,) = feasible.scale_notes(grown, joints)
    assert "LeftUpLeg" in note and "RightUpLeg" not in note
