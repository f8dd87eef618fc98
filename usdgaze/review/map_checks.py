"""Checks behind the ``GazeMap*`` validators: a GazeMapAPI's arrays, their ranges, unit quaternions and
the joints its bindings name, each held to what ``read_map`` and ``apply`` hold them to, one
``ValidationError`` per problem, sited on the attribute at fault."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdSkel

from usdgaze.gaze.definition import (
    API_NAME,
    BINDING_ATTRS,
    EXAMPLE_ATTRS,
    FORWARD_ATTR,
    OFFSET_ATTRS,
    PITCH_ATTR,
    SETTING_ATTRS,
    TIMING_ATTRS,
    UNIT_TOLERANCE,
    YAW_ATTR,
    _TIMING_RANGES,
    _check_range,
    _range_text,
    forward_problem,
    setting_problem,
)
from usdgaze.gaze.motion import TIMING_FIELDS
from usdgaze.review.skel_checks import site_error
from usdgaze.usd.checks import authored_type


def _values(prim: Usd.Prim, name: str):
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return attr, None
    return attr, attr.Get()


def _animated(prim: Usd.Prim, name: str, path) -> list:
    """read_map refuses a gaze map attribute with time samples (its default alone is read): say so."""
    attr = prim.GetAttribute(name)
    if attr and attr.GetNumTimeSamples():
        return [site_error(prim, path, "Animated", f"{name}: has time samples; gaze map attributes are uniform (one default value)")]
    return []


def gaze_map_arrays(prim: Usd.Prim, time_range=None) -> list:
    from usdgaze.usd.schema import _TYPES

    errors, lengths = [], {}
    # The per-example arrays, then the settings, bindings and forward: read_map refuses a wrong type too.
    for name in EXAMPLE_ATTRS + tuple(n for n in _TYPES if n not in EXAMPLE_ATTRS):
        path = prim.GetPath().AppendProperty(name)
        animated = _animated(prim, name, path)
        attr, value = _values(prim, name)
        if animated or value is None:
            # Only time samples: no default, so not 'missing' as well (it said only that).
            errors += animated or ([site_error(prim, path, "Missing", f"{name}: missing, expected one entry per example")]
                                   if name in EXAMPLE_ATTRS else [])
            continue
        if not isinstance(value, _TYPES[name][1]) or isinstance(value, bool):
            errors.append(site_error(prim, path, "WrongType", f"{name}: authored as {authored_type(attr)}, expected {_TYPES[name][0]}"))
            continue
        if name in EXAMPLE_ATTRS:
            lengths[name] = len(value)
    if lengths:
        counts = np.array(list(lengths.values()))
        values, freq = np.unique(counts, return_counts=True)
        expected = int(values[np.argmax(freq)])
        for name, n in lengths.items():
            if n != expected:
                errors.append(site_error(prim, prim.GetPath().AppendProperty(name), "Length",
                                     f"{name}: {n} entries, expected {expected} (one per example)"))
        if expected == 0:
            errors.append(site_error(prim, prim.GetPath().AppendProperty(YAW_ATTR), "Empty", f"{YAW_ATTR}: no examples"))
    return errors


def _array(prim: Usd.Prim, name: str) -> np.ndarray | None:
    _, value = _values(prim, name)
    try:
        return None if value is None else np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None


def _out_of_range(prim, name: str, values: np.ndarray, ok: np.ndarray, expected: str, unit: str = "") -> list:
    bad = np.flatnonzero(~ok)
    if not len(bad):
        return []
    shown = ", ".join(f"example {i} is {values[i]:g}{unit}" for i in bad[:3]) + (f" (+{len(bad) - 3} more)" if len(bad) > 3 else "")
    return [site_error(prim, prim.GetPath().AppendProperty(name), "Range", f"{name}: {shown}, expected {expected}")]


def gaze_map_ranges(prim: Usd.Prim, time_range=None) -> list:
    errors = []
    for name, limit in ((YAW_ATTR, 180.0), (PITCH_ATTR, 90.0)):
        v = _array(prim, name)
        if v is not None and v.ndim == 1:
            errors += _out_of_range(prim, name, v, _check_range(v, -limit, True, limit, True),
                                    f"in [-{limit:g}, {limit:g}] deg", " deg")
    for field, name in zip(TIMING_FIELDS, TIMING_ATTRS):
        v = _array(prim, name)
        if v is not None and v.ndim == 1:
            low, low_in, high, high_in, unit = _TIMING_RANGES[field]
            errors += _out_of_range(prim, name, v, _check_range(v, low, low_in, high, high_in),
                                    _range_text(low, low_in, high, high_in), unit)
    yaw, pitch = _array(prim, YAW_ATTR), _array(prim, PITCH_ATTR)
    if yaw is not None and pitch is not None and yaw.shape == pitch.shape and yaw.ndim == 1:
        pairs = np.stack([yaw, pitch], axis=1)
        _, first, counts = np.unique(pairs, axis=0, return_index=True, return_counts=True)
        for i in first[counts > 1]:
            errors.append(site_error(prim, prim.GetPath().AppendProperty(YAW_ATTR), "Duplicate",
                                 f"{YAW_ATTR}: (yaw, pitch) = ({yaw[i]:g}, {pitch[i]:g}) appears more than once"))
    return errors + _setting_ranges(prim) + _forward_range(prim)


def _setting_ranges(prim: Usd.Prim) -> list:
    """The synthesis settings against the bounds read_map holds them to (its own check)."""
    from usdgaze.usd.schema import _TYPES

    errors = []
    for field, name in SETTING_ATTRS.items():
        _, value = _values(prim, name)
        if not isinstance(value, _TYPES[name][1]) or isinstance(value, bool):
            continue  # unauthored, or of another type: WrongType says so (a string here was an internal error)
        problem = setting_problem(field, value)
        if problem:
            errors.append(site_error(prim, prim.GetPath().AppendProperty(name), "Range", f"{name}: {problem}"))
    return errors


def _forward_range(prim: Usd.Prim) -> list:
    """An authored forward that read_map refuses (NaN, infinite, or too long to have a length); (0, 0, 0) is unset."""
    _, value = _values(prim, FORWARD_ATTR)
    if value is None or not hasattr(value, "__len__") or len(value) != 3 or all(c == 0.0 for c in value):
        return []
    problem = forward_problem(tuple(value))
    return [site_error(prim, prim.GetPath().AppendProperty(FORWARD_ATTR), "Range", f"{FORWARD_ATTR}: {problem}")] if problem else []


def gaze_map_unit_quaternions(prim: Usd.Prim, time_range=None) -> list:
    errors = []
    for name in OFFSET_ATTRS:
        q = _array(prim, name)
        if q is None or q.ndim != 2 or q.shape[1] != 4:
            continue
        length = np.linalg.norm(q, axis=1)
        bad = np.flatnonzero(~(np.isfinite(q).all(axis=1) & (np.abs(length - 1.0) <= UNIT_TOLERANCE)))
        if len(bad):
            shown = ", ".join(f"example {i} of length {length[i]:.6g}" for i in bad[:3])
            errors.append(site_error(prim, prim.GetPath().AppendProperty(name), "NotUnit",
                                 f"{name}: {shown}{' ...' if len(bad) > 3 else ''}, expected unit quaternions "
                                 f"(within {UNIT_TOLERANCE:g})"))
    return errors


def gaze_map_role_joints(prim: Usd.Prim, time_range=None) -> list:
    if not prim.IsA(UsdSkel.Root):
        return [site_error(prim, prim.GetPath(), "NotSkelRoot",
                       f"{API_NAME} is applied to a {prim.GetTypeName() or 'typeless prim'}; it applies only to SkelRoot")]
    skeletons = [p for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Skeleton)]
    errors = []
    for role, name in BINDING_ATTRS.items():
        _, value = _values(prim, name)
        for skel in skeletons:
            missing = [str(j) for j in (value or []) if not _binds(str(j), UsdSkel.Skeleton(skel))]
            if missing:
                errors.append(site_error(prim, prim.GetPath().AppendProperty(name), "UnknownJoint",
                                     f"{name}: '{missing[0]}'{f' (+{len(missing) - 1} more)' if len(missing) > 1 else ''} "
                                     f"is not a joint of {skel.GetPath()}"))
    return errors


def _binds(name: str, skel: UsdSkel.Skeleton) -> bool:
    """Whether a binding's joint name finds a joint of ``skel`` as ``apply`` finds it: by path or by its
    own name, on the joint tokens or, where they say nothing, the paths spelled with its jointNames (a
    binding by own name, ``mixamorig_Head``, bound in apply and was 'not a joint' here)."""
    from usdgaze.core.names import spelled_with_names
    from usdgaze.core.rig import resolve_either
    from usdgaze.errors import RigError

    tokens = [str(j) for j in (skel.GetJointsAttr().Get() or [])]
    names_attr = skel.GetJointNamesAttr()
    names = names_attr.Get() if names_attr and names_attr.HasAuthoredValue() else None
    spelled = spelled_with_names(tokens, UsdSkel.Topology(tokens).GetParentIndices(), names) if names else None
    try:
        resolve_either(name, spelled or tokens, tokens, "")
    except RigError:
        return False
    return True
