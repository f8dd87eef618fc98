"""Measurements for the attend tests, from the WRITTEN layer by UsdSkel FK (nothing from usdgaze's math).

The point of sight is where the two eyes' rays pass closest (vergence); the cyclopean line of sight
goes from the eyes' midpoint to it. Eye-in-head angles use the head's axes taken from the rest pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

from tests import measure

REPO = Path(__file__).resolve().parents[1]
ATTEND = REPO / "sample_stages" / "attend"


def compose(tmp: Path, inp: Path, out: Path, name: str = "composed.usda") -> Path:
    """A root layer with the override over the input, as a viewer would open it."""
    src = Sdf.Layer.FindOrOpen(str(inp))
    root = Sdf.Layer.CreateNew(str(tmp / name))
    root.subLayerPaths[:] = [str(out), str(inp)]
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(root, key, getattr(src, key))
    for key in ("upAxis", "metersPerUnit"):
        if src.pseudoRoot.HasInfo(key):
            root.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    root.Save()
    return tmp / name


def over(path: Path, below: Path) -> Sdf.Layer:
    """A new layer at ``path`` whose one sublayer is ``below``, with its timing and units (a scene's
    objects go in it)."""
    src = Sdf.Layer.FindOrOpen(str(below))
    layer = Sdf.Layer.CreateNew(str(path))
    layer.subLayerPaths[:] = [str(below)]
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(layer, key, getattr(src, key))
    for key in ("upAxis", "metersPerUnit"):
        if src.pseudoRoot.HasInfo(key):
            layer.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    return layer


def still_ball(layer: Sdf.Layer, path: str, where, radius: float) -> None:
    """A still GazeObjectAPI sphere of ``radius`` at ``where`` (its parent made a def), in ``layer``."""
    ball = Sdf.CreatePrimInLayer(layer, path)
    layer.GetPrimAtPath(ball.path.GetParentPath()).specifier = Sdf.SpecifierDef
    ball.specifier, ball.typeName = Sdf.SpecifierDef, "Sphere"
    ball.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    Sdf.AttributeSpec(ball, "radius", Sdf.ValueTypeNames.Double).default = radius
    Sdf.AttributeSpec(ball, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(*where)
    Sdf.AttributeSpec(ball, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]


@dataclass
class Gaze:
    times: np.ndarray
    seconds: np.ndarray
    eyes: np.ndarray  # (F, 3) world midpoint
    sight: np.ndarray  # (F, 3) point of sight (closest approach of the eye rays)
    direction: np.ndarray  # (F, 3) unit cyclopean line of sight
    head_fwd: np.ndarray  # (F, 3) world head forward
    yaw: np.ndarray  # (F,) cyclopean eye-in-head azimuth, deg (+ left)
    pitch: np.ndarray  # (F,) elevation, deg (+ up)
    stage: Usd.Stage


def gaze(path: Path, skeleton: str = "/root/Body/BodySkel", times=None) -> Gaze:
    p = measure.posed(str(path), skeleton, times=times)
    fwd = measure.character_forward_skel(p, "LeftHip", "RightHip")
    up_s = np.linalg.solve(p.skel_to_world[:3, :3].T, p.up)
    up_s /= np.linalg.norm(up_s)
    left = np.cross(up_s, fwd)
    pl, pr = p.position("LeftEye"), p.position("RightEye")
    dl = p.axis("LeftEye", measure.local_forward(p, "LeftEye", fwd))
    dr = p.axis("RightEye", measure.local_forward(p, "RightEye", fwd))
    w0 = pl - pr
    a, b, c = (dl * dl).sum(-1), (dl * dr).sum(-1), (dr * dr).sum(-1)
    d, e = (dl * w0).sum(-1), (dr * w0).sum(-1)
    den = np.maximum(a * c - b * b, 1e-12)
    s = (b * e - c * d) / den
    t = (a * e - b * d) / den
    point = 0.5 * (pl + s[:, None] * dl + pr + t[:, None] * dr)
    mid = 0.5 * (pl + pr)
    v = point - mid
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    hf, hl, hu = (p.axis("Head", measure.local_forward(p, "Head", x)) for x in (fwd, left, up_s))
    yaw = np.degrees(np.arctan2((v * hl).sum(-1), (v * hf).sum(-1)))
    pitch = np.degrees(np.arcsin(np.clip((v * hu).sum(-1), -1, 1)))
    stage = Usd.Stage.Open(str(path))
    secs = (p.times - stage.GetStartTimeCode()) / stage.GetTimeCodesPerSecond()
    return Gaze(p.times, secs, mid, point, v, hf, yaw, pitch, stage)


def positions(stage: Usd.Stage, prim: str, times: np.ndarray) -> np.ndarray:
    xf = UsdGeom.Xformable(stage.GetPrimAtPath(prim))
    return np.array([np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(float(t))))[3, :3] for t in times])


def angle_to(g: Gaze, pts: np.ndarray) -> np.ndarray:
    """Degrees between the line of sight and the direction from the eyes to each point."""
    d = pts - g.eyes
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip((d * g.direction).sum(-1), -1, 1)))


def episodes(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of True."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return list(zip(edges[::2], edges[1::2]))


def inspection(stage: Usd.Stage, obj: str, attr: str, times: np.ndarray) -> np.ndarray:
    """An object's written estimate/uncertainty per frame (the inspection prims of the layer)."""
    for prim in stage.Traverse():
        a = prim.GetAttribute("gaze:attend:object")
        if a and a.Get() == obj:
            return np.array([prim.GetAttribute(f"gaze:attend:{attr}").Get(Usd.TimeCode(float(t))) for t in times],
                            dtype=float)
    raise AssertionError(f"no inspection prim for {obj}")
