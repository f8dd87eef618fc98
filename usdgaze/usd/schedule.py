"""Gaze schedules stored in USD: the ``GazeScheduleAPI`` applied schema (source: ``schemas/schema.usda``).

A schedule on a SkelRoot says who looks at what, when, as parallel arrays (one entry per directive)
and a relationship to the target prims. :func:`read_schedule` turns it into the same
:class:`~usdgaze.passes.requests.DirectiveRequest` values the CLI flags parse to, so a schedule and
the same flags give the same layer byte for byte. Errors read ``FILE:PRIM.ATTRIBUTE: problem``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from pxr import Sdf, Usd, UsdSkel, Vt

from usdgaze.errors import UsdGazeError
from usdgaze.usd.checks import authored_type
from usdgaze.usd.plugin import has_api
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
    return has_api(prim, API_NAME)


def _shortest(x: float) -> float:
    """A float32 read back as the shortest decimal that rounds to it (0.3, not 0.30000001...)."""
    return float(str(np.float32(x)))


class _Found:
    """Problems as they are found: the first raised (a pass reads the schedule and stops), or every
    one kept (``usdgaze validate`` lists them all)."""

    def __init__(self, keep: bool) -> None:
        self.keep, self.messages = keep, []

    def __call__(self, message: str) -> None:
        if not self.keep:
            raise UsdGazeError(message)
        self.messages.append(message)


def _array(prim: Usd.Prim, name: str, where: str, count: int | None, found: _Found) -> list | None:
    """The attribute's entries; None where it is not authored or (a problem found) not usable."""
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        if ATTRS[name][2] is None:
            found(f"{where}.{name}: missing, expected one entry per directive")
        return None
    if attr.GetNumTimeSamples():
        found(f"{where}.{name}: has time samples; schedule attributes are uniform (one default value)")
        return None
    value = attr.Get()
    sdf_type, python_type, _ = ATTRS[name]
    if not isinstance(value, python_type):
        found(f"{where}.{name}: authored as {authored_type(attr)}, expected {sdf_type}")
        return None
    if count is not None and len(value) != count:
        found(f"{where}.{name}: {len(value)} entries, expected {count} (one per directive)")
        return None
    return list(value)


def _offset(prim: Usd.Prim, name: str) -> Sdf.LayerOffset:
    """The layer offset from the layer holding the attribute's strongest opinion to the stage's root layer."""
    stack = prim.GetAttribute(name).GetPropertyStackWithLayerOffsets(Usd.TimeCode.Default())
    return stack[0][1] if stack else Sdf.LayerOffset()


def read_schedule(prim: Usd.Prim, source: str) -> list[DirectiveRequest]:
    """The directives on ``prim`` (a SkelRoot with GazeScheduleAPI), checked, in time order; the first
    problem found is a one-line error."""
    return _read(prim, source, _Found(keep=False))


def schedule_problems(prim: Usd.Prim, source: str) -> tuple[list[DirectiveRequest], list[str]]:
    """Every problem of the schedule on ``prim`` (each the line :func:`read_schedule` would raise for it,
    were it the first), and the directives that are sound."""
    found = _Found(keep=True)
    return _read(prim, source, found), found.messages


def _read(prim: Usd.Prim, source: str, found: _Found) -> list[DirectiveRequest]:
    where = f"{source}:{prim.GetPath()}"
    if not prim.IsA(UsdSkel.Root):
        found(f"{where}: {API_NAME} is applied to a {prim.GetTypeName() or 'typeless prim'}; it applies only to SkelRoot")
        return []
    times = _array(prim, TIME, where, None, found)
    if times is None:
        return []
    if not times:
        found(f"{where}.{TIME}: no directives")
        return []
    # A column found unusable reads as not authored: its entries' checks are skipped, not repeated.
    cols = {name: _array(prim, name, where, len(times), found) for name in ATTRS if name != TIME}
    # Time codes follow the layer offsets (and timeCodesPerSecond) by which the layer holding them is
    # brought in, as time samples and SdfTimeCode values do: a schedule authored in an asset referenced
    # with an offset had its looks played at the asset's times against the animation at the shot's.
    offset = _offset(prim, TIME)
    times = [float(offset * float(t)) if np.isfinite(float(t)) else float(t) for t in times]
    if cols[BLEND] is not None:
        scale = _offset(prim, BLEND).scale
        cols[BLEND] = [float(b) * scale for b in cols[BLEND]]
    rel = prim.GetRelationship(TARGETS_REL)
    targets = [str(p) for p in rel.GetForwardedTargets()] if rel else []
    out = []
    for k in range(len(times)):
        def col(name):
            values = cols[name]
            return ATTRS[name][2] if values is None else values[k]
        d = _directive(k, times, col, cols[POINT] is not None, targets, where, found)
        if d is not None:
            out.append(dataclasses.replace(d, origin=f"{where}.{TIME}: entry {k}"))
    return out


def _directive(k: int, times: list, col, has_point: bool, targets: list[str], where: str,
               found: _Found) -> DirectiveRequest | None:
    """Entry ``k`` as a directive, or None where a problem was found in it (each problem said)."""
    problems = len(found.messages)
    t, kind = float(times[k]), col(KIND)
    if not np.isfinite(t):
        found(f"{where}.{TIME}: entry {k} is not finite")
    elif k and t <= float(times[k - 1]):
        found(f"{where}.{TIME}: entry {k} ({t:g}) is not after entry {k - 1} ({float(times[k - 1]):g}); "
              "directives go in time order, one per time")
    if kind is not None and str(kind) not in KINDS:  # None: the kind column itself was unusable
        found(f"{where}.{KIND}: entry {k} is '{kind}', expected one of {', '.join(KINDS)}")
    weight, blend = _shortest(col(WEIGHT)), _shortest(col(BLEND))
    if not 0.0 <= weight <= 1.0:
        found(f"{where}.{WEIGHT}: entry {k} is {weight:g}, expected a weight in [0, 1]")
    if not (np.isfinite(blend) and blend >= 0.0):
        found(f"{where}.{BLEND}: entry {k} is {blend:g}, expected time codes >= 0")
    made = None
    if kind == "shift":
        yaw, pitch = _shortest(col(YAW)), _shortest(col(PITCH))
        if not (np.isfinite([yaw, pitch]).all() and abs(pitch) <= 90.0 and abs(yaw) <= 360.0):
            found(f"{where}: directive {k}: yaw {yaw:g}, pitch {pitch:g} out of range "
                  "(yaw in [-360, 360], pitch in [-90, 90] deg)")
        made = DirectiveRequest("shift", t, yaw=yaw, pitch=pitch, weight=weight, blend=blend)
    elif kind == "look":
        made = _look(k, t, int(col(TARGET)), col(POINT) if has_point else None, targets, where, found,
                     weight=weight, blend=blend)
    elif kind == "release":
        made = DirectiveRequest("release", t, blend=blend)
    return made if len(found.messages) == problems else None


def _look(k: int, t: float, index: int, point, targets: list[str], where: str, found: _Found,
          **weights: float) -> DirectiveRequest | None:
    """A look directive at target ``index`` (-1: at ``point``, None where not authored)."""
    if index == -1:
        if point is None:
            found(f"{where}.{POINT}: missing; directive {k} looks at a point (target -1)")
            return None
        point = tuple(float(v) for v in point)
        if not np.isfinite(point).all():
            found(f"{where}.{POINT}: entry {k} is not finite")
            return None
        return DirectiveRequest("look", t, point=point, **weights)
    if 0 <= index < len(targets):
        return DirectiveRequest("look", t, target=targets[index], **weights)
    found(f"{where}.{TARGET}: entry {k} is {index}, but {TARGETS_REL} has "
          f"{len(targets)} target{'s' if len(targets) != 1 else ''} (use -1 for a point)")
    return None


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
