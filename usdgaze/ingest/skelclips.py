"""Skeletal example clips (UsdSkel, keyframed or solved capture) as trial series.

The chain's orientations come from the skeleton instead of marker triangles: the skeleton-space
transforms of the last pelvis, lower-spine and upper-spine joints and of the head
(``UsdSkel.SkeletonQuery.ComputeJointSkelTransforms``), bound by name (Mixamo, CMU, Rigify, ... via
:func:`usdgaze.core.rig.bind_chain`) or explicitly by a ``[skeleton]`` table in the marker set or a TOML
sheet (``pelvis = "Hips"``, a joint name or path per role). The rests are found on the speed of
virtual markers: three points 100 mm out along the axes of each of the four chain joints (a marker
triangle's worth, so that a turn of the head alone moves markers as it does on a capture; joint
positions alone would not see it), relative to the pelvis joint (the base-of-spine reference),
in the stage's units. Up is the stage's up axis carried into skeleton space (through the
Skeleton's transform) unless the binding sets ``up_axis`` (skeleton space); forward comes from
left/right-named joints at the crop's first frame, or the binding's ``forward`` (skeleton space).
A Skeleton whose transform to the world is animated (a root control on the SkelRoot or a parent Xform)
has that transform's turn since the first sample added to the chain, and a mirrored one (a negative scale)
is reflected, so the body turns as the world sees it (a yaw toward the figure's left as the world shows it,
as ``apply`` takes one).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

from usdgaze.core import rotations as rot
from usdgaze.gaze.definition import ROLES
from usdgaze.errors import RigError, UsdGazeError
from usdgaze.usd.skelio import animation_of, check_animation, joint_parents, skeleton_to_world
from usdgaze.usd.stage import open_stage
from usdgaze.core.kinematics import snap_up
from usdgaze.core.zero_scale import singular
from usdgaze.core.names import names_not_read, spelled_with_names
from usdgaze.core.rig import bind_chain, character_frame, leaf
from usdgaze.ingest.frames import UPRIGHT_DEG, off_upright
from usdgaze.ingest.markers import SkeletonBinding, parse_axis
from usdgaze.ingest.series import TrialSeries


VIRTUAL_MARKER_MM = 100.0
"""How far out along each chain joint's axes the virtual markers for rest detection sit."""


class SkeletonClipError(UsdGazeError):
    """A UsdSkel example clip cannot be read."""


def _open(path: Path, where: str) -> Usd.Stage:
    return open_stage(path, where, error=SkeletonClipError)


def _skeleton(stage: Usd.Stage, path: str | None, where: str) -> UsdSkel.Skeleton:
    if path:
        prim = stage.GetPrimAtPath(path)
        if not prim or not prim.IsA(UsdSkel.Skeleton):
            raise SkeletonClipError(f"{where}: {path} is not a Skeleton prim")
        return UsdSkel.Skeleton(prim)
    found = [p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)]
    # Bound on the Skeleton or inherited from an ancestor (the SkelRoot), as UsdSkel and apply bind it.
    animated = [p for p in found if animation_of(p) is not None]
    if not animated:
        raise SkeletonClipError(f"{where}: no Skeleton with a bound SkelAnimation")
    if len(animated) > 1:
        raise SkeletonClipError(f"{where}: {len(animated)} animated skeletons; name one in the sheet's skeleton column")
    return UsdSkel.Skeleton(animated[0])


def _resolve(binding: SkeletonBinding, joints: list[str], where: str,
             spelled: list[str] | None = None) -> dict[str, tuple[str, ...]]:
    """Role -> joint paths from names or paths (a name matches a joint's leaf, namespaces ignored), as
    ``spelled`` spells the skeleton's ``joints`` (with its jointNames, say): a joint may be named
    either way (its token ``j5``, as inspect lists it, was not found among the names)."""
    spelled = joints if spelled is None else spelled
    out = {}
    for role, name in binding.joints.items():
        if role not in ROLES:
            raise SkeletonClipError(f"{where}: unknown skeleton role '{role}' (roles: {', '.join(ROLES)})")
        hits = _named(name, joints) or _named(name, spelled)
        if not hits:
            raise SkeletonClipError(f"{where}: skeleton.{role} = '{name}' is not a joint of the skeleton")
        if len(hits) > 1:
            raise SkeletonClipError(f"{where}: skeleton.{role} = '{name}' matches {len(hits)} joints; give the joint path")
        out[role] = (spelled[hits[0]],)
    return out


def _named(name: str, joints: list[str]) -> list[int]:
    """Indices of the joints ``name`` names: its path, else its leaf (then ignoring case)."""
    if name in joints:
        return [joints.index(name)]
    return ([i for i, j in enumerate(joints) if leaf(j) == leaf(name)]
            or [i for i, j in enumerate(joints) if leaf(j).lower() == leaf(name).lower()])


def _skel_query(skel: UsdSkel.Skeleton, where: str) -> tuple[UsdSkel.SkeletonQuery, list[float]]:
    """The skeleton's query (through its SkelRoot where it has one) and its animation's time samples."""
    # Joint tokens UsdSkel cannot parse ('mixamorig:Hips') are read as roots: checked as apply checks them,
    # before USD warns once per joint and the chain is then said to have no pelvis.
    joint_parents([str(j) for j in (skel.GetJointsAttr().Get() or [])], f"{where}: {skel.GetPath()}")
    root = UsdSkel.Root.Find(skel.GetPrim())
    cache = UsdSkel.Cache()
    if root:
        cache.Populate(root, Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(skel)
    if not query:
        raise SkeletonClipError(f"{where}: {skel.GetPath()} is not a valid skeleton (joints, rest transforms)")
    anim = query.GetAnimQuery()
    times = list(anim.GetJointTransformTimeSamples()) if anim else []
    if len(times) < 2:
        raise SkeletonClipError(f"{where}: {skel.GetPath()} has no animation (fewer than 2 time samples)")
    return query, times


def _bound_chain(query: UsdSkel.SkeletonQuery, binding: SkeletonBinding, where: str):
    """The skeleton's joints and its bound chain, with a hint for build-map when binding fails.

    Where the joint paths' words tell nothing (generic tokens such as ``j0/j1``), the paths spelled
    with the skeleton's ``jointNames`` are bound instead, as ``apply`` does."""
    joints = [str(j) for j in query.GetJointOrder()]
    parents = np.array(query.GetTopology().GetParentIndices(), dtype=int)
    names_attr = query.GetSkeleton().GetJointNamesAttr()
    names = names_attr.Get() if names_attr.HasAuthoredValue() else None
    named = spelled_with_names(joints, parents, names)
    first = None
    for spelled in [joints] + ([named] if named else []):
        try:
            return spelled, bind_chain(spelled, parents, _resolve(binding, joints, where, spelled), where)
        except (RigError, SkeletonClipError) as exc:
            first = first or exc
    if isinstance(first, SkeletonClipError):
        raise first
    raise SkeletonClipError(f"{first}{names_not_read(joints, names)} (for build-map: name the joints in a [skeleton] table of the marker set or TOML sheet)") from None


def _frame_times(stage: Usd.Stage, times: list[float], where: str) -> tuple[list[float], float]:
    """Times to sample (sub-frame samples as they are, else every time code) and their rate in Hz."""
    rate = float(stage.GetTimeCodesPerSecond())
    step = float(np.min(np.diff(times)))
    if step < 1.0 - 1e-6:
        # Sub-frame samples: read them as they are if they are evenly spaced.
        if np.any(np.abs(np.diff(times) - step) > 1e-6):
            raise SkeletonClipError(f"{where}: sub-frame time samples are not evenly spaced; resample the clip")
        rate /= step
    else:
        # One sample per time code; keys further apart (keyframed clips) are interpolated by UsdSkel.
        times = list(np.arange(times[0], times[-1] + 1e-9, 1.0))
    return times, rate


def _virtual_markers(world: np.ndarray, chain_world: np.ndarray, pelvis: int, meters: float) -> np.ndarray:
    """Three points out along each chain joint's axes ``(F, 12, 3)``, relative to the pelvis joint."""
    reach = VIRTUAL_MARKER_MM / (meters * 1000.0)
    axes = chain_world[..., :3, :3] / np.linalg.norm(chain_world[..., :3, :3], axis=-2, keepdims=True)
    points = chain_world[..., None, :3, 3] + reach * np.swapaxes(axes, -1, -2)  # (F, 4, 3 axes, xyz)
    return points.reshape(len(world), -1, 3) - world[:, pelvis, :3, 3][:, None, :]


def _to_world(skel: UsdSkel.Skeleton, time: float) -> np.ndarray:
    """The Skeleton's skeleton-to-world matrix ``(4, 4)`` (column vectors) at ``time``."""
    return rot.matrices_from_usd(np.array(
        UsdGeom.Xformable(skel.GetPrim()).ComputeLocalToWorldTransform(Usd.TimeCode(float(time))), dtype=float))


def _skeleton_up(stage: Usd.Stage, to_world: np.ndarray, binding: SkeletonBinding, where: str) -> np.ndarray:
    """Up in skeleton space: the binding's, else the stage's up axis through the Skeleton's transform."""
    if binding.up_axis:
        return parse_axis(binding.up_axis, where)  # given in skeleton space
    # The stage's up axis carried into skeleton space (a rig may sit under a rotating Xform);
    # snapped to the skeleton's axis, as apply takes it: a rig on a slope is upright in its own space.
    return snap_up(np.linalg.solve(to_world[:3, :3], parse_axis(str(UsdGeom.GetStageUpAxis(stage)), where)))


def _check_up(head: np.ndarray, up: np.ndarray, stage: Usd.Stage, binding: SkeletonBinding, where: str) -> None:
    """Refuse an up axis the rig does not stand along (a Z-up rig in a stage that says Y): nothing
    further on fails, the examples only ask the eyes to turn past their range."""
    angle, seen = off_upright(head, up)
    if angle > UPRIGHT_DEG:
        said = (f"[skeleton] up_axis {binding.up_axis}" if binding.up_axis
                else f"the stage's upAxis {UsdGeom.GetStageUpAxis(stage)}")
        raise SkeletonClipError(f"{where}: the head joint is {angle:.0f} deg from {said} (seen from the pelvis, the "
                                f"rig's up is {seen} in skeleton space); set up_axis = \"{seen.lstrip('+')}\" in a "
                                "[skeleton] table of the sheet or marker set")


def read_skeleton_series(path: str | Path, binding: SkeletonBinding = SkeletonBinding(), skeleton: str | None = None,
                         where: str | None = None) -> TrialSeries:
    """Read a UsdSkel clip into a :class:`TrialSeries` (skeleton space)."""
    path = Path(path)
    where = where or str(path)
    stage = _open(path, where)
    skel = _skeleton(stage, skeleton or binding.skeleton, where)
    query, times = _skel_query(skel, where)
    try:  # as apply checks it: UsdSkel poses the rest pose where a sample is unusable, and warns
        check_animation(skel.GetPrim(), str(path))
    except UsdGazeError as exc:
        raise SkeletonClipError(f"{where}: {exc}") from None
    joints, chain = _bound_chain(query, binding, where)
    landmarks = [chain.roles["pelvis"][-1], chain.roles["lowerSpine"][-1], chain.roles["upperSpine"][-1], chain.head]
    times, rate = _frame_times(stage, times, where)

    # One USD call per sample; everything after is vectorized over frames.
    world = rot.matrices_from_usd(
        np.stack([np.array(query.ComputeJointSkelTransforms(Usd.TimeCode(float(t))), dtype=float) for t in times])
    )
    chain_world = world[:, landmarks]
    orientations = rot.from_matrix(chain_world[..., :3, :3])
    to_world = _to_world(skel, times[0])
    # Metres per skeleton unit: the stage's unit times the Skeleton's own scale in the world (a rig
    # scaled 0.01 under its SkelRoot in a metre stage was read in metres, its rest found in the wrong units).
    meters = float(UsdGeom.GetStageMetersPerUnit(stage)) * float(abs(np.linalg.det(to_world[:3, :3]))) ** (1.0 / 3.0)
    if not (np.isfinite(meters) and meters > 0.0):
        raise SkeletonClipError(f"{where}: the Skeleton's transform to the world is degenerate (scale {meters:g} m a unit)")
    points = _virtual_markers(world, chain_world, chain.pelvis, meters)
    up = _skeleton_up(stage, to_world, binding, where)
    _check_up(world[:, chain.head, :3, 3] - world[:, chain.pelvis, :3, 3], up, stage, binding, where)
    forward = None if binding.forward is None else np.asarray(binding.forward, dtype=float)

    def named_frame(i: int) -> np.ndarray:
        return character_frame(joints, world[i], up, forward, f"{where} frame {i}").rotation

    view = _world_view(skel, times, lambda: rot.rotate(named_frame(0), np.array([1.0, 0.0, 0.0])))

    def frame_at(i: int) -> np.ndarray:
        return named_frame(i) if view is None else _seen_frame(view, i, named_frame(i))

    if view is not None:  # the chain as the world sees it, in the skeleton's space at the first sample
        orientations, points = _seen(view, orientations, points)
    return TrialSeries(
        source=where,
        orientations=orientations,
        points=points,
        frame_at=frame_at,
        rate=rate,
        units=f"{meters:g} m",
        mm_per_unit=meters * 1000.0,
        numbering=_numbering(times),
    )


def _world_view(skel: UsdSkel.Skeleton, times: list[float], left_at_start) -> tuple[np.ndarray, np.ndarray] | None:
    """How the world sees skeleton space, as ``(V, flip)``: ``V (F or 1, 3, 3)`` each sample's turn of the
    Skeleton's transform to the world since the first sample (in skeleton space), reflected by ``flip``
    across the character's left axis (``left_at_start()``, skeleton space) where that transform mirrors;
    None where skeleton space is the world's view (a static, unmirrored transform).

    A rig turned by an animated SkelRoot or parent Xform (a DCC's root control) turns its body with it:
    measured in skeleton space alone that turn was lost (20 deg of joints on a 10 deg root gave a map of
    20). A mirrored one (a clip scaled by -1 to make a left turn of a right one) turns as the world shows
    it, as apply's yaw does: read in skeleton space its head turned the other way from its target."""
    to_world = skeleton_to_world(skel.GetPrim(), np.asarray(times, dtype=float))
    linear = to_world[:, :3, :3]
    # A sample scaled to nothing (a character hidden for a while) has no turn: it keeps the last one seen.
    # The first sample is refused before this, by the unit the Skeleton's scale gives it.
    hidden = ~np.isfinite(linear).all(axis=(-2, -1))
    hidden[~hidden] = singular(linear[~hidden])
    mirrored = not hidden[0] and np.linalg.det(linear[0]) < 0.0
    if hidden[0] or (len(linear) == 1 and not mirrored):
        return None
    linear = linear[np.maximum.accumulate(np.where(hidden, 0, np.arange(len(linear))))]
    turns = rot.to_matrix(rot.from_matrix(np.linalg.inv(linear[0]) @ linear))
    flip = np.eye(3)
    if mirrored:
        left = np.asarray(left_at_start(), dtype=float)
        flip = flip - 2.0 * np.outer(left, left)
    return flip @ turns, flip


def _seen(view: tuple[np.ndarray, np.ndarray], orientations: np.ndarray, points: np.ndarray):
    """Orientations ``(F, L, 4)`` and points ``(F, P, 3)`` of skeleton space as :func:`_world_view` sees them."""
    v, flip = view
    v = np.broadcast_to(v, (len(points), 3, 3))
    seen = v[:, None] @ rot.to_matrix(orientations) @ flip
    return rot.from_matrix(seen), np.einsum("fij,fpj->fpi", v, points)


def _seen_frame(view: tuple[np.ndarray, np.ndarray], i: int, frame: np.ndarray) -> np.ndarray:
    """The character frame at sample ``i`` as :func:`_world_view` sees it: a mirrored one's left is the
    world's left of the figure, where its right-named joints show."""
    v, flip = view
    canonical_flip = np.diag([-1.0, 1.0, 1.0]) if np.linalg.det(flip) < 0 else np.eye(3)
    return rot.from_matrix(v[min(i, len(v) - 1)] @ rot.to_matrix(frame) @ canonical_flip)


def _numbering(times: list[float]) -> str:
    """The clip's time codes in words where they are not 0, 1, 2 ... (a shot starting at 1001)."""
    if times[0] == 0.0 and times[-1] == len(times) - 1:
        return ""
    return f"their time codes run {times[0]:g}-{times[-1]:g}"
