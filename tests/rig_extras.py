"""Joints added to or changed on a synthetic rig after it is written: a production rig's helpers (UE5's
twist and IK joints) on top of :mod:`tests.synthetic`'s body, a joint mirrored by a negative scale.
Test support; pxr only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Gf, Usd, UsdSkel, Vt


def add_joints(path: str | Path, extra: list[tuple[str, str | None, tuple, bool]], twist_deg: float = 20.0) -> None:
    """Append joints ``(name, parent leaf name or None, world position at bind, twists)`` to the rig's
    Skeleton and SkelAnimation, saved in place: identity bind rotation, the bind offset as their
    animated translation, and a rotation about their bone of up to ``twist_deg`` where ``twists``."""
    stage = Usd.Stage.Open(str(path))
    root = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Root))
    skel = UsdSkel.Skeleton(next(p for p in Usd.PrimRange(root) if p.IsA(UsdSkel.Skeleton)))
    anim = UsdSkel.Animation(next(p for p in Usd.PrimRange(root) if p.IsA(UsdSkel.Animation)))
    joints = [str(j) for j in skel.GetJointsAttr().Get()]
    by_leaf = {j.rsplit("/", 1)[-1]: j for j in joints}
    bind = list(skel.GetBindTransformsAttr().Get())
    rest = list(skel.GetRestTransformsAttr().Get())
    anim_joints = [str(j) for j in anim.GetJointsAttr().Get()]
    attrs = (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr())
    times = attrs[0].GetTimeSamples()
    rot, trans, scale = ([np.array(a.Get(t)) for t in times] for a in attrs)
    for name, parent, world_pos, twists in extra:
        parent_world = bind[joints.index(by_leaf[parent])] if parent else Gf.Matrix4d(1)
        world = Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(*map(float, world_pos)))
        local = (world * parent_world.GetInverse()).ExtractTranslation()
        path_ = f"{by_leaf[parent]}/{name}" if parent else name
        joints.append(path_)
        anim_joints.append(path_)
        by_leaf[name] = path_
        bind.append(world)
        rest.append(Gf.Matrix4d(1).SetTranslate(local))
        axis = np.array(local) / (np.linalg.norm(local) or 1.0)
        for k in range(len(times)):
            a = np.radians(twist_deg) * np.sin(2 * np.pi * k / max(len(times), 2)) if twists else 0.0
            rot[k] = np.vstack([rot[k], np.r_[np.sin(a / 2) * axis, np.cos(a / 2)][None].astype(np.float32)])
            trans[k] = np.vstack([trans[k], np.array(local, dtype=np.float32)[None]])
            scale[k] = np.vstack([scale[k], np.ones((1, 3), dtype=np.float16)])
    skel.GetJointsAttr().Set(Vt.TokenArray(joints))
    skel.GetBindTransformsAttr().Set(Vt.Matrix4dArray(bind))
    skel.GetRestTransformsAttr().Set(Vt.Matrix4dArray(rest))
    if skel.GetJointNamesAttr().HasAuthoredValue():
        skel.GetJointNamesAttr().Set(Vt.TokenArray([j.rsplit("/", 1)[-1] for j in joints]))
    anim.GetJointsAttr().Set(Vt.TokenArray(anim_joints))
    for k, t in enumerate(times):
        attrs[0].Set(Vt.QuatfArray.FromNumpy(rot[k].astype(np.float32)), t)
        attrs[1].Set(Vt.Vec3fArray.FromNumpy(trans[k].astype(np.float32)), t)
        attrs[2].Set(Vt.Vec3hArray.FromNumpy(scale[k].astype(np.float16)), t)
    stage.GetRootLayer().Save()


def _bind_positions(rig) -> dict[str, np.ndarray]:
    """Each joint's (leaf name's) position at bind, in the rig's skeleton space."""
    stage = Usd.Stage.Open(str(rig.path))
    skel = UsdSkel.Skeleton(next(p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)))
    bind = np.array(skel.GetBindTransformsAttr().Get())
    return {str(j).rsplit("/", 1)[-1]: bind[i][3, :3] for i, j in enumerate(skel.GetJointsAttr().Get())}


def ue5_helpers(rig) -> list[tuple[str, str | None, tuple, bool]]:
    """UE5 mannequin-style helpers for a ``convention="ue"`` rig: a twist joint halfway along each
    upper arm, forearm, thigh and calf (animated), and the IK joints under ``root`` (still)."""
    pos = _bind_positions(rig)
    extra = []
    for s in "lr":
        for bone, end in (("upperarm", "lowerarm"), ("lowerarm", "hand"), ("thigh", "calf"), ("calf", "foot")):
            extra.append((f"{bone}_twist_01_{s}", f"{bone}_{s}", tuple(0.5 * (pos[f"{bone}_{s}"] + pos[f"{end}_{s}"])), True))
    origin = (0.0, 0.0, 0.0)
    extra += [("ik_foot_root", "root", origin, False), ("ik_foot_l", "ik_foot_root", tuple(pos["foot_l"]), False),
              ("ik_foot_r", "ik_foot_root", tuple(pos["foot_r"]), False), ("ik_hand_root", "root", origin, False),
              ("ik_hand_gun", "ik_hand_root", tuple(pos["hand_r"]), False),
              ("ik_hand_r", "ik_hand_gun", tuple(pos["hand_r"]), False),
              ("ik_hand_l", "ik_hand_gun", tuple(pos["hand_l"]), False)]
    return extra


def secondary_chains(rig) -> list[tuple[str, str | None, tuple, bool]]:
    """Chains off the body's frame on a ``convention="ue"`` rig (animated): a jaw with its chin and
    a three-joint ponytail below the head, a three-joint skirt panel on the pelvis (VRoid's
    ``J_Sec_*`` spring chains, a facial rig's jaw)."""
    pos = _bind_positions(rig)
    at = lambda joint, *d: tuple(pos[joint] + np.array(d))  # noqa: E731  (offsets in the rig's Y-up metres)
    return [("jaw", "head", at("head", 0, 0.02, 0.03), True), ("chin", "jaw", at("head", 0, -0.05, 0.09), False),
            ("hair_01", "head", at("head", 0, 0.1, -0.08), True), ("hair_02", "hair_01", at("head", 0, 0, -0.14), True),
            ("hair_03", "hair_02", at("head", 0, -0.12, -0.16), True),
            ("skirt_01", "pelvis", at("pelvis", 0.1, -0.1, 0.1), True),
            ("skirt_02", "skirt_01", at("pelvis", 0.12, -0.3, 0.12), True),
            ("skirt_03", "skirt_02", at("pelvis", 0.13, -0.45, 0.13), False)]


def mirror_joint(path: str | Path, skeleton: str, animation: str, leaf: str) -> None:
    """Mirror joint ``leaf`` along its own x: its local x row (UsdSkel matrices are row-vector)
    negated in the rest transforms, the bind transforms at and below it recomputed, and a scale of
    (-1, 1, 1) in the animation. Positions stay; the frames' handedness changes."""
    scale_joint(path, skeleton, animation, leaf, (-1.0, 1.0, 1.0))


def scale_joint(path: str | Path, skeleton: str, animation: str, leaf: str, scale: tuple) -> None:
    """Scale joint ``leaf`` by ``scale`` along its own axes: its local rows scaled in the rest transforms,
    the bind transforms at and below it recomputed, and ``scale`` in the animation at every sample."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(path))
    stage = Usd.Stage.Open(layer)
    skel = stage.GetPrimAtPath(skeleton)
    joints = [str(j) for j in skel.GetAttribute("joints").Get()]
    j = next(i for i, name in enumerate(joints) if name.rsplit("/", 1)[-1] == leaf)
    below = [i for i, name in enumerate(joints) if name.startswith(joints[j] + "/")]
    rest = np.array(skel.GetAttribute("restTransforms").Get())
    bind = np.array(skel.GetAttribute("bindTransforms").Get())
    rest[j] = np.diag([*map(float, scale), 1.0]) @ rest[j]
    skel.GetAttribute("restTransforms").Set(Vt.Matrix4dArray.FromNumpy(rest))
    # Bind transforms (skeleton space) of the joint and those below: rest FK from the parent's bind.
    index = {name: i for i, name in enumerate(joints)}
    for i in [j, *below]:
        parent = joints[i].rsplit("/", 1)[0]
        bind[i] = rest[i] @ bind[index[parent]] if parent in index else rest[i]
    skel.GetAttribute("bindTransforms").Set(Vt.Matrix4dArray.FromNumpy(bind))
    anim = stage.GetPrimAtPath(animation)
    anim_joints = [str(x) for x in anim.GetAttribute("joints").Get()]
    k = anim_joints.index(joints[j])
    scales = anim.GetAttribute("scales")
    times = scales.GetTimeSamples()
    for t in times or [Usd.TimeCode.Default()]:
        s = np.array(scales.Get(t), dtype=float)
        s[k] = scale
        scales.Set(Vt.Vec3hArray([Gf.Vec3h(*map(float, v)) for v in s]), t)
    layer.Save()


def insert_face_root(rig, turn_deg: float, turn_axis=None, orient_deg: float = 35.0, name: str = "FaceRoot",
                     scale: tuple = (1.0, 1.0, 1.0)) -> tuple[str, str]:
    """Put a joint ``name`` between the head and both eyes of a synthetic rig written with ``mesh=False``
    (a face rig's root, as production rigs hang the eyes under), saved in place; returns the eyes' new
    paths. Its bind frame is the head's turned ``orient_deg`` about a skewed axis (its own joint orient);
    its animated local rotation is its bind-pose one turned ``turn_deg`` more about ``turn_axis`` (skeleton
    space as the bind pose has it; default the rig's up: a yaw), so the eyes ride ``turn_deg`` away from
    their bind-pose relation to the head (0: a consistent rig). ``scale``: its animated local scale. The eyes keep
    their bind transforms and their animated pose relative to the head at ``turn_deg`` 0."""
    stage = Usd.Stage.Open(str(rig.path))
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(rig.skeleton))
    anim = UsdSkel.Animation(stage.GetPrimAtPath(rig.animation))
    joints = [str(j) for j in skel.GetJointsAttr().Get()]
    head, eyes = rig.joint("head"), [rig.joint("eye_l"), rig.joint("eye_r")]
    face = f"{head}/{name}"
    moved = {e: f"{face}/{e.rsplit('/', 1)[-1]}" for e in eyes}
    bind = np.array(skel.GetBindTransformsAttr().Get())  # row-vector skeleton-space matrices
    rest = np.array(skel.GetRestTransformsAttr().Get())
    h = joints.index(head)
    orient = _turn(orient_deg, (0.3, 1.0, 0.5))
    face_bind = bind[h].copy()
    face_bind[:3, :3] = orient @ bind[h, :3, :3]
    face_bind[3, :3] = 0.5 * (bind[joints.index(eyes[0]), 3, :3] + bind[joints.index(eyes[1]), 3, :3]) - 0.04 * bind[h, 1, :3]
    face_local = face_bind @ np.linalg.inv(bind[h])
    at = min(joints.index(e) for e in eyes)  # parents before children, as UsdSkel orders them
    new_joints = [moved.get(j, j) for j in joints]
    new_joints.insert(at, face)
    for name_, m in (("bindTransforms", np.insert(bind, at, face_bind, axis=0)),
                     ("restTransforms", _relocal(np.insert(rest, at, face_local, axis=0), eyes, joints, at, face_local))):
        (skel.GetBindTransformsAttr() if name_ == "bindTransforms" else skel.GetRestTransformsAttr()).Set(
            Vt.Matrix4dArray.FromNumpy(m))
    skel.GetJointsAttr().Set(Vt.TokenArray(new_joints))
    if skel.GetJointNamesAttr().HasAuthoredValue():
        names = [str(n) for n in skel.GetJointNamesAttr().Get()]
        names.insert(at, name)
        skel.GetJointNamesAttr().Set(Vt.TokenArray(names))
    axis = np.asarray(rig.up if turn_axis is None else turn_axis, dtype=float) @ face_bind[:3, :3].T  # into the face's frame
    _reanimate_under_face(anim, eyes, moved, face, face_local, _turn(turn_deg, axis), scale)
    stage.GetRootLayer().Save()
    return moved[eyes[0]], moved[eyes[1]]


def _turn(deg: float, axis: tuple) -> np.ndarray:
    """A 3x3 row-vector rotation of ``deg`` about ``axis``."""
    from scipy.spatial.transform import Rotation as R

    a = np.asarray(axis, dtype=float)
    return R.from_rotvec(np.radians(deg) * a / np.linalg.norm(a)).as_matrix().T


def _relocal(rest: np.ndarray, eyes: list[str], joints: list[str], at: int, face_local: np.ndarray) -> np.ndarray:
    """Rest transforms with the eyes' locals re-expressed under the face joint (row vectors)."""
    out = rest.copy()
    for e in eyes:
        k = joints.index(e) + 1  # shifted by the inserted joint
        out[k] = rest[k] @ np.linalg.inv(face_local)
    return out


def _reanimate_under_face(anim, eyes: list[str], moved: dict, face: str, face_local: np.ndarray,
                          turn: np.ndarray, scale: tuple) -> None:
    """The animation with the face joint listed (its bind-pose local rotation turned by ``turn``) and the
    eyes' animated locals re-expressed under its bind-pose local, so at no turn the pose is unchanged."""
    from scipy.spatial.transform import Rotation as R

    joints = [str(j) for j in anim.GetJointsAttr().Get()]
    attrs = (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr())
    inv = np.linalg.inv(face_local)
    face_q = R.from_matrix((turn @ face_local[:3, :3]).T).as_quat().astype(np.float32)
    for t in attrs[0].GetTimeSamples():
        q, tr, s = (np.array(a.Get(t), dtype=float) for a in attrs)
        for e in eyes:
            k = joints.index(e)
            m = np.eye(4)
            m[:3, :3] = R.from_quat(q[k]).as_matrix().T
            m[3, :3] = tr[k]
            m = m @ inv
            q[k], tr[k] = R.from_matrix(m[:3, :3].T).as_quat(), m[3, :3]
        q, tr, s = np.vstack([q, face_q]), np.vstack([tr, face_local[3, :3]]), np.vstack([s, np.array(scale, dtype=float)[None]])
        attrs[0].Set(Vt.QuatfArray.FromNumpy(q.astype(np.float32)), t)
        attrs[1].Set(Vt.Vec3fArray.FromNumpy(tr.astype(np.float32)), t)
        attrs[2].Set(Vt.Vec3hArray.FromNumpy(s.astype(np.float16)), t)
    anim.GetJointsAttr().Set(Vt.TokenArray([moved.get(j, j) for j in joints] + [face]))


def split_bone(path: str | Path, parent_leaf: str, child_leaf: str, new_leaf: str, new_name: str) -> None:
    """Split the bone from joint ``parent_leaf`` to its child ``child_leaf`` in two (Rigify's DEF-shin.L and
    DEF-shin.L.001): a joint ``new_leaf`` (DCC name ``new_name``) halfway along it, turned as its parent,
    held still in the animation; the child and its subtree re-parented under it, posed where they were."""
    stage = Usd.Stage.Open(str(path))
    skel = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    anim = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
    joints = [str(j) for j in skel.GetAttribute("joints").Get()]
    c = next(i for i, j in enumerate(joints) if j.rsplit("/", 1)[-1] == child_leaf)
    parent, child = joints[c].rsplit("/", 1)[0], joints[c]
    assert parent.rsplit("/", 1)[-1] == parent_leaf
    new = f"{parent}/{new_leaf}"
    moved = lambda j: new + j[len(parent):] if j == child or j.startswith(child + "/") else j  # noqa: E731
    rest, bind = (np.array(skel.GetAttribute(a).Get()) for a in ("restTransforms", "bindTransforms"))
    half = np.eye(4)
    half[3, :3] = 0.5 * rest[c][3, :3]  # row-vector matrices: the translation is the last row
    rest[c][3, :3] -= half[3, :3]
    p = joints.index(parent)
    skel.GetAttribute("joints").Set(Vt.TokenArray(np.insert(np.array([moved(j) for j in joints], dtype=object), c, new).tolist()))
    skel.GetAttribute("restTransforms").Set(Vt.Matrix4dArray.FromNumpy(np.insert(rest, c, half, axis=0)))
    skel.GetAttribute("bindTransforms").Set(Vt.Matrix4dArray.FromNumpy(np.insert(bind, c, half @ bind[p], axis=0)))
    names = skel.GetAttribute("jointNames")
    if names.HasAuthoredValue():
        names.Set(Vt.TokenArray(np.insert(np.array(list(names.Get()), dtype=object), c, new_name).tolist()))
    listed = [str(j) for j in anim.GetAttribute("joints").Get()]
    k = listed.index(child)
    anim.GetAttribute("joints").Set(Vt.TokenArray([moved(j) for j in listed] + [new]))
    extra = {"rotations": (0.0, 0.0, 0.0, 1.0), "translations": half[3, :3], "scales": (1.0, 1.0, 1.0)}
    for name, value in extra.items():
        attr = anim.GetAttribute(name)
        for t in attr.GetTimeSamples():
            v = np.array(attr.Get(t))
            if name == "translations":
                v[k] -= half[3, :3]
            attr.Set(type(attr.Get(t)).FromNumpy(np.ascontiguousarray(np.vstack([v, np.array(value, dtype=v.dtype)]))), t)
    stage.GetRootLayer().Save()
