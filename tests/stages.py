"""Test stages for the look pass, built from the shipped CMU capture (nothing here uses usdgaze).

* :func:`standing`: a standing CMU character: the last 1.3 s of cmu_131_01 (frames 840-994, where the
  actor stands still after the walk), played forward and back ("ping-pong") for as long as asked,
  written at the Sdf level into a copy of the file. Real captured idle sway, no walking.
* :func:`with_targets`: a root layer that sublayers a stage and defines look-at targets: an Xform
  orbiting a point at a fixed angular rate, a static Cube (a Boundable), an Xform with a pivot.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu"
SKEL = "/root/Body/BodySkel"
STAND_FROM, STAND_TO = 840, 994


def standing(path: Path, frames: int) -> Path:
    """A standing CMU clip of ``frames`` time codes (1..frames) at ``path``."""
    shutil.copy(CMU / "cmu_131_01.usdc", path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    anim = SKEL + "/scaled_131_01"
    loop = np.concatenate([np.arange(STAND_FROM, STAND_TO), np.arange(STAND_TO, STAND_FROM, -1)])
    source = loop[np.arange(frames) % len(loop)]
    with Sdf.ChangeBlock():
        for name in ("rotations", "translations", "scales"):
            attr = Sdf.Path(anim + "." + name)
            authored = set(layer.ListTimeSamplesForPath(attr))
            if not set(float(t) for t in source) <= authored:
                continue  # held by fewer samples (e.g. constant scales): leave as is
            values = {t: layer.QueryTimeSample(attr, float(t)) for t in sorted(set(source.tolist()))}
            for t in sorted(authored):
                layer.EraseTimeSample(attr, t)
            for k, t in enumerate(source):
                layer.SetTimeSample(attr, float(k + 1), values[int(t)])
        layer.endTimeCode = float(frames)
    layer.Save()
    return path


def eye_height(path: Path) -> np.ndarray:
    """Midpoint of the head joint at the first sample, by UsdSkel (world)."""
    from . import measure

    p = measure.posed(str(path), SKEL)
    return p.position("Head")[0]


def with_targets(path: Path, base: Path, centre, radius: float, deg_per_s: float, frames: int,
                 tcps: float, start_deg: float = 0.0) -> Path:
    """``path`` sublayers ``base`` and adds /World/Ball (orbiting ``centre`` in the horizontal plane,
    Y up), /World/Box (a static Cube of size 0.2 at ``centre`` + (0, 0, 3)) and /World/Lamp (an
    Xform at (1, 0, 0) with a pivot at (0, 2, 0) local)."""
    stage = Usd.Stage.CreateNew(str(path))
    stage.GetRootLayer().subLayerPaths.append(str(base))
    UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.GetStageMetersPerUnit(Usd.Stage.Open(str(base))))
    stage.SetTimeCodesPerSecond(tcps)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(frames)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    ball = UsdGeom.Xform.Define(stage, "/World/Ball")
    op = ball.AddTranslateOp()
    c = np.asarray(centre, dtype=float)
    for k in range(frames):
        a = np.radians(start_deg + deg_per_s * k / tcps)
        op.Set(Gf.Vec3d(*(c + radius * np.array([np.sin(a), 0.0, np.cos(a)]))), Usd.TimeCode(k + 1))
    box = UsdGeom.Cube.Define(stage, "/World/Box")
    box.CreateSizeAttr(0.2)
    box.AddTranslateOp().Set(Gf.Vec3d(*(c + [0.0, 0.0, 3.0])))
    lamp = UsdGeom.Xform.Define(stage, "/World/Lamp")
    lamp.AddTranslateOp().Set(Gf.Vec3d(1.0, 0.0, 0.0))
    pivot = lamp.AddTranslateOp(opSuffix="pivot")
    pivot.Set(Gf.Vec3d(0.0, 2.0, 0.0))
    lamp.AddRotateYOp().Set(90.0)
    lamp.AddTranslateOp(opSuffix="pivot", isInverseOp=True)
    stage.GetRootLayer().Save()
    return path


def orbit_positions(centre, radius: float, deg_per_s: float, times: np.ndarray, tcps: float,
                    start_deg: float = 0.0) -> np.ndarray:
    a = np.radians(start_deg + deg_per_s * (times - 1) / tcps)
    return np.asarray(centre, dtype=float) + radius * np.column_stack([np.sin(a), np.zeros_like(a), np.cos(a)])
