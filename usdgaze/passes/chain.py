"""The body step of the gaze passes: the rig with its eyes, the base motion's pose and line of sight,
and the chain driven by per-frame segment offsets with the legs counter-rotated (pure numpy).

P+ offsets are parent-relative rotations in the character frame; on the rig each one is applied in its
joint's parent frame as that frame sits in the neutral (bind) pose, spread evenly over the joints sharing
a role (neck and head share the neck segment). The pelvis turns in its heading frame. The leg roots
under the pelvis counter-rotate so the legs keep their base world pose.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.kinematics import Pose, forward, with_ancestors
from usdgaze.core.rig import CharacterFrame, Chain
from usdgaze.errors import UsdGazeError
from usdgaze.passes.sight import azimuth_elevation, directions_to_world
from usdgaze.passes.options import PassOptions

NECK_SEGMENT = 3
SEGMENT_OF_ROLE = {"pelvis": 0, "lowerSpine": 1, "upperSpine": 2, "neck": NECK_SEGMENT, "head": NECK_SEGMENT}


@dataclass
class Rig:
    """The skeleton as the pass sees it: the clip's joints plus added eyes, and per-joint locals."""

    clip: SkelClip
    joints: list[str]
    parents: np.ndarray
    rest_local: np.ndarray
    rest_q: np.ndarray
    """Neutral-pose (bind pose) skeleton-space rotations per joint: where each joint looks ahead. Only
    the joints a pass turns or aims from have one (the chain, the eyes and their ancestors); NaN
    elsewhere."""
    eyes: tuple[int, int]
    added: list[str]
    added_t: dict[int, np.ndarray]
    head: int
    """The head joint: the eyes' range and aim are measured in its frame, whatever joints hang between."""

    def __post_init__(self) -> None:
        # Each joint's columns are read and converted once, however many steps look at them.
        self.local = functools.lru_cache(maxsize=None)(self._local)

    def _local(self, j: int):
        f = len(self.clip.times)
        if j < len(self.clip.joints):
            return self.clip.local_trs(j)
        return np.broadcast_to(self.added_t[j], (f, 3)), np.broadcast_to(rot.IDENTITY, (f, 4)), np.broadcast_to(1.0, (f, 3))


def _check_unmirrored(clip: SkelClip, chain: Chain, rest_world: np.ndarray) -> None:
    """The chain and everything above it must not be mirrored in the neutral pose: its turns are
    rotations of right-handed frames. A mirrored joint elsewhere (a hand, a leg, an eye: a negative
    scale, as some rigs mirror one side) is carried as it is."""
    above = with_ancestors(list(chain.path), clip.parents)
    det = np.linalg.det(rest_world[above, :3, :3])
    if np.any(det <= 0.0):
        k = int(np.argmax(det <= 0.0))
        raise UsdGazeError(f"{clip.source}:{clip.skeleton}: joint '{clip.joints[above[k]]}' of the gaze chain is mirrored "
                           f"in the {clip.neutral_source.split(' ')[0]} (its transform's determinant is {det[k]:.3g}, a "
                           f"negative scale); the chain from the skeleton's root to the head must be unmirrored (mirror "
                           f"the SkelRoot's transform instead)")


def _free_path(path: str, taken: set[str]) -> str:
    """``path``, or ``path`` numbered (``LeftEye1``, ...) where a joint of that path is ``taken``."""
    k, out = 1, path
    while out in taken:
        out, k = f"{path}{k}", k + 1
    return out


def _check_no_stray_influence(clip: SkelClip) -> None:
    """The eyes are added as the skeleton's next two joints: a mesh skinned by one of those indices
    (an index past its joints, which UsdSkel cannot skin by) would have its vertices follow an eye."""
    n = len(clip.joints)
    for where, index in clip.stray_influences:
        if index < n + 2:
            raise UsdGazeError(
                f"{clip.source}:{where}: index {index} is out of range for the {n} joints of {clip.skeleton}, and the "
                f"eye joints this adds would be joints {n} and {n + 1}, so the mesh would follow an eye; fix the "
                "mesh's joint indices, or bind the rig's own eye joints (--bind leftEye=JOINT --bind rightEye=JOINT)")


def with_eyes(clip: SkelClip, chain: Chain, frame: CharacterFrame, options: PassOptions) -> Rig:
    """The rig with its eye joints: existing ones, or a left and a right added under the head."""
    rest_world = clip.neutral()
    _check_unmirrored(clip, chain, rest_world)
    # Each matrix's rotation is its own (an SVD apiece): only those of the joints read are taken.
    read = with_ancestors(list(chain.path) + list(chain.eyes or ()), clip.parents)
    rest_q = np.full((len(rest_world), 4), np.nan)
    rest_q[read] = rot.rotation_part(rest_world[read, :3, :3])[0]
    if chain.eyes is not None:
        return Rig(clip, list(clip.joints), clip.parents, clip.rest_local, rest_q, chain.eyes, [], {}, chain.head)
    head = chain.head
    _check_no_stray_influence(clip)
    # Eye placement scales with the character: the head joint (skull base) of an adult stands ~1.5 m up.
    height = (rest_world[head, :3, 3] - rest_world[:, :3, 3]) @ frame.up
    units_per_m = max(float(height.max()), 1e-9) / 1.5
    joints, added, locals_ = list(clip.joints), [], []
    # An animation made for a fuller rig may list eyes there that this skeleton lacks (UsdSkel ignores
    # them, the layer writes them through): an added eye of that path was listed twice in the layer.
    taken = set(clip.joints) | set(clip.anim_joints)
    for side, name in ((1.0, "LeftEye"), (-1.0, "RightEye")):
        offset = units_per_m * (options.eye_above_head_m * frame.up + options.eye_ahead_of_head_m * frame.forward
                                + side * 0.5 * options.interocular_m * frame.left)
        m = np.eye(4)
        m[:3, 3] = np.linalg.solve(rest_world[head, :3, :3], offset)
        locals_.append(m)
        joints.append(_free_path(f"{clip.joints[head]}/{name}", taken))
        added.append(joints[-1])
    eyes = (len(joints) - 2, len(joints) - 1)
    return Rig(
        clip, joints,
        parents=np.concatenate([clip.parents, [head, head]]),
        rest_local=np.concatenate([clip.rest_local, np.stack(locals_)]),
        rest_q=np.concatenate([rest_q, rest_q[[head, head]]]),  # added eyes start aligned with the head
        eyes=eyes, added=added,
        added_t={e: m[:3, 3] for e, m in zip(eyes, locals_)}, head=head,
    )


def _drive_chain(rig: Rig, chain: Chain, frame: CharacterFrame, disp: np.ndarray, base: Pose
                 ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """New local rotations along the chain (parents first) and their new world rotations."""
    canon = frame.rotation  # canonical -> skeleton space
    counts = np.zeros(4, dtype=int)
    for role, seg in SEGMENT_OF_ROLE.items():
        counts[seg] += len(chain.roles[role])
    role_of = {j: role for role in SEGMENT_OF_ROLE for j in chain.roles[role]}
    # What depends on the displacement alone is computed once a run of frames that hold it (see _runs).
    first, run = _runs(disp)
    # A role's rotation spread over its joints: the same share for each of them.
    spread = disp[first, :4]
    shared = np.flatnonzero(counts > 1)
    if len(shared):
        spread[:, shared] = rot.power(spread[:, shared], 1.0 / counts[shared])
    above = [j for j in chain.path if role_of.get(j) not in (None, "pelvis")]
    turned = _turn_in_rest_frames(rig, above, [SEGMENT_OF_ROLE[role_of[j]] for j in above], canon, spread, run)
    new_rot: dict[int, np.ndarray] = {}
    new_world: dict[int, np.ndarray] = {}
    for j in chain.path:
        _, q_j, _ = rig.local(j)
        p = int(rig.parents[j])
        # A root's parent frame is skeleton space: its products by the identity are left out (they
        # change no value, only the sign of a zero, and the next product's sums keep no such zero).
        parent_world = new_world.get(p, base.rotation.get(p)) if p >= 0 else None
        role = role_of.get(j)
        if j in turned:
            new_rot[j] = turned[j]
        elif role is None:
            new_rot[j] = rot.normalize(q_j)
        elif role == "pelvis":
            # Heading frame: the character frame turned about up to where the pelvis faces now.
            facing = rot.rotate(rot.multiply(base.rotation[j], rot.conjugate(rig.rest_q[j])), frame.forward)
            flat = facing - np.outer(facing @ frame.up, frame.up)
            heading = np.arctan2(rot.cross(frame.forward, flat) @ frame.up, flat @ frame.forward)
            q_world = rot.conjugate_into(rot.multiply(rot.from_axis_angle(frame.up, heading), canon), spread[run, 0])
            if parent_world is not None:
                q_world = rot.conjugate_into(rot.conjugate(parent_world), q_world)
            new_rot[j] = rot.normalized_product(q_world, q_j)
        new_world[j] = rot.normalize(new_rot[j]) if parent_world is None else rot.normalized_product(parent_world, new_rot[j])
    return new_rot, new_world


def _runs(disp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first frame of each run of frames whose displacements ``(F, ...)`` have the same bits, and
    each frame's run. A shift holds one displacement on all its settled frames, and the frames before
    the first shift hold the identity: on the CMU bench, 496 runs in 1,247 frames. Bits, not values,
    are compared: -0.0 and 0.0 may turn a rotation's signs apart."""
    bits = np.ascontiguousarray(disp).reshape(len(disp), math.prod(disp.shape[1:])).view(np.int64)
    starts = np.ones(len(disp), dtype=bool)
    starts[1:] = (bits[1:] != bits[:-1]).any(axis=1)
    return np.flatnonzero(starts), np.cumsum(starts) - 1


def _turn_in_rest_frames(rig: Rig, joints: list[int], segments: list[int], canon: np.ndarray,
                         spread: np.ndarray, run: np.ndarray) -> dict[int, np.ndarray]:
    """New local rotations of chain ``joints`` (not the pelvis): each one's segment share turned in
    its parent's frame as it sits at rest, as the paper's dress-pose offsets are. They need no world
    rotation, so all of them are composed at once, as arrays ``(joints, F, 4)`` (joints first: numpy
    then runs each operation along the frames, not along a few joints at a time). ``spread`` holds
    the shares once a run of frames (:func:`_runs`); ``run`` is each frame's."""
    if not joints:
        return {}
    parents = rig.parents[joints]
    k = np.where((parents >= 0)[:, None], rot.multiply(rot.conjugate(rig.rest_q[parents]), canon), canon)
    local = np.stack([rig.local(j)[1] for j in joints])
    share = np.swapaxes(spread[:, segments], 0, 1)
    turned = rot.normalized_product(rot.conjugate_into(k[:, None], share)[:, run], local)
    return dict(zip(joints, turned))


def _counter_rotate_legs(rig: Rig, chain: Chain, base: Pose, new_world: dict[int, np.ndarray]
                         ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Leg roots keep their world transform: undo the pelvis's change in the pelvis frame."""
    pelvis = chain.pelvis
    undo = rot.multiply(rot.conjugate(new_world[pelvis]), base.rotation[pelvis])
    legs = list(chain.leg_roots)
    if not legs:
        return {}, {}
    # All leg roots at once, as arrays (legs, F, ...).
    t, q = (np.stack([rig.local(j)[k] for j in legs]) for k in (0, 1))
    turned, moved = rot.normalized_product(undo, q), rot.rotate(undo, t)
    return dict(zip(legs, turned)), dict(zip(legs, moved))



@dataclass
class Base:
    """The base motion as a pass sees it: the rig with its eyes, FK of what the pass reads, the
    base line of sight."""

    rig: Rig
    pose: Pose
    skel_to_world: np.ndarray
    """Per-frame 3x3 linear part of skeleton -> world ``(F, 3, 3)``."""
    up: np.ndarray
    """World up."""
    line_of_sight: np.ndarray
    """World direction the base head looks along ``(F, 3)``."""
    ae: np.ndarray
    """Its (azimuth, elevation) in degrees ``(F, 2)``."""

    def head_and_eyes(self) -> tuple[np.ndarray, np.ndarray]:
        """Skeleton-space positions of the base motion's head joint and of its eyes' midpoint ``(F, 3)``.
        The pose holds rotations only: the positions down to the eyes are computed when asked (where
        look targets are seen from; a pass of shifts alone never asks)."""
        rig = self.rig
        pose = forward(with_ancestors([*rig.eyes, rig.head], rig.parents), rig.parents, rig.local, self.pose.rotation)
        return pose.position[rig.head], 0.5 * (pose.position[rig.eyes[0]] + pose.position[rig.eyes[1]])


def gaze_up(clip: SkelClip, frame: CharacterFrame, pose: Pose | None = None, rig: Rig | None = None,
            chain: Chain | None = None) -> np.ndarray:
    """The world axis gaze azimuths turn about: the stage's up, or, for a character leaning or lying in
    the stage (its own up, carried into the world at the first frame, more than ``UP_SNAP_DEG`` from
    the stage's), its own: lying on its back its line of sight is the stage's up, about which every
    azimuth is a roll of the eyes (a look-at to its side missed by 45-90 deg by UsdSkel FK). Given the
    base ``pose``, a character upright in its space but lying in its animation on most frames (a
    capture of an actor lying down: the root joint turned, the pelvis more than ``UP_SNAP_DEG`` off
    the stage's up) turns about its head's own up on those frames, the face's yaw axis."""
    from usdgaze.core.kinematics import UP_SNAP_DEG
    from usdgaze.passes.hidden import held_world

    up_w = np.asarray(clip.world_up, dtype=float)
    s2w = held_world(clip.skel_to_world)[:, :3, :3]
    own = rot.normalize(s2w[0] @ frame.up)
    upright = math.cos(math.radians(UP_SNAP_DEG))
    if float(own @ up_w) <= upright:
        return own
    if pose is None or rig is None or chain is None:
        return up_w
    lying = carried_axis(pose, rig, chain.pelvis, frame.up, s2w) @ up_w <= upright
    # One axis serves the whole clip: the posture of most of its frames (a clip that gets up from the
    # floor and stands keeps the stage's up, which its standing frames need).
    if lying.mean() < 0.5:
        return up_w
    return rot.normalize(carried_axis(pose, rig, chain.head, frame.up, s2w)[lying].mean(axis=0))


def carried_axis(pose: Pose, rig: Rig, joint: int, axis: np.ndarray, s2w: np.ndarray) -> np.ndarray:
    """A skeleton-space axis of the neutral pose carried by ``joint``'s base rotation into the world
    ``(F, 3)``, unit length."""
    to_rest = rot.multiply(pose.rotation[joint], rot.conjugate(rig.rest_q[joint]))
    skel = rot.rotate(to_rest, np.broadcast_to(axis, (len(to_rest), 3)))
    return rot.normalize(np.einsum("fij,fj->fi", s2w[:len(skel)], skel))


def prepare(clip: SkelClip, chain: Chain, frame: CharacterFrame, options: PassOptions) -> Base:
    """The rig with eyes (added if missing), base FK of the chain and eyes (the leg roots' counter
    rotation needs only their locals), and the base line of sight (where the head looks)."""
    rig = with_eyes(clip, chain, frame, options)
    # The eyes' base rotations are not needed unless look targets are seen from them (head_and_eyes
    # composes them then); their scales still decide, as before, whether the pose has linear parts.
    pose = forward(with_ancestors(list(chain.path), rig.parents), rig.parents, rig.local, positions=False,
                   scaled_by=with_ancestors(list(chain.path) + list(rig.eyes), rig.parents))
    skel_to_world = clip.skel_to_world[:, :3, :3]
    up_w = gaze_up(clip, frame, pose, rig, chain)
    if chain.head in pose.linear:  # scales on the chain: the head's axis goes through its full linear map
        head_axis = np.linalg.solve(clip.neutral()[chain.head, :3, :3], frame.forward)
        looks = rot.normalize(np.einsum("fij,j->fi", pose.linear[chain.head], head_axis))
    else:
        looks = rot.rotate(pose.rotation[chain.head], rot.rotate(rot.conjugate(rig.rest_q[chain.head]), frame.forward))
    sight = directions_to_world(skel_to_world, looks)
    return Base(rig, pose, skel_to_world, up_w, sight, azimuth_elevation(sight, up_w))


@dataclass
class Body:
    """The chain driven by a displacement: new local rotations/translations and the moved eye parents."""

    rotations: dict[int, np.ndarray]
    translations: dict[int, np.ndarray]
    moved: Pose
    _centre: np.ndarray | None = field(default=None, repr=False)
    _eyes: dict[int, np.ndarray] = field(default_factory=dict, repr=False)

    def eye_position(self, rig: Rig, e: int) -> np.ndarray:
        """Skeleton-space position of eye ``e`` ``(F, 3)`` (the pass asks more than once: computed once)."""
        if e not in self._eyes:
            self._eyes[e] = self.moved.place(int(rig.parents[e]), rig.local(e)[0])
        return self._eyes[e]

    def eye_centre(self, rig: Rig) -> np.ndarray:
        """Skeleton-space midpoint of the eyes ``(F, 3)``."""
        if self._centre is None:
            self._centre = 0.5 * sum(self.eye_position(rig, e) for e in rig.eyes)
        return self._centre


def move_body(base: Base, chain: Chain, frame: CharacterFrame, displacement: np.ndarray) -> Body:
    """Drive the chain with per-frame segment offsets; legs keep their world pose; FK to the eyes."""
    rig = base.rig
    mirrored = rig.clip.handedness < 0.0
    if mirrored.any():
        # A mirrored SkelRoot (a negative scale): the skeleton's left is the world's right, and a
        # request's yaw is toward the character's left as the world sees it.
        displacement = np.where(mirrored[:, None, None], rot.mirror_left_right(displacement), displacement)
    new_rot, new_world = _drive_chain(rig, chain, frame, displacement, base.pose)
    leg_rot, new_trans = _counter_rotate_legs(rig, chain, base.pose, new_world)
    new_rot.update(leg_rot)

    def new_local(j: int):
        t, q, s = rig.local(j)
        return new_trans.get(j, t), new_rot.get(j, q), s

    eye_parents = sorted({int(rig.parents[e]) for e in rig.eyes})
    # The head too: the eyes' range is measured in its frame, and an eye need not hang below it.
    moved = forward(with_ancestors(eye_parents + [chain.head], rig.parents), rig.parents, new_local, new_world)
    return Body(new_rot, new_trans, moved)
