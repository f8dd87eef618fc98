"""The attend pass: from a clip and moving objects, eyes + neck + upper spine chosen by the planner.

Data flow: clip (UsdSkel arrays) -> base gaze chain in world metres on the planner grid -> the
visuomotor loop (``usdgaze.vision.loop``) -> offsets and point of sight back on the clip's frames ->
new local rotations for the first upper-spine joint, the first neck joint (the head when there is no
neck) and both eyes (aimed at the point of sight, so vergence follows the focal distance).
Pure numpy apart from what it is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.kinematics import Pose, forward, with_ancestors
from usdgaze.core.rig import Chain, CharacterFrame
from usdgaze.passes.aim import aim_eyes
from usdgaze.passes.assemble import assemble
from usdgaze.passes.chain import carried_axis, gaze_up, with_eyes
from usdgaze.passes.hidden import hold_visible, restore
from usdgaze.passes.options import EyeRange, PassOptions
from usdgaze.planning.kinbody import BaseChain
from usdgaze.vision import eye as eyemod
from usdgaze.vision import loop

# The eyes aim at the point of sight each from its own position; near fixation that needs a few
# degrees more than the cyclopean range, which the planner bounds (eye.LO/HI).
_EYE_CLAMP = EyeRange(yaw=50.0, up=32.0, down=52.0)


@dataclass
class AttendResult:
    anim_joints: list[str]
    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    added_joints: list[str]
    added_rest_local: np.ndarray | None
    added_bind_world: np.ndarray | None
    changed_joints: list[str]
    sight_world: np.ndarray  # (F, 3) stage units
    estimates_world: np.ndarray  # (F, O, 3) stage units, NaN while untracked
    uncertainty: np.ndarray  # (F, O) sigma_p, m^2, NaN while untracked
    eye_pose: np.ndarray  # (F, 3) theta, psi (deg), zeta (mm)
    loop: loop.LoopResult = field(repr=False, default=None)
    planner_times: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)


def _spine_neck(chain: Chain) -> tuple[int, int]:
    roles = chain.roles
    spine = (roles.get("upperSpine") or roles.get("lowerSpine") or [chain.pelvis])[0]
    neck = (roles.get("neck") or [chain.head])[0]
    return int(spine), int(neck)


def _interp(t_new: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    flat = v.reshape(len(t), -1)
    out = np.stack([np.interp(t_new, t, flat[:, i]) for i in range(flat.shape[1])], -1)
    return out.reshape((len(t_new),) + v.shape[1:])


def _world(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.einsum("fij,fj->fi", m[:, :3, :3], p) + m[:, :3, 3]


def planner_times(seconds: np.ndarray, h: float) -> np.ndarray:
    """The planner's grid, seconds from the stage's start: every h from the clip's first frame to its last.

    From the first frame, not the stage's start: a clip at time code 1001 in a stage starting at 1 was
    planned for the 41.7 s before it too (25 times the work), its saccade rhythm shifted off its start."""
    return seconds[0] + np.arange(0.0, seconds[-1] - seconds[0] + 1e-9, h)


def base_chain(clip: SkelClip, chain: Chain, frame: CharacterFrame, rig, base: Pose, h: float
               ) -> tuple[BaseChain, np.ndarray]:
    """The base motion's pivots, eye midpoint and head axes on the planner grid (world, metres)."""
    spine, neck = _spine_neck(chain)
    s2w, mpu = clip.skel_to_world, clip.meters_per_unit
    up = gaze_up(clip, frame, base, rig, chain)  # the head's yaw axis
    head = chain.head
    eyes = 0.5 * sum(base.place(int(rig.parents[e]), rig.local(e)[0]) for e in rig.eyes)
    pts = [(_world(s2w, base.position[j]) * mpu) for j in (spine, neck)] + [_world(s2w, eyes) * mpu]
    axes = np.stack([carried_axis(base, rig, head, v, s2w[:, :3, :3]) for v in (frame.forward, frame.left, frame.up)],
                    -1)
    seconds = clip.seconds
    t = planner_times(seconds, h)
    P = [_interp(t, seconds, p) for p in pts]
    A = _interp(t, seconds, axes)
    # re-orthonormalize the interpolated head axes (forward first, then up)
    f = rot.normalize(A[..., 0])
    u = rot.normalize(A[..., 2] - np.sum(A[..., 2] * f, -1, keepdims=True) * f)
    A = np.stack([f, np.cross(u, f), u], -1)
    left = A[..., 1] - np.outer(A[..., 1] @ up, up)
    left = rot.normalize(np.where(np.linalg.norm(left, axis=-1, keepdims=True) > 1e-6, left, np.cross(up, f)))
    return BaseChain(P[0], P[1], P[2], A, left, up), t


def apply_attend(clip: SkelClip, chain: Chain, frame: CharacterFrame, things: list[loop.Thing],
                 options: loop.LoopOptions, progress=None, frames: int | None = None) -> AttendResult:
    """Run the visuomotor loop on one clip and turn its result into animation arrays.

    ``frames``: the shot is the clip's first ``frames`` frames; the rest (the take after a shot cut
    from it) only the planner's windows see, and the result holds the shot's frames."""
    clip, hidden = hold_visible(clip, chain)
    rig = with_eyes(clip, chain, frame, PassOptions())
    spine, neck = _spine_neck(chain)
    base = forward(with_ancestors(list(chain.path) + list(rig.eyes), rig.parents), rig.parents, rig.local)
    bc, t_base = base_chain(clip, chain, frame, rig, base, options.h)
    t_plan = t_base if frames is None else t_base[:len(planner_times(clip.seconds[:frames], options.h))]
    for th in things:
        th.up = clip.world_up
    res = loop.run(bc, things, options, len(t_plan), progress)
    seconds = clip.seconds
    q = _interp(seconds, t_plan, res.offsets)
    left_w = _interp(seconds, t_base, bc.left)
    new_rot = _drive(clip, rig, base, spine, neck, q, left_w, bc.up)

    def new_local(j: int):
        t_, q_, s_ = rig.local(j)
        return t_, new_rot.get(j, q_), s_

    # The point of sight at the frames, from the interpolated eye pose on the moved head (not the
    # planner's points interpolated in space, which would bend a saccade's path and speed).
    e = _interp(seconds, t_plan, res.eye)
    eye_rot, sight_units = eyes_on(clip, chain, frame, rig, new_local, e)
    new_rot.update(eye_rot)
    mpu = clip.meters_per_unit
    anim_joints, rotations, translations, scales = assemble(rig, new_rot, {})
    est = _interp(seconds, t_plan, res.estimate) / mpu
    unc = _interp(seconds, t_plan, res.sigma_p) * options.unit_m**2  # the belief's unit to m^2
    eye_pose = _interp(seconds, t_plan, res.eye) * [180 / np.pi, 180 / np.pi, 1.0]
    shot = slice(0, frames)
    out = AttendResult(anim_joints, rotations[shot], translations[shot], scales[shot], rig.added, None, None,
                       [rig.joints[j] for j in sorted(new_rot)], sight_units[shot], est[shot], unc[shot],
                       eye_pose[shot], res, t_plan)
    if rig.added:
        out.added_rest_local = rig.rest_local[-2:]
        out.added_bind_world = clip.bind_world[chain.head] @ rig.rest_local[-2:]
    return restore(out, hidden, clip)


def eyes_on(clip: SkelClip, chain: Chain, frame: CharacterFrame, rig, new_local, e: np.ndarray
            ) -> tuple[dict[int, np.ndarray], np.ndarray]:
    """Both eyes' local rotations aiming at the point of sight of eye pose ``e`` (F, 3: theta, psi rad,
    zeta mm) on the head that ``new_local(j)`` -> (t, q, s) poses; and that point (world, stage units)."""
    head = chain.head
    # The eyes' parents too: a face joint between head and eyes is where their turns are written.
    moved = forward(with_ancestors([head, *(int(rig.parents[j]) for j in rig.eyes)], rig.parents), rig.parents, new_local)
    n = len(e)
    to_rest = rot.multiply(moved.rotation[head], rot.conjugate(rig.rest_q[head]))
    f, l, u = (rot.rotate(to_rest, np.broadcast_to(v, (n, 3))) for v in (frame.forward, frame.left, frame.up))
    # The eye pose's yaw is toward the world's left; a mirrored SkelRoot puts the skeleton's left on the world's right.
    l = l * clip.handedness[:, None]
    ct, st, cp, sp = np.cos(e[:, 0]), np.sin(e[:, 0]), np.cos(e[:, 1]), np.sin(e[:, 1])
    direction = (cp * ct)[:, None] * f + (cp * st)[:, None] * l + sp[:, None] * u
    mid = 0.5 * sum(moved.place(int(rig.parents[j]), rig.local(j)[0]) for j in rig.eyes)
    scale = np.cbrt(np.abs(np.linalg.det(clip.skel_to_world[:, :3, :3])))
    dist = eyemod.distance(e[:, 2])[0] / clip.meters_per_unit / scale
    sight_skel = mid + dist[:, None] * direction
    # Each eye within the bound of the planner's window (800 deg/s in a saccade window, 100 in recharge,
    # counted from the clip's first frame): the planner bounds the cyclopean direction only, and
    # vergence on a near object took one eye to 856 deg/s on top of it, or to 132-161 deg/s in a
    # recharge window (focus from 2 m to 0.5 m in a frame).
    t = clip.seconds - clip.seconds[0]
    bound = np.degrees(np.maximum(eyemod.speed_bound(t[:-1]), eyemod.speed_bound(t[1:])))
    eyes = aim_eyes(rig, frame, moved, sight_skel, _EYE_CLAMP, seconds=clip.seconds, max_deg_s=bound)
    return eyes.rotations, _world(clip.skel_to_world, sight_skel)


def _drive(clip: SkelClip, rig, base: Pose, spine: int, neck: int, q: np.ndarray, left_w: np.ndarray,
           up_w: np.ndarray) -> dict[int, np.ndarray]:
    """Local rotations of the spine and neck joints carrying the world offsets G_s, G_n."""
    s3 = clip.skel_to_world[:, :3, :3]
    inv = np.linalg.inv(s3)
    up_s = rot.normalize(np.einsum("fij,j->fi", inv, up_w))
    left_s = rot.normalize(np.einsum("fij,fj->fi", inv, left_w))

    def g(yaw, pitch):
        return rot.multiply(rot.from_axis_angle(up_s, yaw), rot.from_axis_angle(left_s, pitch))

    # World turns in skeleton space: a mirroring skel_to_world reverses every rotation's sense.
    q = q * clip.handedness[:, None]
    gs, gn = g(q[:, 0], q[:, 1]), g(q[:, 2], q[:, 3])
    ident = np.tile(rot.IDENTITY, (len(q), 1))
    out = {}
    p_s = int(rig.parents[spine])
    pw = base.rotation[p_s] if p_s >= 0 else ident
    out[spine] = rot.normalized_product(rot.conjugate_into(rot.conjugate(pw), gs), rig.local(spine)[1])
    p_n = int(rig.parents[neck])
    pw_n = rot.multiply(gs, base.rotation[p_n]) if p_n >= 0 else ident
    if neck == spine:
        return out
    out[neck] = rot.normalized_product(rot.conjugate_into(rot.conjugate(pw_n), gn), rig.local(neck)[1])
    return out
