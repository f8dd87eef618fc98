"""Gaze schedules stored in USD: the ``GazeScheduleAPI`` applied schema (source: ``schemas/schema.usda``).

A schedule on a SkelRoot says who looks at what, when, as parallel arrays (one entry per directive)
and a relationship to the target prims. :func:`read_schedule` turns it into the same
:class:`~usdgaze.passes.requests.DirectiveRequest` values the CLI flags parse to, so a schedule and
the same flags give the same layer byte for byte. Errors read ``FILE:PRIM.ATTRIBUTE: problem``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pxr import Sdf, Usd, UsdSkel, Vt

from usdgaze.errors import UsdGazeError
from usdgaze.passes.requests import DirectiveRequest

API_NAME = "GazeScheduleAPI"
TARGETS_REL = "gaze:schedule:targets"
TIME, KIND, TARGET, POINT = "gaze:schedule:time", "gaze:schedule:kind", "gaze:schedule:target", "gaze:schedule:point"
YAW, PITCH, WEIGHT, BLEND = "gaze:schedule:yaw", "gaze:schedule:pitch", "gaze:schedule:weight", "gaze:schedule:blend"
_T = Sdf.ValueTypeNames
# attribute -> (Sdf type, Python type of Get(), fallback per entry; None: required)
ATTRS: dict[str, tuple[Any, type, Any]] = {
    TIME: (_T.DoubleArray, Vt.DoubleArray, None),
    KIND: (_T.TokenArray, Vt.TokenArray, None),
    TARGET: (_T.IntArray, Vt.IntArray, -1),
    POINT: (_T.Point3dArray, Vt.Vec3dArray, (0.0, 0.0, 0.0)),
    YAW: (_T.FloatArray, Vt.FloatArray, 0.0),
    PITCH: (_T.FloatArray, Vt.FloatArray, 0.0),
    WEIGHT: (_T.FloatArray, Vt.FloatArray, 1.0),
    BLEND: (_T.FloatArray, Vt.FloatArray, 0.0),
}
KINDS = ("shift", "look", "release")


def has_schedule(prim: Usd.Prim) -> bool:
    return bool(prim) and prim.HasAPI(API_NAME)


def _shortest(x: float) -> float:
    """A float32 read back as the shortest decimal that rounds to it (0.3, not 0.30000001...)."""
    return float(str(np.float32(x)))


def _array(prim: Usd.Prim, name: str, where: str, count: int | None) -> list | None:
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        if ATTRS[name][2] is None:
            raise UsdGazeError(f"{where}.{name}: missing, expected one entry per directive")
        return None
    if attr.GetNumTimeSamples():
        raise UsdGazeError(f"{where}.{name}: has time samples; schedule attributes are uniform (one default value)")
    value = attr.Get()
    sdf_type, python_type, _ = ATTRS[name]
    if not isinstance(value, python_type):
        raise UsdGazeError(f"{where}.{name}: authored as {type(value).__name__}, expected {sdf_type}")
    if count is not None and len(value) != count:
        raise UsdGazeError(f"{where}.{name}: {len(value)} entries, expected {count} (one per directive)")
    return list(value)


def read_schedule(prim: Usd.Prim, source: str) -> list[DirectiveRequest]:
    """The directives on ``prim`` (a SkelRoot with GazeScheduleAPI), checked, in time order."""
    where = f"{source}:{prim.GetPath()}"
    if not prim.IsA(UsdSkel.Root):
        raise UsdGazeError(f"{where}: {API_NAME} is applied to a {prim.GetTypeName() or 'typeless prim'}; it applies only to SkelRoot")
    times = _array(prim, TIME, where, None)
    count = len(times)
    if count == 0:
        raise UsdGazeError(f"{where}.{TIME}: no directives")
    cols = {name: _array(prim, name, where, count) for name in ATTRS if name != TIME}
    rel = prim.GetRelationship(TARGETS_REL)
    targets = [str(p) for p in rel.GetForwardedTargets()] if rel else []
    out = []
    for k in range(count):
        def col(name):
            values = cols[name]
            return ATTRS[name][2] if values is None else values[k]
        t, kind = float(times[k]), str(col(KIND))
        if not np.isfinite(t):
            raise UsdGazeError(f"{where}.{TIME}: entry {k} is not finite")
        if k and t <= float(times[k - 1]):
            raise UsdGazeError(f"{where}.{TIME}: entry {k} ({t:g}) is not after entry {k - 1} ({float(times[k - 1]):g}); "
                               "directives go in time order, one per time")
        if kind not in KINDS:
            raise UsdGazeError(f"{where}.{KIND}: entry {k} is '{kind}', expected one of {', '.join(KINDS)}")
        weight, blend = _shortest(col(WEIGHT)), _shortest(col(BLEND))
        if not 0.0 <= weight <= 1.0:
            raise UsdGazeError(f"{where}.{WEIGHT}: entry {k} is {weight:g}, expected a weight in [0, 1]")
        if not (np.isfinite(blend) and blend >= 0.0):
            raise UsdGazeError(f"{where}.{BLEND}: entry {k} is {blend:g}, expected time codes >= 0")
        if kind == "shift":
            yaw, pitch = _shortest(col(YAW)), _shortest(col(PITCH))
            if not (np.isfinite([yaw, pitch]).all() and abs(pitch) <= 90.0 and abs(yaw) <= 360.0):
                raise UsdGazeError(f"{where}: directive {k}: yaw {yaw:g}, pitch {pitch:g} out of range "
                                   "(yaw in [-360, 360], pitch in [-90, 90] deg)")
            out.append(DirectiveRequest("shift", t, yaw=yaw, pitch=pitch, weight=weight, blend=blend))
        elif kind == "look":
            index = int(col(TARGET))
            if index == -1:
                if cols[POINT] is None:
                    raise UsdGazeError(f"{where}.{POINT}: missing; directive {k} looks at a point (target -1)")
                point = tuple(float(v) for v in col(POINT))
                if not np.isfinite(point).all():
                    raise UsdGazeError(f"{where}.{POINT}: entry {k} is not finite")
                out.append(DirectiveRequest("look", t, point=point, weight=weight, blend=blend))
            elif 0 <= index < len(targets):
                out.append(DirectiveRequest("look", t, target=targets[index], weight=weight, blend=blend))
            else:
                raise UsdGazeError(f"{where}.{TARGET}: entry {k} is {index}, but {TARGETS_REL} has "
                                   f"{len(targets)} target{'s' if len(targets) != 1 else ''} (use -1 for a point)")
        else:
            out.append(DirectiveRequest("release", t, blend=blend))
    return out


def write_schedule(prim: Usd.Prim, directives: list[DirectiveRequest]) -> None:
    """Apply ``GazeScheduleAPI`` to ``prim`` (a SkelRoot) and author ``directives`` (time codes only)."""
    where = f"{prim.GetStage().GetRootLayer().identifier}:{prim.GetPath()}"
    if not prim.CanApplyAPI(API_NAME):
        raise UsdGazeError(f"{where}: cannot hold {API_NAME}: it applies only to SkelRoot")
    if any(d.seconds or d.blend_seconds for d in directives):
        raise UsdGazeError(f"{where}: a schedule holds time codes; convert times in seconds first")
    directives = sorted(directives, key=lambda d: d.time)
    targets: list[str] = []
    for d in directives:
        if d.target is not None and d.target not in targets:
            targets.append(d.target)
    prim.ApplyAPI(API_NAME)
    prim.CreateRelationship(TARGETS_REL, False).SetTargets([Sdf.Path(t) for t in targets])
    values = {
        TIME: [d.time for d in directives],
        KIND: [d.kind for d in directives],
        TARGET: [targets.index(d.target) if d.target is not None else -1 for d in directives],
        POINT: [d.point if d.point is not None else (0.0, 0.0, 0.0) for d in directives],
        YAW: [d.yaw for d in directives],
        PITCH: [d.pitch for d in directives],
        WEIGHT: [d.weight for d in directives],
        BLEND: [d.blend for d in directives],
    }
    for name, value in values.items():
        sdf_type, python_type, _ = ATTRS[name]
        prim.CreateAttribute(name, sdf_type, False, Sdf.VariabilityUniform).Set(python_type(value))
