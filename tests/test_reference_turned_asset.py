"""An asset whose own root prim turns its data to its upAxis, referenced into a stage of the other axis.

Blender's USD export (the shipped CMU clips) writes upAxis Y and turns its Z-up data onto Y with
``rotateXYZ = (-90, 0, 0)`` on the root prim. Referenced into a Z-up, centimetre stage under a prim
turned +90 deg about X and scaled 100 (the turn the refusal asks for), the character stands up along
Z (measured by UsdSkel FK below). That turn is the arc's; the asset's own -90 is not: counted with it,
the shot was refused as "90 deg off Z", and a reference turned +90 whose own xformOpOrder drops the
asset's turn (the character lying along -Y) was taken. Measured on ``ball_throw.usda`` turned into such a stage,
by FK on the written layer: the eyes within 0.06-2.7 deg of the ball over frames 2-40 of its flight,
as in the Y-up stage (0.01-2.3 deg).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main
from usdgaze.review.validation import run as validate

from . import attend_support as A
from . import measure

BALL_THROW = A.ATTEND / "ball_throw.usda"
SKEL = "/World/root/Body/BodySkel"


def _shot_layer(tmp_path, up: str, meters_per_unit: float) -> Sdf.Layer:
    """A new ``shot.usda`` with ball_throw's time range and rates, in the given up axis and unit."""
    src = Sdf.Layer.FindOrOpen(str(BALL_THROW))
    layer = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(layer, key, getattr(src, key))
    layer.pseudoRoot.SetInfo("upAxis", up)
    layer.pseudoRoot.SetInfo("metersPerUnit", meters_per_unit)
    return layer


def _z_up_cm(tmp_path, world_turn: float = 90.0, own_turn: float | None = None):
    """``shot.usda`` (Z up, metersPerUnit 0.01): /World turned ``world_turn`` deg about X and scaled 100,
    with ball_throw's character and ball referenced under it. ``own_turn``: the referencing /World/root
    authors its own xformOpOrder [rotateX own_turn], dropping the asset's -90."""
    layer = _shot_layer(tmp_path, "Z", 0.01)
    stage = Usd.Stage.Open(layer)
    world = UsdGeom.Xform.Define(stage, "/World")
    world.AddRotateXOp().Set(world_turn)
    world.AddScaleOp().Set((100.0, 100.0, 100.0))
    stage.DefinePrim("/World/root").GetReferences().AddReference(str(BALL_THROW), "/root")
    stage.DefinePrim("/World/Objects").GetReferences().AddReference(str(BALL_THROW), "/Objects")
    if own_turn is not None:
        UsdGeom.Xformable(stage.GetPrimAtPath("/World/root")).ClearXformOpOrder()
        UsdGeom.Xformable(stage.GetPrimAtPath("/World/root")).AddRotateXOp(opSuffix="turn").Set(own_turn)
    layer.Save()
    return tmp_path / "shot.usda"


def _up_along_z(shot) -> float:
    """Degrees between +Z and the character's hips-to-head line at its first frame, by UsdSkel FK."""
    p = measure.posed(str(shot), SKEL)
    rise = p.position("Head")[0] - 0.5 * (p.position("LeftHip")[0] + p.position("RightHip")[0])
    return float(np.degrees(np.arccos(rise[2] / np.linalg.norm(rise))))


def test_an_asset_turned_by_its_own_root_and_by_the_arc_onto_z_is_taken_and_looks_at_the_ball(tmp_path):
    shot = _z_up_cm(tmp_path)
    assert _up_along_z(shot) < 15.0  # it stands: the arc's turn is right
    out = tmp_path / "gaze.usdc"
    assert main(["attend", str(shot), "--out", str(out), "--seed", "0"]) == 0
    g = A.gaze(A.compose(tmp_path, shot, out), SKEL)
    off = A.angle_to(g, A.positions(g.stage, "/World/Objects/Ball", g.times))
    assert off[1:41].max() < 5.0, off[1:41]


def test_a_reference_that_drops_the_assets_own_turn_is_refused(tmp_path, capsys):
    # The skeleton's world turns +90 about X, Y onto Z, as before; but the +90 replaced the asset's -90
    # instead of adding to it, so the Z-up data lies along -Y.
    shot = _z_up_cm(tmp_path, world_turn=0.0, own_turn=90.0)
    assert _up_along_z(shot) > 60.0
    capsys.readouterr()
    assert main(["attend", str(shot), "--out", str(tmp_path / "gaze.usdc")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "which says upAxis Y, but the stage's up is Z" in err[0], err
    assert not (tmp_path / "gaze.usdc").exists()


def test_a_centimetre_asset_scaling_its_metre_data_on_its_own_root_is_taken_at_its_size(tmp_path):
    """The unit check reads the same way: an asset in centimetres (metersPerUnit 0.01, sublayering
    ball_throw) whose root prim scales the CMU clip's metre data by 100, referenced into a metre stage
    under a prim scaled 0.01, is a character of its own size (measured by FK below). The check took the
    asset's own scale as the arc's, read the reference as unscaled and refused it as "100 times too small"."""
    asset = Sdf.Layer.CreateNew(str(tmp_path / "asset_cm.usda"))
    asset.pseudoRoot.SetInfo("upAxis", "Y")
    asset.pseudoRoot.SetInfo("metersPerUnit", 0.01)
    asset.subLayerPaths[:] = [str(BALL_THROW)]
    stage = Usd.Stage.Open(asset)
    root = UsdGeom.Xformable(stage.GetPrimAtPath("/root"))
    root.AddScaleOp().Set((100.0, 100.0, 100.0))  # after its own rotateXYZ, in its xformOpOrder
    asset.Save()
    layer = _shot_layer(tmp_path, "Y", 1.0)
    stage = Usd.Stage.Open(layer)
    UsdGeom.Xform.Define(stage, "/World").AddScaleOp().Set((0.01, 0.01, 0.01))
    stage.DefinePrim("/World/root").GetReferences().AddReference(str(tmp_path / "asset_cm.usda"), "/root")
    layer.Save()
    p = measure.posed(str(tmp_path / "shot.usda"), SKEL)
    height = p.position("Head")[0][1] - min(p.position("LeftAnkle")[0][1], p.position("RightAnkle")[0][1])
    assert 1.2 < height < 2.0, height  # metres, in a metre stage: the character's own size
    problems = [q for q in validate(tmp_path / "shot.usda", only_usdgaze=True) if q["validator"].endswith("SkeletonUnits")]
    assert problems == [], problems
    assert main(["inspect", str(tmp_path / "shot.usda")]) == 0
