"""Object positions read from the translate op's time samples at the Sdf level equal USD's own
per-time answer (UsdGeom ComputeLocalToWorldTransform), through layer offsets, still parents, held
interpolation and times between and beyond the samples; other transforms take the per-time path.
An animated mesh is at the centre of its world bounds (UsdGeom.BBoxCache) at every time."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from usdgaze.usd import object_positions, objects


def _usd_positions(stage, path, codes):
    xf = UsdGeom.Xformable(stage.GetPrimAtPath(path))
    return np.array([np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(float(t))))[3, :3] for t in codes])


def _stage(tmp, animated_parent=False, two_ops=False, held=False):
    inner = Sdf.Layer.CreateNew(str(tmp / "inner.usda"))
    for path, type_name in (("/World", "Xform"), ("/World/Ball", "Sphere"), ("/World/Still", "Sphere")):
        spec = Sdf.CreatePrimInLayer(inner, path)
        spec.specifier, spec.typeName = Sdf.SpecifierDef, type_name
    ball = inner.GetPrimAtPath("/World/Ball")
    tr = Sdf.AttributeSpec(ball, "xformOp:translate", Sdf.ValueTypeNames.Float3)
    for i, t in enumerate((0.0, 3.0, 4.0, 10.0)):
        inner.SetTimeSample(tr.path, t, Gf.Vec3f(i * 1.5, np.sin(i), -i * i))
    order = ["xformOp:translate"]
    if two_ops:
        Sdf.AttributeSpec(ball, "xformOp:rotateY", Sdf.ValueTypeNames.Float).default = 30.0
        order.append("xformOp:rotateY")
    Sdf.AttributeSpec(ball, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = order
    imp = Sdf.AttributeSpec(ball, "gaze:object:importance", Sdf.ValueTypeNames.Double)
    inner.SetTimeSample(imp.path, 2.0, 1.0)
    inner.SetTimeSample(imp.path, 6.0, 3.0)
    still = inner.GetPrimAtPath("/World/Still")
    Sdf.AttributeSpec(still, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(1, 2, 3)
    Sdf.AttributeSpec(still, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    inner.Save()
    root = Sdf.Layer.CreateNew(str(tmp / "root.usda"))
    root.subLayerPaths.append(inner.identifier)
    root.subLayerOffsets[0] = Sdf.LayerOffset(offset=5.0, scale=2.0)
    world = Sdf.CreatePrimInLayer(root, "/World")
    world.specifier = Sdf.SpecifierOver
    rot = Sdf.AttributeSpec(world, "xformOp:rotateXYZ", Sdf.ValueTypeNames.Float3)
    if animated_parent:
        root.SetTimeSample(rot.path, 5.0, Gf.Vec3f(0, 0, 0))
        root.SetTimeSample(rot.path, 25.0, Gf.Vec3f(0, 90, 0))
    else:
        rot.default = Gf.Vec3f(10, 40, -20)
    Sdf.AttributeSpec(world, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(0.5, 1, -2)
    Sdf.AttributeSpec(world, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate", "xformOp:rotateXYZ"]
    root.Save()
    stage = Usd.Stage.Open(root.identifier)
    if held:
        stage.SetInterpolationType(Usd.InterpolationTypeHeld)
    return stage


CODES = np.arange(0.0, 30.0, 0.37)  # before, between, on and after the (offset) samples 5, 11, 13, 25


@pytest.mark.parametrize("case", ["fast", "held", "animated_parent", "two_ops"])
def test_positions_equal_usds_own_answer(tmp_path, case):
    stage = _stage(tmp_path, animated_parent=case == "animated_parent", two_ops=case == "two_ops", held=case == "held")
    prims = [stage.GetPrimAtPath(p) for p in ("/World/Ball", "/World/Still")]
    fast = object_positions.fast_positions(prims[0], CODES)
    assert (fast is not None) == (case in ("fast", "held"))
    got = objects.read_objects(stage, "x.usda", prims, CODES, 0.01)
    for obj, path in zip(got, ("/World/Ball", "/World/Still")):
        want = _usd_positions(stage, path, CODES) * 0.01
        assert np.abs(obj.positions - want).max() < 1e-6, (case, path)
    attr = prims[0].GetAttribute("gaze:object:importance")
    want = np.array([attr.Get(Usd.TimeCode(float(t))) for t in CODES])
    assert np.abs(got[0].importance - want).max() < 1e-12
    assert np.ptp(got[0].positions, 0).min() > 0.005 # the ball moves on every axis: the check can fail


def test_a_blocked_translate_sample_reads_as_usd_does(tmp_path):
    """A blocked time sample (``Sdf.ValueBlock``) leaves the op out at its times, as USD says; the Sdf
    read took it for a number and attend stopped with an internal error (exit 1)."""
    stage = _stage(tmp_path)
    inner = Sdf.Layer.FindOrOpen(str(tmp_path / "inner.usda"))
    inner.SetTimeSample(Sdf.Path("/World/Ball.xformOp:translate"), 3.0, Sdf.ValueBlock())
    prim = stage.GetPrimAtPath("/World/Ball")
    got = objects.read_objects(stage, "x.usda", [prim], CODES, 1.0)[0].positions
    want = _usd_positions(stage, "/World/Ball", CODES)
    assert np.abs(got - want).max() < 1e-6
    assert np.ptp(want, 0).max() > 1.0  # the ball moves: the comparison can fail


@pytest.mark.parametrize("extent", [False, True])
def test_an_animated_mesh_is_at_its_bounds_centre_at_every_time(tmp_path, extent):
    """Baked points centred on the mesh's origin at the first frame, then flying off it: whether the
    mesh was off-centre was decided once, at the first time, and it was read at its origin for the
    whole shot (2.7 m off at the end here). Measured against UsdGeom.BBoxCache's world bounds per time,
    under a turned, moved parent and the mesh's own translate."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "mesh.usda"))
    parent = UsdGeom.Xform.Define(stage, "/World")
    parent.AddTranslateOp().Set(Gf.Vec3d(0.5, 0.0, -1.0))
    parent.AddRotateYOp().Set(30.0)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Baked")
    mesh.AddTranslateOp().Set(Gf.Vec3d(0.0, 1.0, 0.0))
    mesh.CreateFaceVertexCountsAttr([4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 4, 5, 6, 7])
    corners = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (-0.1, 0.1)])
    for f in range(1, 73):
        s = (f - 1) / 24.0
        pts = corners + [0.6 * s, 0.6 * s, 0.8 * s]  # centred on the origin at frame 1 only
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)), f)
        if extent:
            mesh.GetExtentAttr().Set(UsdGeom.Boundable.ComputeExtentFromPlugins(mesh, Usd.TimeCode(f)), f)
    codes = np.arange(1.0, 72.0, 0.7)
    got = objects.read_objects(stage, "mesh.usda", [mesh.GetPrim()], codes, 1.0)[0].positions
    want = np.array([UsdGeom.BBoxCache(Usd.TimeCode(float(t)), [UsdGeom.Tokens.default_], useExtentsHint=True)
                     .ComputeWorldBound(mesh.GetPrim()).ComputeCentroid() for t in codes])
    assert np.abs(got - want).max() < 1e-5
    assert np.linalg.norm(want[-1] - want[0]) > 2.0  # it flies: reading it still would fail
