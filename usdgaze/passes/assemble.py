"""The last step of the gaze passes: aim the eyes, measure what was achieved, assemble the arrays."""

from __future__ import annotations

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.rig import CharacterFrame, Chain
from usdgaze.passes.aim import aim_eyes
from usdgaze.passes.chain import Base, Body, Rig
from usdgaze.passes.schedule import Schedule
from usdgaze.passes.sight import azimuth_elevation, directions_to_world, line_of_sight
from usdgaze.passes.options import PassOptions, PassResult


def assemble(rig: Rig, rotations_new: dict[int, np.ndarray], translations_new: dict[int, np.ndarray]
              ) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Full animation arrays: the input's values, with the driven joints overwritten.

    Driven joints the animation does not list (added eyes, an unanimated chain joint) are appended,
    so every existing index stays valid and untouched joints keep their exact bits.
    """
    clip = rig.clip
    animated = set(int(j) for j in clip.anim_to_skel)
    appended = sorted({j for j in list(rotations_new) + list(translations_new) if j not in animated})
    anim_index = {int(s): a for a, s in enumerate(clip.anim_to_skel)}
    anim_joints = list(clip.anim_joints)
    rotations, translations, scales = clip.rotations, clip.translations, clip.scales
    if appended:
        t_add, q_add, s_add = zip(*(rig.local(j) for j in appended))
        rotations = np.concatenate([rotations, np.stack(q_add, 1).astype(np.float32)], axis=1)
        translations = np.concatenate([translations, np.stack(t_add, 1).astype(np.float32)], axis=1)
        scales = np.concatenate([scales, np.stack(s_add, 1).astype(np.float16)], axis=1)
        for j in appended:
            anim_index[j] = len(anim_joints)
            anim_joints.append(rig.joints[j])
    elif not clip.owns_arrays:  # concatenate already made new arrays; else write into the clip's only if it owns them
        rotations = rotations.copy()
        translations = translations.copy() if translations_new else translations
    for j, q in rotations_new.items():  # a joint at a time: all at once costs 80 MB more at 100k frames
        column = anim_index[j]
        # Compared with the float32 samples as they are (each product widens them exactly); stored
        # as float32 by the assignment, as astype(np.float32) rounds.
        rotations[:, column] = rot.align_hemisphere(q, rotations[:, column])
    for j, t in translations_new.items():
        translations[:, anim_index[j]] = t.astype(np.float32)
    return anim_joints, rotations, translations, scales


def _wanted(sight_w: np.ndarray, up_w: np.ndarray, base_ae: np.ndarray, plan: Schedule) -> np.ndarray:
    """The wanted line-of-sight change ``(F, 2)`` toward world directions ``sight_w``, against the base's."""
    wanted_ae = azimuth_elevation(sight_w, up_w)
    near_plan = rot.unwrap_near(wanted_ae[:, 0] - base_ae[:, 0], plan.requested[:, 0])
    # The eyes lead the body: more than 90 deg ahead of its plan (a saccade of a large shift), the
    # wanted azimuth continues from where it was, not on whichever side is nearer the body's.
    yaw = rot.unwrap_from_kept(near_plan, np.abs(near_plan - plan.requested[:, 0]) <= 90.0)
    return np.column_stack([yaw, wanted_ae[:, 1] - base_ae[:, 1]])


def finish(clip: SkelClip, chain: Chain, frame: CharacterFrame, base: Base, body: Body, plan: Schedule,
           sight_point: np.ndarray, options: PassOptions, requested: np.ndarray | None = None,
           saccading: np.ndarray | None = None, side: np.ndarray | None = None) -> PassResult:
    """Aim both eyes at the skeleton-space ``sight_point`` per frame, measure, assemble the arrays.

    ``requested`` is the wanted line-of-sight change per frame (default: toward ``sight_point``);
    ``side`` the side of the head the eyes keep for a point behind it (:func:`aim.held_side`).
    """
    rig, skel_to_world, up_w, base_ae = base.rig, base.skel_to_world, base.up, base.ae
    eyes = aim_eyes(rig, frame, body.moved, sight_point, options.eye_range, side, clip.seconds,
                    positions=np.stack([body.eye_position(rig, e) for e in rig.eyes]))
    new_rot = dict(body.rotations)
    new_rot.update(eyes.rotations)
    new_trans = body.translations
    centre = body.eye_centre(rig)
    if requested is None:
        requested = _wanted(directions_to_world(skel_to_world, sight_point - centre), up_w, base_ae, plan)

    # What was achieved, measured like a viewer would: from the eyes' midpoint to their point of sight.
    origin, sight = line_of_sight(eyes.positions[0], eyes.directions[0], eyes.positions[1], eyes.directions[1])
    sight_w = directions_to_world(skel_to_world, sight)
    achieved_ae = azimuth_elevation(sight_w, up_w)
    # Unwrapped near the request, but no line of sight turns past half a turn plus the eyes' range: a
    # 360 deg request that reached 100 deg reached 100, not 460.
    reach_deg = 180.0 + options.eye_range.yaw
    achieved = np.column_stack([
        rot.unwrap_near(achieved_ae[:, 0] - base_ae[:, 0], np.clip(requested[:, 0], -reach_deg, reach_deg)),
        achieved_ae[:, 1] - base_ae[:, 1],
    ])
    m = clip.skel_to_world

    def world(p: np.ndarray) -> np.ndarray:
        return np.einsum("fij,fj->fi", np.broadcast_to(m[:, :3, :3], (len(p), 3, 3)), p) + m[:, :3, 3]

    origin_w = world(origin)
    reach = rot.length(world(sight_point) - origin_w)

    anim_joints, rotations, translations, scales = assemble(rig, new_rot, new_trans)
    result = PassResult(
        anim_joints=anim_joints,
        rotations=rotations,
        translations=translations,
        scales=scales,
        added_joints=rig.added,
        changed_joints=[rig.joints[j] for j in sorted(set(new_rot) | set(new_trans))],
        requested=requested,
        achieved=achieved,
        eye_angles=eyes.angles,
        settled=plan.settled if saccading is None else plan.settled & ~saccading,
        seconds=clip.seconds,
        shift_timing=plan.timing,
        eye_positions=np.stack([world(p) for p in eyes.positions]),
        point_of_sight=origin_w + reach[:, None] * sight_w,
    )
    if rig.added:
        result.added_rest_local = rig.rest_local[-2:]
        result.added_bind_world = clip.bind_world[chain.head] @ rig.rest_local[-2:]
    return result
