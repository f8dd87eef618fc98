"""What ``attend`` reads as an object, and the one-line refusals of what it cannot read.

- A Mesh baked in world space (points far from its origin, no transform) is where its points are,
  as ``apply --look-at`` takes it: the centre of its world bounds, by UsdGeom, not its origin.
- GazeObjectAPI attributes of another type than the schema's (a string importance, a float3 radius)
  are one line naming the attribute, exit 2, in ``attend``; ``validate`` reports them as Type errors.
- An authored importance sample that is not > 0 is named with its time, in ``attend`` as in
  ``validate``, whatever times the planner samples.
- An inactive prim is not in the scene: ``--objects`` and ``--look-at`` refuse it.
- A physics obstacle's radius is more than 0 and at most 10 m; other objects' sizes are not bounded.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from usdgaze.console.main import main
from usdgaze.errors import UsdGazeError
from usdgaze.usd import objects

from .bad_common import rig


def _scene(tmp, build) -> Usd.Stage:
    stage = Usd.Stage.CreateNew(str(tmp / "scene.usda"))
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(120)
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    build(stage)
    stage.GetRootLayer().Save()
    return stage


def test_a_mesh_baked_in_world_space_is_where_its_points_are(tmp_path):
    def build(stage):
        mesh = UsdGeom.Mesh.Define(stage, "/Obj/Baked")
        pts = np.array([[0.5, 1.4, -0.4], [0.7, 1.4, -0.4], [0.6, 1.6, -0.2], [0.6, 1.5, -0.3]])
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
        mesh.CreateFaceVertexCountsAttr([3, 3])
        mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 0, 2, 3])
        mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(mesh.GetPointsAttr().Get()))
        UsdGeom.Sphere.Define(stage, "/Obj/Ball").AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))

    stage = _scene(tmp_path, build)
    codes = np.array([0.0, 60.0, 120.0])
    got = objects.read_objects(stage, "scene.usda", [stage.GetPrimAtPath("/Obj/Baked"),
                                                     stage.GetPrimAtPath("/Obj/Ball")], codes, 1.0)
    box = UsdGeom.Imageable(stage.GetPrimAtPath("/Obj/Baked")).ComputeWorldBound(
        Usd.TimeCode(0), UsdGeom.Tokens.default_).ComputeCentroid()
    assert np.abs(got[0].positions - np.array(box)).max() < 1e-6
    assert np.linalg.norm(got[0].positions[0]) > 1.5  # not the origin
    assert np.abs(got[1].positions - [1, 2, 3]).max() < 1e-12  # a centred sphere: its translation


def _rig_with_ball(tmp_path, edit):
    """The small synthetic rig with a Sphere /Obj/Ball in front of it, edited by ``edit(ball, layer)``."""
    r = rig(tmp_path, frames=60)
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    layer.Reload(force=True)
    stage = Usd.Stage.Open(layer)  # held: its prims expire with it
    ball = UsdGeom.Sphere.Define(stage, "/Obj/Ball")
    ball.AddTranslateOp().Set(Gf.Vec3d(0.5, 1.5, 1.0))
    edit(ball.GetPrim(), layer)
    layer.Save()
    return r


@pytest.mark.parametrize("name, type_name, value", [
    ("gaze:object:importance", Sdf.ValueTypeNames.String, "high"),
    ("gaze:object:importance", Sdf.ValueTypeNames.FloatArray, [1.0, 2.0]),
    ("gaze:object:radius", Sdf.ValueTypeNames.String, "big"),
    ("gaze:object:radius", Sdf.ValueTypeNames.Float3, Gf.Vec3f(1, 1, 1)),
    ("gaze:object:kind", Sdf.ValueTypeNames.Float, 2.0),
])
def test_an_object_attribute_of_the_wrong_type_is_one_line(tmp_path, capsys, name, type_name, value):
    def wrong_type(ball, layer):
        ball.AddAppliedSchema("GazeObjectAPI")
        # At the Sdf level: USD's own Set refuses a value of another type than the registered schema's.
        Sdf.AttributeSpec(layer.GetPrimAtPath("/Obj/Ball"), name, type_name).default = value

    r = _rig_with_ball(tmp_path, wrong_type)
    before = r.path.read_bytes()
    assert main(["attend", str(r.path), "--out", str(tmp_path / "out.usda")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"/Obj/Ball.{name}: is a {type_name}, expected a" in err[0], err
    assert not (tmp_path / "out.usda").exists() and r.path.read_bytes() == before
    assert main(["validate", str(r.path), "--only-usdgaze"]) == 3
    out = capsys.readouterr().out
    assert f"/Obj/Ball.{name}: error: {name}: is a {type_name}" in out and "GazeObject.Type" in out


def test_an_authored_importance_not_above_zero_is_named_with_its_time(tmp_path):
    def build(stage):
        ball = UsdGeom.Sphere.Define(stage, "/Obj/Ball")
        ball.AddTranslateOp().Set(Gf.Vec3d(0, 1.5, 2))
        attr = ball.GetPrim().CreateAttribute("gaze:object:importance", Sdf.ValueTypeNames.Float)
        for t, v in ((1.0, 1.0), (100.0, 0.0), (120.0, 1.0)):
            attr.Set(v, t)

    stage = _scene(tmp_path, build)
    # The planner's times miss time code 100; the authored zero is found all the same.
    with pytest.raises(UsdGazeError) as err:
        objects.read_objects(stage, "scene.usda", [stage.GetPrimAtPath("/Obj/Ball")], np.array([0.0, 50.0, 110.0]), 1.0)
    assert str(err.value) == "scene.usda:/Obj/Ball.gaze:object:importance: 0 at time 100, expected > 0"


def test_an_inactive_prim_is_not_an_object_nor_a_target(tmp_path, capsys):
    r = _rig_with_ball(tmp_path, lambda ball, layer: ball.SetActive(False))
    assert main(["attend", str(r.path), "--objects", "/Obj/Ball", "--out", str(tmp_path / "a.usda")]) == 2
    assert capsys.readouterr().err.strip().endswith("/Obj/Ball: is inactive (active = false), so it is not in the scene")
    assert main(["apply", str(r.path), "--look-at", "/Obj/Ball@0.2s", "--out", str(tmp_path / "b.usda")]) == 2
    assert "/Obj/Ball: is inactive (active = false)" in capsys.readouterr().err
    assert not (tmp_path / "a.usda").exists() and not (tmp_path / "b.usda").exists()


@pytest.mark.parametrize("task, radius, refused", [
    ("obstacle", 10.0, False), ("obstacle", 0.05, False), ("obstacle", 10.5, True), ("obstacle", float("nan"), True),
    ("obstacle", float("inf"), True), ("obstacle", -1.0, True),
    # Only an obstacle of the physics pass is bounded: a stone's or a plain object's size is not.
    ("stone", 1e6, False), (None, 1e6, False),
])
def test_an_obstacle_radius_is_a_body_a_person_walks_round(tmp_path, task, radius, refused):
    def build(stage):
        ball = UsdGeom.Sphere.Define(stage, "/Obj/Ball")
        ball.AddTranslateOp().Set(Gf.Vec3d(1, 0, 2))
        ball.GetPrim().CreateAttribute("gaze:object:radius", Sdf.ValueTypeNames.Float).Set(radius)
        if task:
            ball.GetPrim().CreateAttribute("usdgaze:physics:task", Sdf.ValueTypeNames.Token).Set(task)

    stage = _scene(tmp_path, build)
    read = lambda: objects.read_objects(stage, "scene.usda", [stage.GetPrimAtPath("/Obj/Ball")],  # noqa: E731
                                        np.array([0.0]), 1.0)
    if not refused:
        assert read()[0].radius == np.float32(radius)
        return
    with pytest.raises(UsdGazeError) as err:
        read()
    assert str(err.value).startswith("scene.usda:/Obj/Ball.gaze:object:radius: ") and "\n" not in str(err.value)


def test_a_skinned_mesh_is_not_an_object(tmp_path, capsys):
    """A mesh a Skeleton skins keeps its transform and its rest-pose bounds while the body moves: attend
    took it for an object standing still (apply --look-at refuses it the same way)."""
    r = rig(tmp_path, frames=24, mesh=True)
    stage = Usd.Stage.Open(str(r.path))
    assert stage.GetPrimAtPath(r.mesh).AddAppliedSchema("GazeObjectAPI")  # beside its SkelBindingAPI
    stage.GetRootLayer().Save()
    out = tmp_path / "a.usda"
    assert main(["attend", str(r.path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{r.mesh}: is (or holds) a skinned mesh" in err[0], err
    assert not out.exists()


def test_a_point_instancer_prototype_is_not_an_object(tmp_path, capsys):
    """A prototype is drawn only where the PointInstancer puts its instances: attend took one for an
    object at its own place, where nothing is drawn (apply --look-at refuses it the same way)."""
    r = rig(tmp_path, frames=24)
    stage = Usd.Stage.Open(str(r.path))
    instancer = UsdGeom.PointInstancer.Define(stage, "/Props")
    ball = UsdGeom.Sphere.Define(stage, "/Props/Prototypes/Ball")
    ball.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 0.0))
    assert ball.GetPrim().AddAppliedSchema("GazeObjectAPI")
    instancer.CreatePrototypesRel().SetTargets([ball.GetPath()])
    instancer.CreateProtoIndicesAttr([0])
    instancer.CreatePositionsAttr([Gf.Vec3f(0.5, 1.6, 2.0)])
    stage.GetRootLayer().Save()
    out = tmp_path / "a.usda"
    assert main(["attend", str(r.path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "/Props/Prototypes/Ball: is a prototype of the PointInstancer /Props" in err[0], err
    assert not out.exists()
