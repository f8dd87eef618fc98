"""The eye step of the gaze passes: aim each eye at a point of sight within the eye range, and say
where a request was not reached (pure numpy)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.gaze import saccade
from usdgaze.core.clip import SkelClip
from usdgaze.core.kinematics import Pose
from usdgaze.core.rig import CharacterFrame
from usdgaze.passes.chain import Rig
from usdgaze.passes.schedule import Schedule
from usdgaze.passes.options import EyeRange, PassOptions, Shift


@dataclass
class EyeAim:
    rotations: dict[int, np.ndarray]
    angles: np.ndarray
    """Eye-in-head (yaw, pitch) per frame and eye ``(F, 2, 2)``, after the range clamp."""
    positions: list[np.ndarray]
    directions: list[np.ndarray]


def aim_eyes(rig: Rig, frame: CharacterFrame, moved: Pose, sight_point: np.ndarray, limits: EyeRange,
             side: np.ndarray | None = None, seconds: np.ndarray | None = None,
             positions: np.ndarray | None = None,
             max_deg_s: float | np.ndarray = saccade.MAX_SACCADE_DEG_S) -> EyeAim:
    """Point each eye at the point of sight (Listing's law: no torsion), within the eye range; a point
    behind the head on the side ``side (F,)`` says (see :func:`held_side`). With the frames'
    ``seconds``, no eye turns faster than ``max_deg_s`` (the seed's bound, or one per frame interval:
    :func:`capped_speed`).

    Both eyes are computed together, as arrays ``(2, F, ...)``; ``positions`` are the eyes' own, where
    the caller has them.

    The range and the aim are the head joint's: for eyes hung under a face joint, the eye-in-head
    angles are measured in the head's frame and the eye's turn is then carried into its parent's frame
    as animated (:func:`_into_parents`). Measured in the parent's frame, a face joint animated 25 deg
    from its bind-pose relation to the head shifted the range by as much, and the gaze missed."""
    parents = [int(rig.parents[e]) for e in rig.eyes]
    heads = parents if _held_as_bound(rig, moved, parents) else [rig.head, rig.head]
    fwd_h, left_h, up_h, rest_eye, to_head, to_world, shown_at_rest = _sockets(rig, frame, moved, heads)
    pos = positions if positions is not None else np.stack([moved.place(p, rig.local(e)[0]) for p, e in zip(parents, rig.eyes)])
    u_h = to_head(rot.normalize(sight_point - pos))

    def along(axis: np.ndarray) -> np.ndarray:
        return np.einsum("efi,ei->ef", u_h, axis)

    raw_pitch = np.degrees(np.arcsin(np.clip(along(up_h), -1.0, 1.0)))
    pitch = np.clip(raw_pitch, -limits.down, limits.up)
    yaw = np.clip(held_side(np.degrees(np.arctan2(along(left_h), along(fwd_h))), side), -limits.yaw, limits.yaw)
    yaw = yaw * toward_the_pole(raw_pitch)
    if seconds is not None:
        yaw, pitch = capped_speed(np.stack([yaw, pitch], axis=-1), seconds, max_deg_s).transpose(2, 0, 1)
    y, pc = np.radians(yaw)[..., None], np.radians(pitch)[..., None]
    cos_pc = np.cos(pc)
    u_h = (cos_pc * np.sin(y)) * left_h[:, None] + (cos_pc * np.cos(y)) * fwd_h[:, None] + np.sin(pc) * up_h[:, None]
    arc = rot.shortest_arc(fwd_h[:, None], u_h)
    bent = _own_scale_turn(rig, rest_eye, fwd_h, shown_at_rest)
    turned = (rot.normalized_product(arc, rest_eye[:, None]) if bent is None
              else rot.normalized_product(rot.multiply(arc, rest_eye[:, None]), bent))
    if parents != heads:
        turned = _into_parents(moved, rig.head, parents, turned, u_h)
    return EyeAim(
        rotations=dict(zip(rig.eyes, turned)),
        angles=np.stack([yaw, pitch], axis=-1).transpose(1, 0, 2),  # (F, eye, yaw|pitch)
        positions=list(pos),
        directions=list(to_world(u_h)),
    )


HELD_AS_BOUND = 1e-6
"""A joint between head and eye whose animated linear map relative to the head stays this close (max
abs difference of the 3x3, about radians) to its bind-pose one frames the eyes as the head does: the
eyes are aimed in their parent's frame, as before there was a head-frame measure, bit for bit."""


def _held_as_bound(rig: Rig, moved: Pose, parents: list[int]) -> bool:
    """Whether each eye's parent is the head, or holds its bind-pose relation to it on every frame
    (within :data:`HELD_AS_BOUND`), so that measuring in the parent's frame is measuring in the head's."""
    head = rig.head
    if all(p == head for p in parents):
        return True
    neutral = rig.clip.neutral()[:, :3, :3]
    for p in set(parents) - {head}:
        if p in moved.linear:
            held = np.linalg.solve(moved.linear[head], moved.linear[p])
        else:
            held = rot.to_matrix(rot.multiply(rot.conjugate(moved.rotation[head]), moved.rotation[p]))
        if np.abs(held - np.linalg.solve(neutral[head], neutral[p])).max() > HELD_AS_BOUND:
            return False
    return True


def _into_parents(moved: Pose, head: int, parents: list[int], turned: np.ndarray, u_h: np.ndarray) -> np.ndarray:
    """Eye rotations ``turned (2, F, 4)`` given in the head's frame, as local rotations in each eye's own
    parent's frame ``parents`` as animated (a face joint between head and eye, turned or not as in the
    bind pose). ``u_h`` is where each eye looks in the head's frame.

    Without scales the change of frame is the rotation between the two joints' world rotations. With
    scales it is the linear map from the head's frame into the parent's (a rotation unless a joint
    between them is scaled itself): its rotation, and then the turn that puts the eye on ``u_h``
    as the parent's frame maps it, so that the eye still looks where the head's frame aimed it."""
    if not any(p in moved.linear for p in parents):
        change = np.stack([rot.multiply(rot.conjugate(moved.rotation[p]), moved.rotation[head]) for p in parents])
        return rot.normalized_product(change, turned)
    lin = np.stack([np.linalg.solve(moved.linear[p], moved.linear[head]) for p in parents])  # (2, F, 3, 3)
    change = rot.rotation_part(lin)[0]
    aimed = np.einsum("efij,efj->efi", lin, u_h)
    fix = rot.shortest_arc(rot.rotate(change, u_h), aimed)
    return rot.normalized_product(rot.multiply(fix, change), turned)


def _sockets(rig: Rig, frame: CharacterFrame, moved: Pose, parents: list[int]):
    """Per eye, in the frame of joint ``parents`` (the head: see :func:`aim_eyes`): the character's
    forward, left and up as the eye sees them in the neutral pose, the eye's neutral rotation in it,
    and the maps of directions into that frame ``(2, F, 3)`` and back to skeleton space, and the
    eye-local axis the neutral pose shows as forward.

    With scales on the eyes' parents or the eyes (a squashed and stretched head, an eye mirrored by a
    negative scale) the parent's frame is its full linear map, not its rotation: the eye turns in a
    scaled socket, and aimed through the rotation alone it missed by up to 8.6 deg (a head scaled (1,
    1.3, 0.9)). Without scales, quaternions alone, as the chain's."""
    eyes = list(rig.eyes)
    neutral = rig.clip.neutral()[:, :3, :3]
    n = len(neutral)
    lin_p = neutral[parents]
    lin_e = np.stack([neutral[e] if e < n else neutral[p] for e, p in zip(eyes, parents)])
    col = np.linalg.norm(np.concatenate([lin_p, lin_e]), axis=-2)
    unscaled = float(np.abs(col - 1.0).max()) <= 1e-5 and bool(np.all(np.linalg.det(lin_e) > 0.0))
    if unscaled and not any(p in moved.linear for p in parents):
        to_parent = rot.conjugate(rig.rest_q[parents])  # (2, 4)
        turned = rot.rotate(to_parent[:, None], np.stack([frame.forward, frame.left, frame.up]))  # (2, 3, 3)
        axes = [np.ascontiguousarray(turned[:, k]) for k in range(3)]  # laid out as one rotate's each
        head = np.stack([moved.rotation[p] for p in parents])  # (2, F, 4)
        rest_eye = rot.multiply(to_parent, rig.rest_q[eyes])  # each eye in its parent, looking ahead
        return (*axes, rest_eye, lambda v: rot.rotate(rot.conjugate(head), v), lambda u: rot.rotate(head, u),
                rot.rotate(rot.conjugate(rest_eye), axes[0]))
    fwd = rot.normalize(np.linalg.solve(lin_p, np.broadcast_to(frame.forward, (2, 3))[..., None])[..., 0])
    up = np.linalg.solve(lin_p, np.broadcast_to(frame.up, (2, 3))[..., None])[..., 0]
    up = rot.normalize(up - rot.dot(up, fwd, keepdims=True) * fwd)
    rest_eye, _ = rot.rotation_part(np.linalg.solve(lin_p, lin_e))
    head = np.stack([moved.linear[p] if p in moved.linear else rot.to_matrix(moved.rotation[p]) for p in parents])
    return (fwd, np.cross(up, fwd), up, rest_eye,
            lambda v: rot.normalize(np.linalg.solve(head, v[..., None])[..., 0]),
            lambda u: rot.normalize(np.einsum("efij,efj->efi", head, u)),
            np.linalg.solve(np.linalg.solve(lin_p, lin_e), fwd[..., None])[..., 0])


def _own_scale_turn(rig: Rig, rest_eye: np.ndarray, fwd_h: np.ndarray, shown_at_rest: np.ndarray
                    ) -> np.ndarray | None:
    """Per eye and frame ``(2, F, 4)``, the turn in the eye's own frame that takes the forward its own
    animated scale shows onto the one its rotation alone aims; None where no eye's scale bends it.

    ``shown_at_rest``: per eye, the local axis the neutral pose shows as forward. UsdSkel scales a
    joint in its own frame before its rotation, so an eye squashed off its forward axes (a cartoon
    eye made oval, whose joint orient is not its gaze) points that axis scaled: aimed by the rotation
    alone it missed a look-at target by 16 deg (scale (1, 1.6, 0.7)), or 20 deg when only the bind
    pose scaled it."""
    scales = [np.asarray(rig.local(e)[2], dtype=float) for e in rig.eyes]
    frames = len(scales[0])
    # An eye's scale held on every frame (a broadcast row: an added eye's, most rigs') bends it alike on
    # every frame: the turn is measured on one and broadcast.
    still = frames > 0 and all(s.ndim == 2 and s.strides[0] == 0 for s in scales)
    scale = np.stack([s[:1] if still else s for s in scales])  # (2, F or 1, 3)
    shown = rot.normalize(scale * shown_at_rest[:, None, :])
    aimed = np.broadcast_to(rot.rotate(rot.conjugate(rest_eye), fwd_h)[:, None, :], shown.shape)
    if rot.length(rot.cross(shown, aimed)).max() <= 1e-9 and rot.dot(shown, aimed).min() > 0.0:
        return None
    turn = rot.shortest_arc(shown, aimed)
    return np.broadcast_to(turn, (len(scales), frames, 4)) if still else turn


def capped_speed(angles: np.ndarray, seconds: np.ndarray,
                 max_deg_s: float | np.ndarray = saccade.MAX_SACCADE_DEG_S) -> np.ndarray:
    """Eye-in-head (yaw, pitch) ``(E, F, 2)`` turning no faster than ``max_deg_s`` (the seed's bound on
    the eyes, 800 deg/s, or one per frame interval, ``(F - 1,)``): where the aim runs ahead, the eye
    follows it at that speed until it is back on.

    The clamped aim of a goal the eyes cannot reach jumps where the goal's side is undefined (it passes
    behind the head or near its pole, or the base's own line of sight passes the zenith) or where the
    request turns it the other way round: an eye swapped one limit of its range for the other in a
    frame. Only the frames from such a step until the eye is back on its aim are walked one by one.
    """
    if len(seconds) < 2:
        return angles
    dt = np.diff(seconds)
    reach = max_deg_s * dt  # (F-1,)
    fast = rot.length(np.diff(angles, axis=1)) > reach * (1.0 + 1e-9)
    if not fast.any():
        return angles
    out = angles.copy()
    for e in range(len(angles)):
        ahead = np.flatnonzero(fast[e])
        k = 0
        while True:
            i = int(np.searchsorted(ahead, k))
            if i == len(ahead):
                break
            k = int(ahead[i]) + 1  # the first frame the aim runs ahead of the eye
            while k < len(seconds):
                d = angles[e, k] - out[e, k - 1]
                n = float(np.hypot(d[0], d[1]))
                if n <= reach[k - 1]:
                    break  # back on the aim: out[e, k] is the aim's own
                out[e, k] = out[e, k - 1] + d * (reach[k - 1] / n)
                k += 1
    return out


POLE_DEG = 75.0
"""Beyond this pitch of a point in the head's frame, an eye keeps less of its clamped yaw (see
:func:`toward_the_pole`)."""


def toward_the_pole(raw_pitch: np.ndarray) -> np.ndarray:
    """The share of its clamped yaw an eye keeps for a point past ``POLE_DEG`` above or below the
    head's horizon: cos(pitch) / cos(POLE_DEG), down to 0 straight above or below. Near the head's pole
    a point's yaw is all but undefined, and the eye clamped at +-44 deg swung from side to side as the
    point moved about it (a shift of 60 deg yaw and 90 up: 70 deg in a frame, 3,675 deg/s), while
    what the yaw adds to its aim shrinks as that cosine; nearer the horizon nothing changes (at 60 deg the
    eyes of the CMU walk's lunge swept their range in 5 frames as the head pitched)."""
    return np.minimum(np.cos(np.radians(raw_pitch)) / np.cos(np.radians(POLE_DEG)), 1.0)


OVER_THE_POLE = 2.0
"""A :func:`held_side` side: a goal behind the head is reached over its pole, not round a side."""


def held_side(yaw_deg: np.ndarray, side: np.ndarray | None) -> np.ndarray:
    """Eye-in-head yaw ``(..., F)``: behind the head (beyond 90 deg, past any eye's reach), on the side
    ``side (F,)`` says (+1 left, -1 right, 0 either, :data:`OVER_THE_POLE` neither).

    A goal a shift asks for more than 90 deg round is behind the head until the head has turned
    toward it: each eye stays at its limit on the shift's side, where ``arctan2``'s branch put it on
    the other side whenever the goal was past half a turn from the head (a swap of 88 deg in a frame,
    and back). A shift asking less is behind the head only because the head is pitched away from it
    (straight up, then straight down): the eye takes the yaw of the goal mirrored to the front, which
    passes through 0 with the goal, where either side swapped 88 deg in a frame. A target passing
    behind has no side: the eye changes sides as the target crosses.
    """
    if side is None or not np.any(side):
        return yaw_deg
    behind = np.abs(yaw_deg) > 90.0
    mirrored = np.sign(yaw_deg) * (180.0 - np.abs(yaw_deg))
    kept = np.where(behind & (np.abs(side) == 1.0), rot.unwrap_near(yaw_deg, 180.0 * side), yaw_deg)
    return np.where(behind & (side == OVER_THE_POLE), mirrored, kept)


def reach_warnings(clip: SkelClip, shifts: list[Shift], plan: Schedule, base_ae: np.ndarray,
                    achieved: np.ndarray, eye_angles: np.ndarray, options: PassOptions,
                    ends: list[float] | None = None) -> list[str]:
    """One line per shift whose hold (until the next shift, or ``ends[k]``) misses the request by
    more than the tolerance, saying why."""
    limits = options.eye_range
    seconds = clip.seconds
    warnings = []
    for k, sh in enumerate(shifts):
        end = ends[k] if ends is not None else shifts[k + 1].time_s if k + 1 < len(shifts) else np.inf
        hold = plan.settled & (seconds >= sh.time_s) & (seconds < end)
        if not np.any(hold):
            warnings.extend(_cut_short(clip, sh, end, achieved))
            continue
        if np.abs(achieved[hold] - plan.requested[hold]).max() <= options.tolerance_deg:
            continue
        reach = achieved[hold].mean(axis=0)
        angles = eye_angles[hold]
        at_limit = np.any(np.abs(angles[..., 0]) >= limits.yaw - 1e-6) or np.any(
            (angles[..., 1] >= limits.up - 1e-6) | (angles[..., 1] <= -limits.down + 1e-6))
        if np.any(np.abs(base_ae[hold, 1] + plan.requested[hold, 1]) > 89.0):
            wanted = base_ae[hold, 1] + plan.requested[hold, 1]
            way = "down" if wanted.mean() < 0 else "up"  # where the request points, not where the base does
            base = base_ae[hold, 1].mean()
            why = (f"the base line of sight points {abs(base):.0f} deg {'down' if base < 0 else 'up'}, and the gaze "
                   f"cannot pass straight {way}")
        elif at_limit:
            why = f"the eyes reach their range (yaw +-{limits.yaw:g}, up {limits.up:g}, down {limits.down:g} deg)"
        else:
            why = "the chain cannot turn that far"
        warnings.append(
            f"{clip.where()}: shift at {sh.time_s:g} s asks for yaw {sh.yaw:g}, pitch {sh.pitch:g} deg; "
            f"reached about yaw {reach[0]:.1f}, pitch {reach[1]:.1f} ({why})"
        )
    return warnings


def _cut_short(clip: SkelClip, sh: Shift, end: float, achieved: np.ndarray) -> list[str]:
    """The line for a shift the animation ends before it settles (a next directive that interrupts
    it is asked for, and says nothing)."""
    seconds = clip.seconds
    if end < seconds[-1] or sh.time_s > seconds[-1]:
        return []
    reach = achieved[-1]
    return [f"{clip.where()}: shift at {sh.time_s:g} s asks for yaw {sh.yaw:g}, pitch {sh.pitch:g} deg; the "
            f"animation ends {seconds[-1] - sh.time_s:.3g} s after it starts, before it settles: reached about "
            f"yaw {reach[0]:.1f}, pitch {reach[1]:.1f} on the last frame"]
