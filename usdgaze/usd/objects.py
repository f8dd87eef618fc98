"""Objects to look at, read from a stage: prims with ``GazeObjectAPI`` or named paths.

An object's true state is the translation of its local-to-world transform, sampled at the planner's
times; positions come back in metres (the stage's metersPerUnit applied).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from usdgaze.errors import UsdGazeError

API_NAME = "GazeObjectAPI"
KINDS = ("", "ballistic", "static", "moving")


@dataclass
class StageObject:
    path: str
    positions: np.ndarray  # (K, 3) metres, world
    importance: np.ndarray  # (K,) > 0
    radius: float
    kind: str


def _attr(prim: Usd.Prim, name: str, default, where: str):
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return default
    value = attr.Get()
    if value is None:
        raise UsdGazeError(f"{where}.{name}: has no value")
    return value


def _importance(prim: Usd.Prim, time_codes: np.ndarray, where: str) -> np.ndarray:
    attr = prim.GetAttribute("gaze:object:importance")
    if not attr or not attr.HasAuthoredValue():
        return np.ones(len(time_codes))
    values = [attr.Get(Usd.TimeCode(float(t))) for t in time_codes]
    if any(v is None for v in values):
        raise UsdGazeError(f"{where}.gaze:object:importance: has no value")
    return np.array(values, dtype=float)


def object_prims(stage: Usd.Stage, source: str, paths: list[str] | None) -> list[Usd.Prim]:
    """The prims named by ``paths``, else every prim with GazeObjectAPI; one-line errors otherwise."""
    if paths:
        prims = []
        for p in paths:
            if not Sdf.Path.IsValidPathString(p) or not Sdf.Path(p).IsAbsolutePath():
                raise UsdGazeError(f"{source}: --objects entry '{p}' is not an absolute prim path such as /World/Ball")
            prim = stage.GetPrimAtPath(p)
            if not prim or not prim.IsValid():
                raise UsdGazeError(f"{source}:{p}: no such prim")
            prims.append(prim)
    else:
        prims = [p for p in stage.Traverse() if p.HasAPI(API_NAME)]
    if not prims:
        raise UsdGazeError(f"{source}: no objects to look at: apply {API_NAME} to some prims or pass --objects PATH,...")
    for prim in prims:
        if not prim.IsA(UsdGeom.Xformable):
            kind = prim.GetTypeName() or "typeless prim"
            raise UsdGazeError(f"{source}:{prim.GetPath()}: is a {kind} without a transform; an object must be Xformable")
    return prims


def read_objects(stage: Usd.Stage, source: str, prims: list[Usd.Prim], time_codes: np.ndarray,
                 meters_per_unit: float) -> list[StageObject]:
    """World positions of every object at ``time_codes`` plus its GazeObjectAPI attributes."""
    out = []
    caches = [UsdGeom.XformCache(Usd.TimeCode(float(t))) for t in time_codes]
    for prim in prims:
        where = f"{source}:{prim.GetPath()}"
        importance = _importance(prim, time_codes, where)
        radius = float(_attr(prim, "gaze:object:radius", 0.1, where))
        kind = str(_attr(prim, "gaze:object:kind", "", where))
        if not np.all(np.isfinite(importance)) or np.any(importance <= 0):
            bad = importance[~(np.isfinite(importance) & (importance > 0))][0]
            raise UsdGazeError(f"{where}.gaze:object:importance: {bad:g} must be > 0")
        if not np.isfinite(radius) or radius < 0:
            raise UsdGazeError(f"{where}.gaze:object:radius: {radius:g} must be >= 0")
        if kind not in KINDS:
            raise UsdGazeError(f"{where}.gaze:object:kind: '{kind}' is not one of {', '.join(repr(k) for k in KINDS)}")
        pos = np.array([np.array(c.GetLocalToWorldTransform(prim))[3, :3] for c in caches]) * meters_per_unit
        if not np.all(np.isfinite(pos)):
            raise UsdGazeError(f"{where}: its world transform is not finite at some time")
        out.append(StageObject(str(prim.GetPath()), pos, importance, radius, kind))
    return out
