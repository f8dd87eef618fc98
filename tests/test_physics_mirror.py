"""``attend --physics`` on a mirrored world: the SkelRoot (and the ball) under a scale of -1 along X.

Physics is symmetric under a mirror, so the mirrored shot must simulate what the plain one does:
the same skeleton-local rotations and translations, bit for bit (the model of a mirrored character
is its right-handed mirror image), the eyes included, and by UsdSkel's forward kinematics every
joint where the plain shot's is, mirrored. Before, a mirrored character failed with exit 1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc

from . import catch_stages as cs
from . import measure
from .test_physics_pass import SKEL, excerpt

MIRROR = np.diag([-1.0, 1.0, 1.0])


def mirrored(path: Path, src: Path, prims: tuple[str, ...]) -> Path:
    """A root layer over ``src`` putting a scale of (-1, 1, 1) outermost on each of ``prims``."""
    stage = Usd.Stage.Open(str(src))
    orders = {p: list(UsdGeom.Xformable(stage.GetPrimAtPath(p)).GetXformOpOrderAttr().Get() or []) for p in prims}
    base = stage.GetRootLayer()
    layer = Sdf.Layer.CreateNew(str(path))
    for key in ("upAxis", "metersPerUnit"):
        layer.pseudoRoot.SetInfo(key, stage.GetMetadata(key))
    layer.timeCodesPerSecond, layer.framesPerSecond = base.timeCodesPerSecond, base.framesPerSecond
    layer.startTimeCode, layer.endTimeCode = base.startTimeCode, base.endTimeCode
    layer.subLayerPaths.append(str(src))
    for p in prims:
        over = Sdf.CreatePrimInLayer(layer, p)
        over.specifier = Sdf.SpecifierOver
        Sdf.AttributeSpec(over, "xformOp:scale:mirror", Sdf.ValueTypeNames.Float3).default = (-1.0, 1.0, 1.0)
        Sdf.AttributeSpec(over, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = ["xformOp:scale:mirror"] + orders[p]
    layer.Save()
    return path


def _arrays(out: Path, anim: str) -> tuple[np.ndarray, np.ndarray]:
    layer = Sdf.Layer.FindOrOpen(str(out))
    got = []
    for name in ("rotations", "translations"):
        path = Sdf.Path(f"{anim}.{name}")
        got.append(np.stack([np.asarray(layer.QueryTimeSample(path, t)) for t in layer.ListTimeSamplesForPath(path)]))
    return got[0], got[1]


def _composed(path: Path, out: Path, src: Path) -> Path:
    stage = Usd.Stage.Open(str(src))
    layer = Sdf.Layer.CreateNew(str(path))
    for key in ("upAxis", "metersPerUnit"):
        layer.pseudoRoot.SetInfo(key, stage.GetMetadata(key))
    layer.timeCodesPerSecond = stage.GetTimeCodesPerSecond()
    layer.framesPerSecond = stage.GetFramesPerSecond()
    layer.subLayerPaths[:] = [str(out), str(src)]
    layer.Save()
    return path


def _both(tmp: Path, src: Path, prims: tuple[str, ...]):
    options = mpc.Options(h=0.02, horizon_s=0.6)
    flipped = mirrored(tmp / "mirrored.usda", src, prims)
    physics_pass.run(src, tmp / "plain_sim.usda", options)
    physics_pass.run(flipped, tmp / "mirrored_sim.usda", options)
    return (_composed(tmp / "plain_shot.usda", tmp / "plain_sim.usda", src),
            _composed(tmp / "mirrored_shot.usda", tmp / "mirrored_sim.usda", flipped))


def test_a_mirrored_walk_simulates_the_plain_walk_mirrored(tmp_path):
    src = excerpt(tmp_path / "walk.usda", 0.3)
    plain, flipped = _both(tmp_path, src, ("/root",))
    anim = SKEL + "/scaled_131_01"
    a, b = _arrays(tmp_path / "plain_sim.usda", anim), _arrays(tmp_path / "mirrored_sim.usda", anim)
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()
    p, m = measure.posed(str(plain), SKEL), measure.posed(str(flipped), SKEL)
    assert len(p.times) == len(m.times) > 20
    assert np.abs(m.world[:, :, 3, :3] - p.world[:, :, 3, :3] @ MIRROR).max() < 1e-5
    # Not trivially so: the walk moves the pelvis and the legs.
    assert np.linalg.norm(np.ptp(p.position("Hips"), axis=0)) > 0.05


def test_a_mirrored_catch_moves_body_and_eyes_as_the_plain_one_mirrored(tmp_path):
    head, shoulders, fwd, left = cs.character()
    start = shoulders + 2.5 * fwd + 1.5 * left + np.array([0.0, 0.3, 0.0])
    arrival = shoulders + 0.35 * fwd + 0.3 * left
    src = cs.throw_stage(tmp_path / "throw.usda", start, arrival, 0.9, 0.3)
    plain, flipped = _both(tmp_path, src, ("/root", "/Objects"))
    a, b = _arrays(tmp_path / "plain_sim.usda", cs.ANIM), _arrays(tmp_path / "mirrored_sim.usda", cs.ANIM)
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()
    p, m = measure.posed(str(plain), SKEL), measure.posed(str(flipped), SKEL)
    assert np.abs(m.world[:, :, 3, :3] - p.world[:, :, 3, :3] @ MIRROR).max() < 1e-5
    # The eyes turn toward the ball on the character's left, so the comparison covers their yaw:
    # the added left eye's local rotation moves by more than 3 deg over the shot.
    eye = p.index("LeftEye")
    assert eye == 31 and a[0].shape[1] == 33
    first, last = a[0][0, eye].astype(float), a[0][-1, eye].astype(float)
    assert np.degrees(2 * np.arccos(min(1.0, abs(first @ last)))) > 3.0
