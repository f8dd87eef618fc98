"""What ``attend`` reads as an object, and the one-line refusals of what it cannot read.

- A Mesh baked in world space (points far from its origin, no transform) is where its points are,
  as ``apply --look-at`` takes it: the centre of its world bounds, by UsdGeom, not its origin.
- GazeObjectAPI attributes of another type than the schema's (a string importance, a float3 radius)
  are one line naming the attribute, exit 2, in ``attend``; ``validate`` reports them as Type errors.
- An authored importance sample that is not > 0 is named with its time, in ``attend`` as in
  ``validate``, whatever times the planner samples.
- An inactive prim is not in the scene: ``--objects`` and ``--look-at`` refuse it.
- A physics obstacle's radius is more than 0 and at most 10 m; other objects' sizes are not bounded.
- A transform USD cannot evaluate (an op of the wrong type, an unknown op, a named op that is not
  there), on the object or a parent, in ``attend`` or on a ``--physics`` stone, is one line naming the
  prim and attribute, exit 2 (an internal error, exit 1, before).
- ``apply --look-at`` refuses the same transforms of its target prim in the same line (an internal
  error, exit 1, or a look at the world's origin, exit 0, before); an xformOpOrder authored as a token
  or a string (USD orders no op by it) is named as such (its letters were read as op names).
- An instancing prototype's prim, an abstract class prim and the character's own Skeleton are not
  objects (one line each); an instance's prim (an instance proxy) is.
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


@pytest.mark.parametrize("positions, said", [
    ([Gf.Vec3f(1.2, 1.6, 2.0), Gf.Vec3f(-1.2, 1.6, 2.0)], True),
    ([Gf.Vec3f(0.5, 1.6, 2.0)], False),  # one instance: the centre of its bounds is where it is
])
def test_a_point_instancer_of_several_instances_is_said_to_be_one_object(tmp_path, capsys, positions, said):
    """A PointInstancer drawing two balls 2.4 m apart was one object at the centre of their bounds: the eyes
    held the empty midpoint (within 5 deg on 98% of an audit's frames, 32 deg off each ball), without a
    word. A swarm's centre may be meant, so attend and apply --look-at say it in one warning line."""
    r = rig(tmp_path, frames=24)
    stage = Usd.Stage.Open(str(r.path))
    instancer = UsdGeom.PointInstancer.Define(stage, "/Props")
    ball = UsdGeom.Sphere.Define(stage, "/Props/Prototypes/Ball")
    assert instancer.GetPrim().AddAppliedSchema("GazeObjectAPI")
    instancer.CreatePrototypesRel().SetTargets([ball.GetPath()])
    instancer.CreateProtoIndicesAttr([0] * len(positions))
    instancer.CreatePositionsAttr(positions)
    stage.GetRootLayer().Save()
    for argv in (["attend", str(r.path), "--out", str(tmp_path / "a.usda")],
                 ["apply", str(r.path), "--look-at", "/Props@0.2s", "--out", str(tmp_path / "b.usda")]):
        capsys.readouterr()
        assert main(argv) == 0
        lines = [l for l in capsys.readouterr().err.splitlines() if "PointInstancer" in l]
        want = f"{r.path}:/Props: a PointInstancer drawing 2 instances is one object, looked at in the centre"
        assert lines == ([f"usdgaze: warning: {want} of their bounds, where none of them may be; to look at each, "
                          "give each a prim of its own"] if said else []), lines


_N = Sdf.ValueTypeNames


def _retyped(prim_type: str, name: str, type_name, value, sampled: bool = False, on: str = "/Obj/Ball"):
    """An edit for ``_rig_with_ball``: the object a ``prim_type`` whose xformOpOrder is ``[name]``, that op
    authored at the Sdf level (USD's own Set refuses a value of another type) on the prim ``on``."""
    def edit(ball, layer):
        ball.AddAppliedSchema("GazeObjectAPI")
        ball.SetTypeName(prim_type)
        spec = layer.GetPrimAtPath(on)
        if on != "/Obj/Ball":  # a parent: made transformable (Define made it a typeless def)
            spec.typeName = "Xform"
        for old in ("xformOp:translate", "xformOpOrder"):
            if old in spec.properties:
                spec.RemoveProperty(spec.properties[old])
        Sdf.AttributeSpec(spec, "xformOpOrder", _N.TokenArray, variability=Sdf.VariabilityUniform).default = [name]
        if type_name is None:  # the op named but never authored
            return
        attr = Sdf.AttributeSpec(spec, name, type_name)
        for t in (0.0, 30.0) if sampled else ():
            layer.SetTimeSample(attr.path, t, value)
        if not sampled:
            attr.default = value
    return edit


def _order_typed(type_name, value):
    """An edit for ``_rig_with_ball``: the object's xformOpOrder authored as ``type_name`` (not token[]):
    USD orders no op by it and reads the prim at identity, the world's origin."""
    def edit(ball, layer):
        ball.AddAppliedSchema("GazeObjectAPI")
        spec = layer.GetPrimAtPath("/Obj/Ball")
        spec.RemoveProperty(spec.properties["xformOpOrder"])
        Sdf.AttributeSpec(spec, "xformOpOrder", type_name, variability=Sdf.VariabilityUniform).default = value
    return edit


_UNEVALUABLE = [
    (_retyped("Sphere", "xformOp:translate", _N.Double, 1.0), "/Obj/Ball.xformOp:translate: is a double, expected"),
    (_retyped("Xform", "xformOp:foo", _N.Double3, Gf.Vec3d(0, 1, 2)), "/Obj/Ball.xformOpOrder: 'xformOp:foo' is no "),
    (_retyped("Sphere", "xformOp:translate", _N.Double3Array, [Gf.Vec3d(0, 1.6, 2)]), "is a double3[], expected"),
    (_retyped("Sphere", "xformOp:translate", None, None), "/Obj/Ball.xformOpOrder: names xformOp:translate, which"),
    (_order_typed(_N.Token, "xformOp:translate"), "/Obj/Ball.xformOpOrder: is a token, expected a token[]"),
    (_retyped("Sphere", "xformOp:scale", _N.Double, 2.0, on="/Obj"), "/Obj.xformOp:scale: is a double"),
]


@pytest.mark.parametrize("edit, want", _UNEVALUABLE)
def test_a_look_at_target_whose_transform_usd_cannot_evaluate_is_one_line(tmp_path, capsys, edit, want):
    """``apply --look-at PRIM`` read the target without attend's transform checks: an op of the wrong
    type or an unknown op stopped it with USD's internal error (exit 1), and an op USD skips (named but
    not authored, or an xformOpOrder authored as a token, whose letters attend read as op names) was
    looked at at the world's origin, exit 0."""
    r = _rig_with_ball(tmp_path, edit)
    before = r.path.read_bytes()
    out = tmp_path / "out.usda"
    assert main(["apply", str(r.path), "--look-at", "/Obj/Ball@0.5s", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and want in err[0] and "internal error" not in err[0], err
    assert not out.exists() and r.path.read_bytes() == before


@pytest.mark.parametrize("edit, physics, want", [
    (_order_typed(_N.Token, "xformOp:translate"), False, "/Obj/Ball.xformOpOrder: is a token, expected a token[]"),
    (_order_typed(_N.String, "xformOp:translate"), False, "/Obj/Ball.xformOpOrder: is a string, expected a token[]"),
    (_retyped("Sphere", "xformOp:translate", _N.Double, 1.0), False,
     "/Obj/Ball.xformOp:translate: is a double, expected a float3, double3 or half3 (a translate op)"),
    (_retyped("Sphere", "xformOp:translate", _N.Double, 1.0, sampled=True), False, "xformOp:translate: is a double,"),
    (_retyped("Sphere", "xformOp:translate", _N.Double4, Gf.Vec4d(0, 1.6, 2, 1)), False, "is a double4, expected"),
    (_retyped("Sphere", "xformOp:translate", _N.Double3Array, [Gf.Vec3d(0, 1.6, 2)]), False,
     "is a double3[], expected"),
    (_retyped("Xform", "xformOp:translate", _N.String, "a"), False, "is a string, expected"),
    (_retyped("Xform", "xformOp:translate", _N.Double2, Gf.Vec2d(1, 2), sampled=True), False, "is a double2, expected"),
    (_retyped("Xform", "xformOp:rotateY", _N.Double3, Gf.Vec3d(0, 90, 0)), False,
     "/Obj/Ball.xformOp:rotateY: is a double3, expected a float, double or half (a rotateY op)"),
    (_retyped("Xform", "xformOp:foo", _N.Double3, Gf.Vec3d(0, 1, 2)), False,
     "/Obj/Ball.xformOpOrder: 'xformOp:foo' is no transform op USD evaluates (Invalid xform opType token 'foo'.)"),
    (_retyped("Sphere", "xformOp:translate", None, None), False,
     "/Obj/Ball.xformOpOrder: names xformOp:translate, which the prim does not have"),
    # A parent's op: USD evaluates it for the object's world transform.
    (_retyped("Sphere", "xformOp:scale", _N.Double, 2.0, on="/Obj"), False, "/Obj.xformOp:scale: is a double"),
    # The physics pass reads its stones through the same reader.
    (_retyped("Sphere", "xformOp:translate", _N.Double, 1.0), True, "/Obj/Ball.xformOp:translate: is a double,"),
])
def test_a_transform_usd_cannot_evaluate_is_one_line(tmp_path, capsys, edit, physics, want):
    """A wrongly typed or unknown transform op stopped attend with an internal error (exit 1: numpy's
    ValueError, USD's Tf.ErrorException); a double3[] translate was read as its first element."""
    def stone(ball, layer):
        edit(ball, layer)
        if physics:  # a stone only, read by the physics pass's task reader
            ball.RemoveAppliedSchema("GazeObjectAPI")
            ball.CreateAttribute("usdgaze:physics:task", _N.Token).Set("stone")

    r = _rig_with_ball(tmp_path, stone)
    before = r.path.read_bytes()
    out = tmp_path / "out.usda"
    assert main(["attend", str(r.path), "--out", str(out)] + (["--physics"] if physics else [])) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and want in err[0] and "internal error" not in err[0], err
    assert not out.exists() and r.path.read_bytes() == before
    if not physics:  # validate says what attend refuses (it said nothing of a translate authored as a double)
        assert main(["validate", str(r.path), "--only-usdgaze"]) == 3
        said = capsys.readouterr().out
        site, _, problem = want.rpartition(".xformOp")
        line = next(l for l in said.splitlines() if "GazeObject.Transform" in l)
        assert (f"xformOp{problem}" if site else want) in line and f"{site}.xformOp" in line, said


def _instanced(ball, layer):
    """A class prim /Proto holding a Ball, and an instanceable /Props/A referencing it."""
    proto = Sdf.CreatePrimInLayer(layer, "/Proto")
    proto.specifier, proto.typeName = Sdf.SpecifierClass, "Xform"
    Sdf.CopySpec(layer, "/Obj/Ball", layer, "/Proto/Ball")
    prop = Sdf.CreatePrimInLayer(layer, "/Props/A")
    layer.GetPrimAtPath("/Props").specifier = Sdf.SpecifierDef
    prop.specifier, prop.typeName, prop.instanceable = Sdf.SpecifierDef, "Xform", True
    prop.referenceList.Prepend(Sdf.Reference("", "/Proto"))


@pytest.mark.parametrize("case", ["prototype", "class", "own skeleton", "instance proxy"])
def test_an_object_drawn_nowhere_or_on_the_character_is_one_line(tmp_path, capsys, case):
    """An instancing prototype's prim, an abstract class prim and the character's own Skeleton were
    accepted as objects (exit 0): the first two are drawn nowhere at their own place, the third moves
    with the eyes that look. The instance's own prim (an instance proxy) is drawn, and is an object."""
    r = _rig_with_ball(tmp_path, _instanced)
    stage = Usd.Stage.Open(str(r.path))
    proto = stage.GetPrimAtPath("/Props/A").GetPrototype().GetPath()  # named by USD: /__Prototype_1
    path, want = {"prototype": (f"{proto}/Ball", f"{proto}/Ball: lies in the instancing prototype {proto}, drawn only "
                                "as the prims of its instances, such as /Props/A/Ball; make one of those the object"),
                  "class": ("/Proto/Ball", "/Proto/Ball: is an abstract class prim (or lies under one)"),
                  "own skeleton": (r.skeleton, f"{r.skeleton}: lies inside the character {r.skel_root}; an object"),
                  "instance proxy": ("/Props/A/Ball", None)}[case]
    out = tmp_path / "out.usda"
    code = main(["attend", str(r.path), "--objects", path, "--out", str(out), "--window", "0.3"])
    err = capsys.readouterr().err.strip().splitlines()
    if want is None:
        assert code == 0 and out.exists(), err
        return
    assert code == 2 and len(err) == 1 and want in err[0], err
    assert not out.exists()
    if case != "own skeleton":  # a look-at target is refused the same way
        assert main(["apply", str(r.path), "--look-at", f"{path}@0.2s", "--out", str(out)]) == 2
        assert path in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("command", [["attend"], ["apply", "--shift", "0.5s:20:0"]])
@pytest.mark.parametrize("name, type_name, value, want", [
    ("xformOp:translate", _N.Double, 1.0, ".xformOp:translate: is a double, expected a float3"),
    ("xformOp:foo", _N.Double3, Gf.Vec3d(0, 1, 2), ".xformOpOrder: 'xformOp:foo' is no transform op USD evaluates"),
    ("xformOpOrder", _N.Token, "xformOp:translate", ".xformOpOrder: is a token, expected a token[]"),
])
def test_a_character_whose_transform_usd_cannot_evaluate_is_one_line(tmp_path, capsys, command, name, type_name,
                                                                      value, want):
    """The same transforms on the character's SkelRoot (above its Skeleton): apply and attend stopped with
    USD's internal error (exit 1) on a translate authored as a double or an unknown op, and took an
    xformOpOrder authored as a token (USD then drops the SkelRoot's ops)."""
    r = _rig_with_ball(tmp_path, lambda ball, layer: ball.AddAppliedSchema("GazeObjectAPI"))
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    spec = layer.GetPrimAtPath(r.skel_root)
    for old in ("xformOpOrder", name):
        if old in spec.properties:
            spec.RemoveProperty(spec.properties[old])
    order = Sdf.AttributeSpec(spec, "xformOpOrder", type_name if name == "xformOpOrder" else _N.TokenArray,
                              variability=Sdf.VariabilityUniform)
    order.default = value if name == "xformOpOrder" else [name]
    if name != "xformOpOrder":
        Sdf.AttributeSpec(spec, name, type_name).default = value
    layer.Save()
    before = r.path.read_bytes()
    out = tmp_path / "out.usda"
    assert main([command[0], str(r.path), "--out", str(out), *command[1:]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{r.skel_root}{want}" in err[0] and "internal error" not in err[0], err
    assert not out.exists() and r.path.read_bytes() == before
    if command == ["attend"]:  # validate says so of the Skeleton (it said nothing)
        assert main(["validate", str(r.path), "--only-usdgaze"]) == 3
        said = capsys.readouterr().out
        line = next(l for l in said.splitlines() if "SkeletonArrays.Transform" in l)
        assert want.split(": ", 1)[1] in line and f"{r.skel_root}.{want[1:].split(':', 1)[0]}" in line, said


def test_an_object_named_by_a_property_path_is_said_so(tmp_path, capsys):
    """``--objects /Obj/Ball.radius`` (a property, copied from an attribute's path) was 'no such prim'."""
    r = _rig_with_ball(tmp_path, lambda ball, layer: None)
    out = tmp_path / "a.usda"
    assert main(["attend", str(r.path), "--objects", "/Obj/Ball.radius", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'/Obj/Ball.radius' names a property; give its prim, /Obj/Ball" in err[0], err
    assert not out.exists()
