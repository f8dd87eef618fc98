"""The review guides' lines of sight are 3 mm wide in the world whatever the character's transform: a
metre character referenced into a centimetre shot and scaled 100x keeps thin lines, not 30 cm ones."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

from usdgaze import api

from .synthetic import make_rig


def _shot(tmp_path, meters_per_unit: float, scale: float):
    """A shot in ``meters_per_unit`` referencing a metre rig at /World/Hero, scaled by ``scale``."""
    make_rig(tmp_path / "hero.usda", frames=24)
    stage = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    stage.SetTimeCodesPerSecond(60)
    world = UsdGeom.Xform.Define(stage, "/World")
    hero = stage.DefinePrim("/World/Hero")
    hero.GetReferences().AddReference("./hero.usda")
    UsdGeom.Xformable(hero).AddScaleOp().Set(Gf.Vec3f(scale, scale, scale))
    stage.SetDefaultPrim(world.GetPrim())
    stage.Save()
    return tmp_path / "shot.usda"


@pytest.mark.parametrize("meters_per_unit, scale", [(1.0, 1.0), (0.01, 100.0), (1.0, 0.5)])
def test_lines_of_sight_are_3_mm_wide_in_the_world(tmp_path, meters_per_unit, scale):
    shot = _shot(tmp_path, meters_per_unit, scale)
    api.apply(shot, ["0.1s:20:0"], tmp_path / "gaze.usda", preview=tmp_path / "preview.usda")
    stage = Usd.Stage.Open(str(tmp_path / "preview.usda"))
    for name in ("leftEyeSight", "rightEyeSight"):
        curve = UsdGeom.BasisCurves(stage.GetPrimAtPath(f"/World/Hero/Skel/gazeGuides/{name}"))
        xf = np.array(curve.ComputeLocalToWorldTransform(Usd.TimeCode(10)))
        world_scale = abs(np.linalg.det(xf[:3, :3])) ** (1 / 3)
        width_m = curve.GetWidthsAttr().Get()[0] * world_scale * meters_per_unit
        assert width_m == pytest.approx(0.003, rel=1e-4)


def test_guide_extent_holds_the_drawn_line(tmp_path):
    """Each frame's authored extent is what UsdGeom computes from that frame's points and widths (a
    bound that leaves out half the line's width clips it in a viewer's culling)."""
    shot = _shot(tmp_path, 0.01, 100.0)
    api.apply(shot, ["0.1s:20:0"], tmp_path / "gaze.usda", preview=tmp_path / "preview.usda")
    stage = Usd.Stage.Open(str(tmp_path / "preview.usda"))
    curve = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hero/Skel/gazeGuides/leftEyeSight"))
    widths = curve.GetWidthsAttr().Get()
    times = curve.GetPointsAttr().GetTimeSamples()
    assert len(times) == 24
    for t in times:
        want = np.array(UsdGeom.Curves.ComputeExtent(curve.GetPointsAttr().Get(t), widths))
        got = np.array(curve.GetExtentAttr().Get(t))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.abs(want).max())
