"""``pxr.UsdValidation`` validators for usdgaze's schemas and the animation it writes.

Declared in the schema plugin's plugInfo.json (plugin ``usdgaze.review.validators``, a Python
plugin), so any tool that has the plugin on ``PXR_PLUGINPATH_NAME`` and usdgaze on its Python path
loads them on demand (``usdchecker --validate``-style tools, ``UsdValidation.ValidationContext``);
``import usdgaze`` registers them at once. Each validator reports every problem it finds, one
``ValidationError`` per problem, sited on the attribute (or prim) at fault.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdSkel, UsdValidation

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
from usdgaze.review.layer_checks import gaze_layer_schedule, sampled_range
from usdgaze.usd.checks import arc_units_problem, arc_up_axis_problem, authored_type
from usdgaze.usd.skelio import animation_of
from usdgaze.review.skel_checks import animation_arrays, ill_formed_joints, skinned_influences

PLUGIN = "usdgaze.review.validators"
"""The Python plugin's name in plugInfo.json (= this module); validator names are ``PLUGIN:Name``."""
KEYWORD = "UsdGazeValidators"


def declared() -> dict[str, dict]:
    """The validators plugInfo.json declares for this plugin: name -> {doc, schemaTypes}
    (written by ``schemas/generate.py``, the one place their docs live)."""
    import json

    from usdgaze.usd.plugin import plugin_dir

    text = (plugin_dir() / "plugInfo.json").read_text(encoding="utf-8")
    data = json.loads("\n".join(line for line in text.splitlines() if not line.startswith("#")))
    for plugin in data["Plugins"]:
        if plugin["Name"] == PLUGIN:
            return {k: v for k, v in plugin["Info"]["Validators"].items() if k != "keywords"}
    raise RuntimeError(f"plugInfo.json declares no {PLUGIN} plugin; run python schemas/generate.py")


def _error(prim: Usd.Prim, path, name: str, message: str):
    site = UsdValidation.ValidationErrorSite(prim.GetStage(), path)
    return UsdValidation.ValidationError(name, UsdValidation.ValidationErrorType.Error, [site], message)


def _values(prim: Usd.Prim, name: str):
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return attr, None
    return attr, attr.Get()


def _animated(prim: Usd.Prim, name: str, path) -> list:
    """read_map refuses a gaze map attribute with time samples (its default alone is read): say so."""
    attr = prim.GetAttribute(name)
    if attr and attr.GetNumTimeSamples():
        return [_error(prim, path, "Animated", f"{name}: has time samples; gaze map attributes are uniform (one default value)")]
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
            errors += animated or ([_error(prim, path, "Missing", f"{name}: missing, expected one entry per example")]
                                   if name in EXAMPLE_ATTRS else [])
            continue
        if not isinstance(value, _TYPES[name][1]) or isinstance(value, bool):
            errors.append(_error(prim, path, "WrongType", f"{name}: authored as {authored_type(attr)}, expected {_TYPES[name][0]}"))
            continue
        if name in EXAMPLE_ATTRS:
            lengths[name] = len(value)
    if lengths:
        counts = np.array(list(lengths.values()))
        values, freq = np.unique(counts, return_counts=True)
        expected = int(values[np.argmax(freq)])
        for name, n in lengths.items():
            if n != expected:
                errors.append(_error(prim, prim.GetPath().AppendProperty(name), "Length",
                                     f"{name}: {n} entries, expected {expected} (one per example)"))
        if expected == 0:
            errors.append(_error(prim, prim.GetPath().AppendProperty(YAW_ATTR), "Empty", f"{YAW_ATTR}: no examples"))
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
    return [_error(prim, prim.GetPath().AppendProperty(name), "Range", f"{name}: {shown}, expected {expected}")]


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
            errors.append(_error(prim, prim.GetPath().AppendProperty(YAW_ATTR), "Duplicate",
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
            errors.append(_error(prim, prim.GetPath().AppendProperty(name), "Range", f"{name}: {problem}"))
    return errors


def _forward_range(prim: Usd.Prim) -> list:
    """An authored forward that read_map refuses (NaN, infinite, or too long to have a length); (0, 0, 0) is unset."""
    _, value = _values(prim, FORWARD_ATTR)
    if value is None or not hasattr(value, "__len__") or len(value) != 3 or all(c == 0.0 for c in value):
        return []
    problem = forward_problem(tuple(value))
    return [_error(prim, prim.GetPath().AppendProperty(FORWARD_ATTR), "Range", f"{FORWARD_ATTR}: {problem}")] if problem else []


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
            errors.append(_error(prim, prim.GetPath().AppendProperty(name), "NotUnit",
                                 f"{name}: {shown}{' ...' if len(bad) > 3 else ''}, expected unit quaternions "
                                 f"(within {UNIT_TOLERANCE:g})"))
    return errors


def gaze_map_role_joints(prim: Usd.Prim, time_range=None) -> list:
    if not prim.IsA(UsdSkel.Root):
        return [_error(prim, prim.GetPath(), "NotSkelRoot",
                       f"{API_NAME} is applied to a {prim.GetTypeName() or 'typeless prim'}; it applies only to SkelRoot")]
    skeletons = [p for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Skeleton)]
    errors = []
    for role, name in BINDING_ATTRS.items():
        _, value = _values(prim, name)
        for skel in skeletons:
            missing = [str(j) for j in (value or []) if not _binds(str(j), UsdSkel.Skeleton(skel))]
            if missing:
                errors.append(_error(prim, prim.GetPath().AppendProperty(name), "UnknownJoint",
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


def skeleton_arrays(prim: Usd.Prim, time_range=None) -> list:
    """A Skeleton's bind and rest transforms, where authored, one finite matrix per joint (a layer that
    adds eyes writes all three: a short or broken one passed validate and failed every reader); its
    jointNames one name per joint; the meshes it skins, joint indices UsdSkel can skin by."""
    skel = UsdSkel.Skeleton(prim)
    joints = skel.GetJointsAttr().Get()
    n = 0 if joints is None else len(joints)
    errors = []
    for attr in (skel.GetBindTransformsAttr(), skel.GetRestTransformsAttr()):
        if not attr or not attr.HasAuthoredValue():
            continue
        value = attr.Get()
        m = np.asarray(value if value is not None else [], dtype=float).reshape(-1, 4, 4)
        if joints is None:
            errors.append(_error(prim, attr.GetPath(), "NoJoints", f"{attr.GetName()}: authored, but the Skeleton has no joints"))
        elif len(m) != n:
            errors.append(_error(prim, attr.GetPath(), "Length", f"{attr.GetName()}: {len(m)} entries, expected {n} (one per joint)"))
        elif not np.isfinite(m).all():
            errors.append(_error(prim, attr.GetPath(), "NotFinite", f"{attr.GetName()}: NaN or infinite values"))
    return (errors + ill_formed_joints(skel, joints) + _joint_names_length(skel, joints)
            + _sparse_without_rest(skel, joints) + skinned_influences(skel))


def _joint_names_length(skel: UsdSkel.Skeleton, joints) -> list:
    """jointNames, where authored, one per joint: readers (and the binder, which reads a rig's names
    there where its joint tokens say nothing) cannot pair a longer or shorter list with the joints."""
    attr = skel.GetJointNamesAttr()
    if not attr or not attr.HasAuthoredValue():
        return []
    k, n = len(attr.Get() or []), 0 if joints is None else len(joints)
    if k == n:
        return []
    return [_error(skel.GetPrim(), attr.GetPath(), "Length", f"jointNames: {k} entries, expected {n} (one per joint)")]


def _sparse_without_rest(skel: UsdSkel.Skeleton, joints) -> list:
    """A bound animation that leaves joints out needs restTransforms: UsdSkel takes those joints from
    them, and without them poses nothing (apply refuses such a skeleton, so validate says it too)."""
    rest = skel.GetRestTransformsAttr()
    if not joints or (rest and rest.HasAuthoredValue() and len(rest.Get() or []) > 0):
        return []
    anim_prim = animation_of(skel.GetPrim())
    if not anim_prim:
        return []
    listed = set(UsdSkel.Animation(anim_prim).GetJointsAttr().Get() or [])
    left_out = [j for j in joints if j not in listed]
    if not left_out:
        return []
    return [_error(skel.GetPrim(), rest.GetPath(), "SparseWithoutRest",
                   f"restTransforms: not authored, and {anim_prim.GetPath()} leaves {len(left_out)} of the skeleton's "
                   f"{len(joints)} joints out ('{left_out[0]}'); UsdSkel cannot pose this skeleton")]


def skeleton_units(prim: Usd.Prim, time_range=None) -> list:
    """The Skeleton, its SkelRoot and its bound animation, where a reference or payload brings them in,
    come from layers in the stage's metersPerUnit (apply refuses them otherwise, so validate says it too)."""
    return _across_arcs(prim, arc_units_problem, "Units")


def skeleton_up_axis(prim: Usd.Prim, time_range=None) -> list:
    """The Skeleton, its SkelRoot and its bound animation, where a reference or payload brings them in,
    come from layers in the stage's upAxis or are rotated onto it (apply refuses them otherwise)."""
    return _across_arcs(prim, arc_up_axis_problem, "UpAxis")


def _across_arcs(prim: Usd.Prim, find, name: str) -> list:
    """What ``find`` (one of ``usd.checks``' arc problems) says of the Skeleton ``prim``, its SkelRoot and
    its bound animation, as the reader asks it."""
    root = UsdSkel.Root.Find(prim)
    problem = find(prim.GetStage(), prim, [root.GetPrim() if root else None, prim, animation_of(prim)])
    return [] if problem is None else [_error(problem[0], problem[0].GetPath(), name, problem[1])]


def _malformed(prim: Usd.Prim, text: str):
    """One of the schedule reader's lines (``:PRIM[.ATTRIBUTE]: problem``), sited on the attribute it names."""
    prefix = f":{prim.GetPath()}"
    text = text[len(prefix):] if text.startswith(prefix) else text
    attr = text[1:].split(":", 3) if text.startswith(".") else None
    name = ":".join(attr[:3]) if attr and len(attr) > 3 else None
    path = prim.GetPath().AppendProperty(name) if name and prim.HasProperty(name) else prim.GetPath()
    return _error(prim, path, "Malformed", text.lstrip(".: ") if name is None else text[1:])


def gaze_schedule(prim: Usd.Prim, time_range=None) -> list:
    """A GazeScheduleAPI: storage as its reader checks it, every target a prim of the stage one can
    look at (Xformable or Boundable), every directive inside the stage's time range."""
    from pxr import UsdGeom

    from usdgaze.usd import schedule as sch

    directives, problems = sch.schedule_problems(prim, "")
    errors = [_malformed(prim, text) for text in problems]
    stage = prim.GetStage()
    rel = prim.GetRelationship(sch.TARGETS_REL)
    for target in (rel.GetForwardedTargets() if rel else []):
        t = stage.GetPrimAtPath(target)
        if not t or not (t.IsA(UsdGeom.Xformable) or t.IsA(UsdGeom.Boundable)):
            errors.append(_error(prim, rel.GetPath(), "MissingTarget",
                                 f"{sch.TARGETS_REL}: {target} is {'not an Xformable or Boundable prim' if t else 'no prim'} "
                                 "on this stage"))
    if stage.HasAuthoredTimeCodeRange():
        # apply plays a directive anywhere the animation has samples (handles past the playback range).
        start, end = sampled_range(stage, [prim.GetPath()], stage.GetStartTimeCode(), stage.GetEndTimeCode())
        late = [d.time for d in directives if not start <= d.time <= end]
        if late:
            errors.append(_error(prim, prim.GetPath().AppendProperty(sch.TIME), "OutOfRange",
                                 f"{sch.TIME}: {', '.join(f'{t:g}' for t in late[:3])} outside the stage's time range "
                                 f"and its animation [{start:g}, {end:g}]"))
    return errors


def gaze_object(prim: Usd.Prim, time_range=None) -> list:
    """A GazeObjectAPI: on an Xformable whose transform USD can evaluate, importance > 0 at every sample,
    radius >= 0, a known kind."""
    from pxr import UsdGeom

    errors = []
    if not prim.IsA(UsdGeom.Xformable):
        errors.append(_error(prim, prim.GetPath(), "NotXformable",
                             f"GazeObjectAPI is applied to a {prim.GetTypeName() or 'typeless prim'}; "
                             "it needs an Xformable (the object's world transform is its state)"))
    else:  # as attend reads it: an op USD cannot evaluate, on the object or above it, is refused there
        from usdgaze.usd.xformops import transform_problem

        found = transform_problem(prim)
        if found:
            attr = found[1].split(": ", 1)[0]  # the line names the attribute first
            errors.append(_error(found[0], found[0].GetPath().AppendProperty(attr), "Transform", found[1]))
    from usdgaze.usd.objects import importance_problem, type_problem

    typed = {}
    for name in ("gaze:object:importance", "gaze:object:radius", "gaze:object:kind"):
        attr = prim.GetAttribute(name)
        problem = type_problem(attr) if attr and attr.HasAuthoredValue() else None
        if problem:
            errors.append(_error(prim, attr.GetPath(), "Type", problem))
        typed[name] = attr if attr and not problem else None
    attr = typed["gaze:object:importance"]
    problem = importance_problem(attr) if attr and attr.HasAuthoredValue() else None
    if problem:
        errors.append(_error(prim, attr.GetPath(), "Range", problem))
    radius = typed["gaze:object:radius"]
    if radius and radius.Get() is not None and not (np.isfinite(radius.Get()) and radius.Get() >= 0.0):
        errors.append(_error(prim, radius.GetPath(), "Range", f"gaze:object:radius: {radius.Get()}, expected >= 0 m"))
    kind = typed["gaze:object:kind"]
    allowed = ("", "ballistic", "static", "moving")
    if kind and kind.Get() is not None and str(kind.Get()) not in allowed:
        errors.append(_error(prim, kind.GetPath(), "UnknownKind",
                             f"gaze:object:kind: '{kind.Get()}', expected one of {', '.join(repr(a) for a in allowed)}"))
    return errors


STAGE_TASKS = {"GazeLayerSchedule": gaze_layer_schedule}

TASKS = {
    "GazeMapArrays": gaze_map_arrays,
    "GazeMapRanges": gaze_map_ranges,
    "GazeMapUnitQuaternions": gaze_map_unit_quaternions,
    "GazeMapRoleJoints": gaze_map_role_joints,
    "AnimationArrays": animation_arrays,
    "SkeletonArrays": skeleton_arrays,
    "SkeletonUnits": skeleton_units,
    "SkeletonUpAxis": skeleton_up_axis,
    "GazeSchedule": gaze_schedule,
    "GazeObject": gaze_object,
}


def names() -> list[str]:
    """Full names of usdgaze's validators."""
    return [f"{PLUGIN}:{n}" for n in list(TASKS) + list(STAGE_TASKS)]


def register() -> None:
    """Register every validator once: through the plugin's metadata when plugInfo declared them
    (the normal case), else with metadata built here (a registry built before usdgaze's plugin was)."""
    registry = UsdValidation.ValidationRegistry()
    info = None
    for short, task in list(TASKS.items()) + list(STAGE_TASKS.items()):
        name = f"{PLUGIN}:{short}"
        stage_level = short in STAGE_TASKS
        if registry.HasValidator(name):
            continue
        if registry.GetValidatorMetadata(name) is not None:
            (registry.RegisterPluginStageValidator if stage_level else registry.RegisterPluginPrimValidator)(name, task)
        else:
            info = info or declared()
            md = UsdValidation.ValidatorMetadata(
                name=name, doc=info[short]["doc"], keywords=[KEYWORD],
                schemaTypes=info[short].get("schemaTypes", []), isTimeDependent=False, isSuite=False)
            (registry.RegisterStageValidator if stage_level else registry.RegisterPrimValidator)(md, task, [])


register()
