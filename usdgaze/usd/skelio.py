"""UsdSkel I/O: find skeletons and their animations on a stage and read them into numpy arrays."""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.kinematics import world_matrices
from usdgaze.core.zero_scale import singular
from usdgaze.errors import UsdGazeError
from usdgaze.usd import checks
from usdgaze.usd.clip_samples import animation_samples, rest_pose_samples
from usdgaze.usd.skinning import influence_problems
from usdgaze.usd.xformops import check_transform


def skel_roots(stage: Usd.Stage) -> list[Usd.Prim]:
    """Every SkelRoot prim on the stage (instance proxies included), in traversal order."""
    return [p for p in stage.Traverse(Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Root)]


def no_skel_root(stage: Usd.Stage, source: str) -> UsdGazeError:
    """The error for a stage without a SkelRoot; a map file (its map on a class SkelRoot) says so."""
    classes = [p for p in stage.Traverse(Usd.PrimAllPrimsPredicate) if p.IsAbstract() and p.IsA(UsdSkel.Root)]
    if classes:
        return UsdGazeError(f"{source}: no SkelRoot on the stage, only the class {classes[0].GetPath()} (a gaze map "
                            f"file: give it to apply --map, or reference it from a character's SkelRoot)")
    return UsdGazeError(f"{source}: no SkelRoot on the stage")


def skeletons_under(root: Usd.Prim) -> list[Usd.Prim]:
    """Skeleton prims below a SkelRoot, not below a SkelRoot nested in it: a skeleton is its nearest
    SkelRoot's (counted for both, the outer root's selection refused the inner one's as unselected)."""
    out = []
    prims = iter(Usd.PrimRange(root, Usd.TraverseInstanceProxies()))
    for p in prims:
        if p != root and p.IsA(UsdSkel.Root):
            prims.PruneChildren()
        elif p.IsA(UsdSkel.Skeleton):
            out.append(p)
    return out


def _animation_source(skel: Usd.Prim) -> tuple[bool, Usd.Prim | None]:
    """Whether ``skel:animationSource`` targets anything for ``skel`` (on it, or on an ancestor such as
    the SkelRoot, which UsdSkel's binding inherits down), and the SkelAnimation it binds, or None.
    Targeting nothing, UsdSkel shows the rest pose; targeting something else is a broken binding."""
    binding = UsdSkel.BindingAPI(skel)
    rel = binding.GetAnimationSourceRel()
    targets = rel.GetForwardedTargets() if rel else []
    prim = skel.GetStage().GetPrimAtPath(targets[0]) if targets else binding.GetInheritedAnimationSource()
    return bool(targets) or bool(prim), (prim if prim and prim.IsA(UsdSkel.Animation) else None)


def animation_of(skel: Usd.Prim) -> Usd.Prim | None:
    """The SkelAnimation bound to ``skel`` (on it or inherited, as UsdSkel binds it), or None."""
    return _animation_source(skel)[1]


def animations_elsewhere(stage: Usd.Stage, roots: list[Usd.Prim]) -> dict[str, str]:
    """Animation path -> a Skeleton it drives under a SkelRoot not in ``roots``."""
    chosen = {r.GetPath() for r in roots}
    out: dict[str, str] = {}
    for root in skel_roots(stage):
        if root.GetPath() in chosen:
            continue
        for skel in skeletons_under(root):
            anim = animation_of(skel)
            if anim is not None:
                out.setdefault(str(anim.GetPath()), str(skel.GetPath()))
    return out


def check_not_shared(others: dict[str, str], animation: str, source: str) -> None:
    """An animation that also drives a character not being written (``animations_elsewhere``)
    would move that one too: one line."""
    if animation in others:
        raise UsdGazeError(f"{source}:{animation}: also drives {others[animation]}, which is not selected; "
                           "an override of it would move both alike: give each character its own SkelAnimation")


def ill_formed_joint(joint: str) -> str | None:
    """Why UsdSkel cannot place the joint token ``joint`` (apply refuses it; validate says it too), or None."""
    if Sdf.Path.IsValidPathString(joint) and not Sdf.Path(joint).IsAbsolutePath():
        return None
    # UsdSkel parses joint tokens as relative paths; it reads an ill-formed one as a root joint.
    return (f"'{joint}' is not a valid joint path (UsdSkel reads an ill-formed joint as a root); use letters, "
            "digits and '_' in joint names, as exporters write 'mixamorig:Hips' as 'mixamorig_Hips'")


def joint_parents(joints: list[str], where: str) -> np.ndarray:
    """Each joint's parent index (-1 for a root), from the joint tokens' paths; a joint listed twice
    or a token that is no path is a one-line error naming ``where``."""
    index = {j: i for i, j in enumerate(joints)}
    if len(index) < len(joints):
        twice = next(j for i, j in enumerate(joints) if index[j] != i)
        raise UsdGazeError(f"{where}.joints: joint '{twice}' is listed twice")
    parents = np.full(len(joints), -1, dtype=int)
    for i, j in enumerate(joints):
        problem = ill_formed_joint(j)
        if problem:
            raise UsdGazeError(f"{where}.joints: {problem}")
        parent = j.rsplit("/", 1)[0] if "/" in j else None
        if parent is not None:
            if parent not in index or index[parent] >= i:
                raise UsdGazeError(f"{where}.joints: joint '{j}' comes before or without its parent '{parent}'")
            parents[i] = index[parent]
    return parents


def _matrices(attr: Usd.Attribute) -> np.ndarray | None:
    value = attr.Get() if attr and attr.HasAuthoredValue() else None
    if value is None or len(value) == 0:
        return None
    return rot.matrices_from_usd(np.array(value, dtype=float).reshape(-1, 4, 4))


def bind_problem(bind_world: np.ndarray | None, joints: list[str]) -> str | None:
    """Why bindTransforms cannot serve as the neutral pose, or None when it can."""
    if bind_world is None:
        return "bindTransforms is not authored"
    if len(bind_world) != len(joints):
        return f"bindTransforms has {len(bind_world)} entries, expected {len(joints)}"
    if not np.all(np.isfinite(bind_world)):
        return "bindTransforms holds NaN or infinite values"
    bad = np.flatnonzero(singular(bind_world[:, :3, :3]))
    if len(bad):
        return f"bindTransforms is singular at joint '{joints[bad[0]].rsplit('/', 1)[-1]}'"
    pos = bind_world[:, :3, 3]
    if len(joints) > 1 and np.ptp(pos, axis=0).max() <= 1e-9 * max(1.0, float(np.abs(pos).max())):
        return "bindTransforms puts every joint at one point"
    return None


def skeleton_to_world(skel: Usd.Prim, times: np.ndarray) -> np.ndarray:
    """Skeleton-space to world matrices (column-vector): one if static, else one per frame."""
    xformable = UsdGeom.Xformable(skel)
    varying = False
    prim = skel
    while prim and not prim.IsPseudoRoot():
        x = UsdGeom.Xformable(prim)
        if x and x.TransformMightBeTimeVarying():
            varying = True
            break
        prim = prim.GetParent()
    if not varying:
        at = Usd.TimeCode(float(times[0])) if len(times) else Usd.TimeCode.Default()
        return rot.matrices_from_usd(np.array(xformable.ComputeLocalToWorldTransform(at), dtype=float)[None])
    # USD has no batched evaluation of xformOps; its cache keeps the static ancestors' part between
    # frames: 6.2 us a frame against 11.9 for ComputeLocalToWorldTransform (20k frames, one animated parent).
    cache, mats = UsdGeom.XformCache(), np.empty((len(times), 4, 4))
    for i, t in enumerate(times):
        cache.SetTime(Usd.TimeCode(float(t)))
        mats[i] = cache.GetLocalToWorldTransform(skel)
    return rot.matrices_from_usd(mats)


def _skeleton_joints(skeleton: UsdSkel.Skeleton, where_skel: str) -> tuple[list[str], np.ndarray]:
    """The skeleton's joint paths and each joint's parent index (-1 for a root)."""
    joints = [str(j) for j in (skeleton.GetJointsAttr().Get() or [])]
    if not joints:
        raise UsdGazeError(f"{where_skel}.joints: the skeleton has no joints")
    return joints, joint_parents(joints, where_skel)


NEW_ANIMATION = "gazeAnimation"  # the child of an unanimated Skeleton that the layer defines and binds


def _new_animation_path(skel: Usd.Prim) -> str:
    name, k = NEW_ANIMATION, 1
    while skel.GetChild(name):
        name, k = f"{NEW_ANIMATION}{k}", k + 1
    return str(skel.GetPath().AppendChild(name))


def _bound_animation(anim_prim: Usd.Prim | None, where_skel: str, source: str) -> tuple[Usd.Prim, str]:
    """The SkelAnimation bound to the skeleton (checked like it) and its location for messages."""
    if anim_prim is None:
        raise UsdGazeError(f"{where_skel}: skel:animationSource targets no SkelAnimation; bind one, or remove the "
                           "relationship to add gaze to the rest pose")
    where_anim = f"{source}:{anim_prim.GetPath()}"
    if not anim_prim.IsActive():
        raise UsdGazeError(f"{where_anim}: the bound animation is inactive (active = false), so UsdSkel poses "
                           "the skeleton without it; activate it or bind another")
    checks.check_not_instanced(anim_prim, where_anim)
    checks.check_types(anim_prim, checks.ANIMATION_TYPES, where_anim)
    return anim_prim, where_anim


def _poses(skeleton: UsdSkel.Skeleton, joints: list[str], parents: np.ndarray, where_skel: str):
    """Rest (local), bind (world) and neutral (world) poses, and which authored pose the neutral came from."""
    rest_local = _matrices(skeleton.GetRestTransformsAttr())
    bind_authored = _matrices(skeleton.GetBindTransformsAttr())
    rest_authored = rest_local is not None
    # Broken numbers are refused (the file needs fixing); a bind pose that is merely unusable as the
    # neutral (not authored, every joint at one point) falls back to the rest pose.
    for name, m in (("restTransforms", rest_local), ("bindTransforms", bind_authored)):
        if m is not None and len(m) != len(joints):
            raise UsdGazeError(f"{where_skel}.{name}: {len(m)} entries, expected {len(joints)} (one per joint)")
        checks.check_matrices(m, joints, f"{where_skel}.{name}")
    problem = bind_problem(bind_authored, joints)
    if rest_local is None and bind_authored is None:
        raise UsdGazeError(f"{where_skel}: neither restTransforms nor bindTransforms is authored; the rest pose is unknown")
    if rest_local is None:
        if problem:
            raise UsdGazeError(f"{where_skel}.bindTransforms: {problem}, and restTransforms is not authored; "
                               "the rest pose is unknown")
        parent_world = np.where(parents[:, None, None] >= 0, bind_authored[np.maximum(parents, 0)], np.eye(4))
        rest_local = np.linalg.solve(parent_world, bind_authored)
    rest_world = world_matrices(rest_local[None], parents)[0]
    # The neutral pose is the bind pose, which the mesh (eyes included) was modelled in; DCCs write
    # restTransforms as whatever frame they exported from.
    neutral_world = rest_world if problem else bind_authored
    neutral_source = f"restTransforms ({problem})" if problem else "bindTransforms"
    # Written back (extended) when eyes are added: the input's own values where they fit the joints.
    bind_world = bind_authored if bind_authored is not None and len(bind_authored) == len(joints) else rest_world
    return rest_local, bind_world, neutral_world, neutral_source, (rest_authored, bind_authored is not None)


def _animated_joints(anim: UsdSkel.Animation, joints: list[str], skel: Usd.Prim, where_anim: str):
    """The animation's joint list and, for each of its joints, the index of that joint in the skeleton."""
    anim_joints = [str(j) for j in (anim.GetJointsAttr().Get() or [])]
    if not anim_joints:
        raise UsdGazeError(f"{where_anim}.joints: the animation names no joints")
    index = {j: i for i, j in enumerate(joints)}
    if len(set(anim_joints)) < len(anim_joints):
        seen: set[str] = set()
        twice = next(j for j in anim_joints if j in seen or seen.add(j))
        raise UsdGazeError(f"{where_anim}.joints: joint '{twice}' is listed twice")
    missing = [j for j in anim_joints if j not in index]
    if len(missing) == len(anim_joints):
        raise UsdGazeError(f"{where_anim}.joints: none of its {len(anim_joints)} joints is a joint of {skel.GetPath()} "
                           f"(the first: '{missing[0]}'), so it animates nothing")
    # UsdSkel ignores the joints a skeleton lacks (an animation made for a fuller rig); so does the
    # pass, writing their values through (-1: no skeleton joint).
    return anim_joints, np.array([index.get(j, -1) for j in anim_joints], dtype=int), missing


def check_animation(skel: Usd.Prim, source: str) -> None:
    """:func:`read_clip`'s checks of a Skeleton's bound SkelAnimation, for readers that pose it through
    UsdSkel (build-map's clips): where they fail, UsdSkel poses the rest pose with a warning."""
    where_skel = f"{source}:{skel.GetPath()}"
    joints, _ = _skeleton_joints(UsdSkel.Skeleton(skel), where_skel)
    bound, anim_prim = _animation_source(skel)
    if bound:
        anim_prim, where_anim = _bound_animation(anim_prim, where_skel, source)
        anim = UsdSkel.Animation(anim_prim)
        anim_joints, _, _ = _animated_joints(anim, joints, skel, where_anim)
        animation_samples(anim, len(anim_joints), where_anim, anim_joints)


def _joint_names(skeleton: UsdSkel.Skeleton) -> list[str] | None:
    """The skeleton's authored jointNames, or None."""
    names_attr = skeleton.GetJointNamesAttr()
    return [str(j) for j in names_attr.Get()] if names_attr and names_attr.HasAuthoredValue() else None


def _bound_samples(skel: Usd.Prim, anim_prim: Usd.Prim | None, joints: list[str], rest: np.ndarray | None,
                   source: str, notes: list[str]):
    """The bound animation's path, joints, their skeleton indices and samples (``animation_samples``'s
    times, rotations, translations, scales, held); ``notes`` gets the joints UsdSkel ignores."""
    where_skel = f"{source}:{skel.GetPath()}"
    anim_prim, where_anim = _bound_animation(anim_prim, where_skel, source)
    anim = UsdSkel.Animation(anim_prim)
    animation = str(anim_prim.GetPath())
    anim_joints, anim_to_skel, ignored = _animated_joints(anim, joints, skel, where_anim)
    checks.check_rest_covers(rest, joints, anim_to_skel, where_skel, animation)
    if ignored:
        notes.append(f"{where_anim}.joints: {len(ignored)} of its joints are not joints of {skel.GetPath()} "
                     f"('{ignored[0]}'{', ...' if len(ignored) > 1 else ''}); UsdSkel ignores them, and the layer "
                     "writes their values through unchanged")
    return animation, anim_joints, anim_to_skel, animation_samples(anim, len(anim_joints), where_anim, anim_joints)


def read_clip(stage: Usd.Stage, skel: Usd.Prim, root: Usd.Prim, source: str) -> SkelClip:
    """Read a Skeleton, its rest/bind pose and its bound animation's samples into a :class:`SkelClip`."""
    skeleton = UsdSkel.Skeleton(skel)
    where_skel = f"{source}:{skel.GetPath()}"
    checks.check_stage(stage, source)
    checks.check_not_instanced(skel, where_skel)
    checks.check_types(skel, checks.SKELETON_TYPES, where_skel)
    joints, parents = _skeleton_joints(skeleton, where_skel)
    rest_local, bind_world, neutral_world, neutral_source, authored = _poses(skeleton, joints, parents, where_skel)
    bound, anim_prim = _animation_source(skel)
    # The Skeleton's world transform, as an object's or a target's: an op USD cannot evaluate on it or a
    # prim above it stopped apply and attend with USD's internal error (exit 1).
    check_transform(skel, source)
    checks.check_arcs(stage, skel, [root, skel, anim_prim], source)
    notes: list[str] = []
    if bound:
        animation, anim_joints, anim_to_skel, samples = _bound_samples(skel, anim_prim, joints, authored[0], source,
                                                                       notes)
    else:  # the layer defines an animation holding the rest pose, with the gaze in it, and binds it
        animation = _new_animation_path(skel)
        anim_joints, anim_to_skel = list(joints), np.arange(len(joints))
        samples = (*rest_pose_samples(stage, rest_local, where_skel), True)
    times, rotations, translations, scales, held = samples
    joint_names = _joint_names(skeleton)
    skel_to_world = skeleton_to_world(skel, times)
    notes.extend(checks.check_scaled_away(skel, times, skel_to_world, source))
    skinned = influence_problems(skel)
    notes.extend(f"{source}:{p.prim.GetPath()}.{p.attribute}: {p.problem}" for p in skinned)
    return SkelClip(
        source=source,
        skel_root=str(root.GetPath()),
        skeleton=str(skel.GetPath()),
        animation=animation,
        animation_bound=bound,
        held_pose=held,
        notes=notes,
        joints=joints,
        parents=parents,
        rest_local=rest_local,
        bind_world=bind_world,
        neutral_world=neutral_world,
        neutral_source=neutral_source,
        authored_poses=authored,
        anim_joints=anim_joints,
        anim_to_skel=anim_to_skel,
        times=times,
        rotations=rotations,
        translations=translations,
        scales=scales,
        skel_to_world=skel_to_world,
        up_axis=str(UsdGeom.GetStageUpAxis(stage)),
        meters_per_unit=float(UsdGeom.GetStageMetersPerUnit(stage)),
        time_codes_per_second=float(stage.GetTimeCodesPerSecond()),
        frames_per_second=float(stage.GetFramesPerSecond()),
        start_time=float(stage.GetStartTimeCode()),
        end_time=float(stage.GetEndTimeCode()),
        joint_names=joint_names,
        stray_influences=[(f"{p.prim.GetPath()}.{p.attribute}", p.beyond) for p in skinned if p.beyond is not None],
    )
