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

from usdgaze.review.map_checks import (gaze_map_arrays, gaze_map_ranges, gaze_map_role_joints,
                                       gaze_map_unit_quaternions)
from usdgaze.review.layer_checks import gaze_layer_schedule, sampled_range
from usdgaze.usd.checks import arc_units_problem, arc_up_axis_problem
from usdgaze.usd.skelio import animation_of
from usdgaze.review.skel_checks import site_error, animation_arrays, ill_formed_joints, skinned_influences

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


def skeleton_arrays(prim: Usd.Prim, time_range=None) -> list:
    """A Skeleton's bind and rest transforms, where authored, one finite matrix per joint (a layer that
    adds eyes writes all three: a short or broken one passed validate and failed every reader); its
    jointNames one name per joint; the meshes it skins, joint indices UsdSkel can skin by; its transform
    one USD can evaluate."""
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
            errors.append(site_error(prim, attr.GetPath(), "NoJoints", f"{attr.GetName()}: authored, but the Skeleton has no joints"))
        elif len(m) != n:
            errors.append(site_error(prim, attr.GetPath(), "Length", f"{attr.GetName()}: {len(m)} entries, expected {n} (one per joint)"))
        elif not np.isfinite(m).all():
            errors.append(site_error(prim, attr.GetPath(), "NotFinite", f"{attr.GetName()}: NaN or infinite values"))
    # As apply, attend and inspect read it: an op USD cannot evaluate on it or above it is refused there.
    return (errors + ill_formed_joints(skel, joints) + _joint_names_length(skel, joints)
            + _sparse_without_rest(skel, joints) + skinned_influences(skel) + _transform_errors(prim))


def _transform_errors(prim: Usd.Prim) -> list:
    """A ``Transform`` error, sited on the attribute at fault, where USD cannot evaluate the transform of
    ``prim`` or of a prim above it whose transform it inherits (:func:`xformops.transform_problem`)."""
    from usdgaze.usd.xformops import transform_problem

    found = transform_problem(prim)
    if not found:
        return []
    attr = found[1].split(": ", 1)[0]  # the line names the attribute first
    return [site_error(found[0], found[0].GetPath().AppendProperty(attr), "Transform", found[1])]


def _joint_names_length(skel: UsdSkel.Skeleton, joints) -> list:
    """jointNames, where authored, one per joint: readers (and the binder, which reads a rig's names
    there where its joint tokens say nothing) cannot pair a longer or shorter list with the joints."""
    attr = skel.GetJointNamesAttr()
    if not attr or not attr.HasAuthoredValue():
        return []
    k, n = len(attr.Get() or []), 0 if joints is None else len(joints)
    if k == n:
        return []
    return [site_error(skel.GetPrim(), attr.GetPath(), "Length", f"jointNames: {k} entries, expected {n} (one per joint)")]


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
    return [site_error(skel.GetPrim(), rest.GetPath(), "SparseWithoutRest",
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
    return [] if problem is None else [site_error(problem[0], problem[0].GetPath(), name, problem[1])]


def _malformed(prim: Usd.Prim, text: str):
    """One of the schedule reader's lines (``:PRIM[.ATTRIBUTE]: problem``), sited on the attribute it names."""
    prefix = f":{prim.GetPath()}"
    text = text[len(prefix):] if text.startswith(prefix) else text
    attr = text[1:].split(":", 3) if text.startswith(".") else None
    name = ":".join(attr[:3]) if attr and len(attr) > 3 else None
    path = prim.GetPath().AppendProperty(name) if name and prim.HasProperty(name) else prim.GetPath()
    return site_error(prim, path, "Malformed", text.lstrip(".: ") if name is None else text[1:])


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
            errors.append(site_error(prim, rel.GetPath(), "MissingTarget",
                                 f"{sch.TARGETS_REL}: {target} is {'not an Xformable or Boundable prim' if t else 'no prim'} "
                                 "on this stage"))
    if stage.HasAuthoredTimeCodeRange():
        # apply plays a directive anywhere the animation has samples (handles past the playback range).
        start, end = sampled_range(stage, [prim.GetPath()], stage.GetStartTimeCode(), stage.GetEndTimeCode())
        late = [d.time for d in directives if not start <= d.time <= end]
        if late:
            errors.append(site_error(prim, prim.GetPath().AppendProperty(sch.TIME), "OutOfRange",
                                 f"{sch.TIME}: {', '.join(f'{t:g}' for t in late[:3])} outside the stage's time range "
                                 f"and its animation [{start:g}, {end:g}]"))
    return errors


def gaze_object(prim: Usd.Prim, time_range=None) -> list:
    """A GazeObjectAPI: on an Xformable whose transform USD can evaluate, importance > 0 at every sample,
    radius >= 0, a known kind."""
    from pxr import UsdGeom

    errors = []
    if not prim.IsA(UsdGeom.Xformable):
        errors.append(site_error(prim, prim.GetPath(), "NotXformable",
                             f"GazeObjectAPI is applied to a {prim.GetTypeName() or 'typeless prim'}; "
                             "it needs an Xformable (the object's world transform is its state)"))
    else:  # as attend reads it: an op USD cannot evaluate, on the object or above it, is refused there
        errors += _transform_errors(prim)
    from usdgaze.usd.objects import importance_problem, is_obstacle, type_problem

    typed = {}
    for name in ("gaze:object:importance", "gaze:object:radius", "gaze:object:kind"):
        attr = prim.GetAttribute(name)
        problem = type_problem(attr) if attr and attr.HasAuthoredValue() else None
        if problem:
            errors.append(site_error(prim, attr.GetPath(), "Type", problem))
        typed[name] = attr if attr and not problem else None
    attr = typed["gaze:object:importance"]
    problem = importance_problem(attr) if attr and attr.HasAuthoredValue() else None
    if problem:
        errors.append(site_error(prim, attr.GetPath(), "Range", problem))
    radius = typed["gaze:object:radius"]
    # An obstacle's radius has its stricter range, (0, 10] m: PhysicsObstacles says it, once.
    if (radius and radius.Get() is not None and not is_obstacle(prim)
            and not (np.isfinite(radius.Get()) and radius.Get() >= 0.0)):
        errors.append(site_error(prim, radius.GetPath(), "Range", f"gaze:object:radius: {radius.Get()}, expected >= 0 m"))
    kind = typed["gaze:object:kind"]
    allowed = ("", "ballistic", "static", "moving")
    if kind and kind.Get() is not None and str(kind.Get()) not in allowed:
        errors.append(site_error(prim, kind.GetPath(), "UnknownKind",
                             f"gaze:object:kind: '{kind.Get()}', expected one of {', '.join(repr(a) for a in allowed)}"))
    return errors


def skeleton_instances(stage: Usd.Stage, time_range=None) -> list:
    """Each Skeleton under a SkelRoot, or the SkelAnimation bound to it, that lies inside an instance
    (an instance proxy, or instanceable): no override can reach it, so apply refuses it (a prim
    validator never visits an instance proxy, so the stage is walked with them)."""
    from usdgaze.usd.checks import instanced_problem
    from usdgaze.usd.skelio import skel_roots, skeletons_under

    errors = []
    for root in skel_roots(stage):
        for skel in skeletons_under(root):
            for prim in (skel, animation_of(skel)):
                problem = instanced_problem(prim)
                if problem:  # the skeleton's first: apply reads it before its animation
                    errors.append(site_error(prim, prim.GetPath(), "Instanced", problem))
                    break
    return errors


def physics_obstacles(stage: Usd.Stage, time_range=None) -> list:
    """Every prim the physics pass walks round (``usdgaze:physics:task = "obstacle"``, inside instances
    too, as attend reads them) authors its size, ``gaze:object:radius``: one value, in (0, 10] m."""
    from usdgaze.usd.objects import authored_obstacle_problem, scene_prims

    radius_attr = "gaze:object:radius"
    errors = []
    for prim in scene_prims(stage):
        problem = authored_obstacle_problem(prim)
        if problem:  # a site USD cannot find is no site: a prim without GazeObjectAPI has no such attribute
            path = prim.GetPath().AppendProperty(radius_attr) if prim.HasProperty(radius_attr) else prim.GetPath()
            errors.append(site_error(prim, path, "Radius", problem))
    return errors


STAGE_TASKS = {"GazeLayerSchedule": gaze_layer_schedule, "SkeletonInstances": skeleton_instances,
               "PhysicsObstacles": physics_obstacles}

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
