"""``plot``'s eye-in-head angles of a mirrored character (its SkelRoot scaled -1 in X, as a DCC mirrors
a crowd member): a yaw is toward the character's left as the world shows it, as ``apply`` takes a
request (README, "Mirrored characters"). The eye plot measured it toward the skeleton's left, so a
+30 deg gaze change showed the eyes at -25 deg. Read back from the figure the command saves, against
UsdSkel's FK with the world's left (up x forward) as the reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Vt

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn

EYES = ("mixamorig_LeftEye", "mixamorig_RightEye")


def _mirrored(folder: Path, mirrored: bool) -> Path:
    rig = syn.make_rig(folder / "in.usda", frames=48, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    if not mirrored:
        return rig.path
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    prim = layer.GetPrimAtPath(rig.skel_root)
    Sdf.AttributeSpec(prim, "xformOp:scale", Sdf.ValueTypeNames.Float3).default = Gf.Vec3f(-1, 1, 1)
    Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:scale"])
    layer.Save()
    return rig.path


def _world_left_yaw(composed: Path, skeleton: str) -> np.ndarray:
    """Each eye's yaw in the head (deg, + toward the head's left as the world shows it: the world images
    of its up and forward axes, crossed right-handedly) by UsdSkel."""
    p = measure.posed(str(composed), skeleton)
    fwd = measure.character_forward_skel(p, "mixamorig_LeftUpLeg", "mixamorig_RightUpLeg")
    up = np.linalg.solve(p.skel_to_world[:3, :3].T, p.up)
    head_fwd, head_up = (p.axis("mixamorig_Head", measure.local_forward(p, "mixamorig_Head", v)) for v in (fwd, up))
    left = np.cross(head_up, head_fwd)
    left /= np.linalg.norm(left, axis=-1, keepdims=True)
    out = []
    for eye in EYES:
        d = p.axis(eye, measure.local_forward(p, eye, fwd))
        out.append(np.degrees(np.arctan2((d * left).sum(-1), (d * head_fwd).sum(-1))))
    return np.stack(out, axis=1)


@pytest.mark.parametrize("mirrored", [True, False], ids=["mirrored", "as-built"])
def test_a_mirrored_characters_eye_yaw_is_toward_its_left_as_the_world_shows_it(tmp_path, monkeypatch, mirrored):
    from usdgaze.review import plotting

    src = _mirrored(tmp_path, mirrored)
    layer = tmp_path / "gaze.usdc"
    assert main(["apply", str(src), "--shift", "0.5s:30:0", "--out", str(layer)]) == 0
    drawn = {}
    save = plotting.save_figure

    def record(fig, path, outputs, dpi=100):
        drawn[Path(path).stem] = {line.get_label(): np.asarray(line.get_ydata(), dtype=float)
                                  for ax in fig.axes for line in ax.get_lines()}
        save(fig, path, outputs, dpi)

    monkeypatch.setattr(plotting, "save_figure", record)
    assert main(["plot", str(src), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0
    composed = Sdf.Layer.CreateNew(str(tmp_path / "composed.usda"))
    composed.timeCodesPerSecond = composed.framesPerSecond = 24
    composed.pseudoRoot.SetInfo("upAxis", "Y")
    composed.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    composed.subLayerPaths[:] = [str(layer), str(src)]
    composed.Save()
    want = _world_left_yaw(tmp_path / "composed.usda", "/Character/Skel")
    assert want[-1].min() > 15.0  # the eyes took part of the +30 deg turn to the left
    eyes = drawn["Character_eyes"]
    for k, side in enumerate(("left", "right")):
        assert np.abs(eyes[f"{side} eye yaw"] - want[:, k]).max() < 0.05, side
