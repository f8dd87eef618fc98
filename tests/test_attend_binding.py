"""``usdgaze attend`` binds as ``apply`` does: --bind/--forward hints, then the SkelRoot's GazeMapAPI
bindings, then names. Checked on a rig whose joints are numbered (no name says what they are), by
UsdSkel FK on the written layer: the eyes turn to a ball the character would not otherwise look at."""

from __future__ import annotations

import dataclasses

import numpy as np
from pxr import Gf, Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main
from usdgaze.gaze.defaults import default_definition

from . import measure
from . import synthetic as syn
from .attend_support import compose, over


def _scene(tmp, rig: syn.Rig):
    """The rig's stage under a layer with a still ball 2 m ahead of the eyes and 1.5 m to their left."""
    p = measure.posed(str(rig.path), rig.skeleton)
    s2w = p.skel_to_world[:3, :3]
    eyes = 0.5 * (p.position(rig.leaf["eye_l"])[0] + p.position(rig.leaf["eye_r"])[0])
    ball = eyes + 2.0 * (rig.forward @ s2w) + 1.5 * (rig.left @ s2w)
    layer = over(tmp / "scene.usda", rig.path)
    Sdf.CreatePrimInLayer(layer, "/Objects").specifier = Sdf.SpecifierDef
    prim = Sdf.CreatePrimInLayer(layer, "/Objects/Ball")
    prim.specifier, prim.typeName = Sdf.SpecifierDef, "Sphere"
    prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(*ball)
    Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    layer.Save()
    return tmp / "scene.usda", ball


def _angle_to_ball(stage_path, rig: syn.Rig, ball) -> np.ndarray:
    """Degrees between the left eye's forward (its bind-pose axis along the character forward) and the ball."""
    p = measure.posed(str(stage_path), rig.skeleton)
    fwd_s = rig.forward
    eye = rig.leaf["eye_l"]
    d = p.axis(eye, measure.local_forward(p, eye, fwd_s))
    to = ball - p.position(eye)
    return measure.angle_between(d, to / np.linalg.norm(to, axis=1, keepdims=True))


def test_attend_binds_an_unnamed_rig_from_hints_and_from_the_gaze_map(tmp_path):
    rig = syn.make_rig(tmp_path / "in.usda", convention="numbered", frames=24, time_codes_per_second=24,
                       mesh=False, walk_speed=0.0)
    scene, ball = _scene(tmp_path, rig)
    leaf = rig.leaf
    roles = {"pelvis": leaf["pelvis"], "head": leaf["head"], "leftEye": leaf["eye_l"], "rightEye": leaf["eye_r"]}
    out = tmp_path / "none.usdc"
    assert main(["attend", str(scene), "--out", str(out), "--window", "0.3"]) == 2  # nothing says which joint is what
    assert not out.exists()
    base = _angle_to_ball(scene, rig, ball)
    assert base.min() > 15.0

    args = [a for role, j in roles.items() for a in ("--bind", f"{role}={j}")]
    forward = ",".join(f"{v:g}" for v in rig.forward)
    out = tmp_path / "hints.usdc"
    assert main(["attend", str(scene), "--out", str(out), "--window", "0.3", *args, "--forward", forward]) == 0
    hinted = _angle_to_ball(compose(tmp_path, scene, out, "hints_composed.usda"), rig, ball)
    assert hinted[-8:].max() < 5.0, hinted  # looking at the ball by the last third of a second

    # The same bindings authored on the SkelRoot as GazeMapAPI: no flags needed.
    from pxr import Usd

    from usdgaze.usd import schema

    keys = {"pelvis": "pelvis", "head": "head", "leftEye": "eye_l", "rightEye": "eye_r"}
    d = dataclasses.replace(default_definition(), forward=tuple(float(v) for v in rig.forward),
                            bindings={role: (rig.joint(k),) for role, k in keys.items()})  # paths, as build-map writes
    stage = Usd.Stage.Open(str(rig.path))
    schema.write_map(stage.GetPrimAtPath(rig.skel_root), d)
    stage.GetRootLayer().Save()
    out = tmp_path / "map.usdc"
    assert main(["attend", str(scene), "--out", str(out), "--window", "0.3"]) == 0
    mapped = _angle_to_ball(compose(tmp_path, scene, out, "map_composed.usda"), rig, ball)
    assert np.allclose(mapped, hinted, atol=1e-3)
