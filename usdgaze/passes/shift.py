"""The gaze pass: layer a schedule of gaze shifts onto a skeletal animation (Heck 5.2.3, extended).

Pure numpy. Input: a :class:`~usdgaze.core.clip.SkelClip`, its bound :class:`~usdgaze.core.rig.Chain`, the
character frame, a :class:`~usdgaze.gaze.gazemap.ParametricGazeMap` and the shifts. Output: new
animation arrays in which only the chain joints, the leg roots under the pelvis and the eyes differ.

How a request is met:

* A request (yaw, pitch) is a change of the line of sight against the base motion's line of sight at
  the same frame (the base's eyes look where its head looks): yaw changes the azimuth about the
  stage up axis (positive toward the character's left), pitch the elevation.
* Shift k blends every segment from the state the previous shift left it in to the map's answer for
  the request (identity for (0, 0)), with the map's timing for the *change* (cascade, overshoot,
  settle). P+ offsets are parent-relative rotations in the character frame; on the rig each one is
  applied in its joint's parent frame as that frame sits in the neutral (bind) pose, spread evenly over the joints
  sharing a role (neck and head share the neck segment). The pelvis turns in its heading frame.
* The leg roots under the pelvis counter-rotate so the legs keep their base world pose.
* The eyes converge on a point of sight at ``fixation_m`` along the wanted line of sight. The wanted
  line of sight follows the map's gaze progress on the canonical chain (so it leads, overshoots and
  settles like the model) and equals the request exactly once the shift settles: the eyes absorb
  the model's residual on this rig and the base motion's bobbing, within the eye range.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from usdgaze.gaze import motion
from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.errors import UsdGazeError
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.core.kinematics import Pose, forward, with_ancestors
from usdgaze.core.hints import BindHints
from usdgaze.core.rig import CharacterFrame, Chain

NECK_SEGMENT = 3
SEGMENT_OF_ROLE = {"pelvis": 0, "lowerSpine": 1, "upperSpine": 2, "neck": NECK_SEGMENT, "head": NECK_SEGMENT}


@dataclass(frozen=True)
class Shift:
    """A gaze request: at ``time_s`` seconds (from the stage start), change the gaze by (yaw, pitch) deg."""

    time_s: float
    yaw: float
    pitch: float
    cut: bool = False
    """Reach the request at once (used where the change is invisible, e.g. at zero gaze weight)."""
    timing_change: tuple[float, float] | None = None
    """Gaze change whose timing the shift takes (default: the change of request). A shift that holds
    a target while the base motion swings moves the head little in the world, whatever its request."""
    min_duration_s: float = 0.0
    """Lower bound on the shift's duration (keeps the displacement's own speed bounded)."""


@dataclass(frozen=True)
class EyeRange:
    """Eye-in-head limits in degrees (Eom et al. 2019: abduction/adduction 44.2, elevation 27.7,
    depression 47.1)."""

    yaw: float = 44.2
    up: float = 27.7
    down: float = 47.1


@dataclass(frozen=True)
class PassOptions:
    fixation_m: float = 2.0
    """Distance of the point of sight along the line of sight, in metres."""
    eye_range: EyeRange = EyeRange()
    interocular_m: float = 0.063
    """Spacing of added eyes (mean adult interpupillary distance ~63 mm)."""
    eye_above_head_m: float = 0.07
    """Added eyes sit this far above the head joint (skull base) ..."""
    eye_ahead_of_head_m: float = 0.09
    """... and this far in front of it, for a ~1.5 m head-joint height."""
    tolerance_deg: float = 0.5
    """Hold-phase error above which a request is reported as out of reach."""
    binding: BindHints = BindHints()
    """Role bindings and forward given by the user (``--bind``, ``--forward``); they win over the map's."""


@dataclass
class PassResult:
    """New animation arrays plus what a reviewer wants to see."""

    anim_joints: list[str]
    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    added_joints: list[str] = field(default_factory=list)
    added_rest_local: np.ndarray | None = None
    added_bind_world: np.ndarray | None = None
    changed_joints: list[str] = field(default_factory=list)
    requested: np.ndarray | None = None
    """Wanted change of the line of sight per frame ``(F, 2)`` (deg)."""
    achieved: np.ndarray | None = None
    """Achieved change per frame by FK ``(F, 2)``."""
    eye_angles: np.ndarray | None = None
    """Eye-in-head (yaw, pitch) per frame and eye ``(F, 2, 2)``."""
    settled: np.ndarray | None = None
    """Frames in a hold phase (a shift finished, no new one begun)."""
    seconds: np.ndarray | None = None
    """Sample times in seconds from the stage start."""
    segment_angles: np.ndarray | None = None
    """Rotation angle of each model segment's displacement per frame ``(F, 5)`` (deg)."""
    shift_timing: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    eye_positions: np.ndarray | None = None
    """World position of each eye per frame ``(2, F, 3)`` (left first)."""
    point_of_sight: np.ndarray | None = None
    """World point the eyes fixate per frame ``(F, 3)``."""


# -- the schedule ---------------------------------------------------------------------------------

@dataclass
class Schedule:
    displacement: np.ndarray
    """Per-frame segment offsets ``(F, 5, 4)`` (canonical frame)."""
    requested: np.ndarray
    """Per-frame wanted line-of-sight change ``(F, 2)``."""
    settled: np.ndarray
    timing: list[dict]
    progress: np.ndarray | None = None
    """Per-frame fraction ``(F,)`` of the active shift's gaze change done on the canonical chain."""


@dataclass
class _Segment:
    """One shift's blend: from whatever the previous shift is doing to this shift's target."""

    start_s: float
    request: np.ndarray
    target: np.ndarray
    motion: motion.GazeMotions
    previous: "_Segment | None"
    inherit: bool
    """The previous shift is still moving when this one starts: blend from its live trajectory."""

    def evaluate(self, at: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Segment offsets ``(F, 5, 4)``, wanted gaze change ``(F, 2)``, normalized time and gaze
        progress (fraction of the change, overshoot included) at ``at``."""
        if self.previous is None:
            start = np.broadcast_to(rot.IDENTITY, (len(at), 5, 4))
            start_delta = np.zeros((len(at), 2))
        elif self.inherit:
            start, start_delta, _, _ = self.previous.evaluate(at)
        else:
            start = np.broadcast_to(self.previous.target, (len(at), 5, 4))
            start_delta = np.broadcast_to(self.previous.request, (len(at), 2))
        m = self.motion
        tau = motion.normalized_time(at - self.start_s, m.duration)
        s = motion.profile(tau[:, None], m.starts[None, :], m.peak_time, m.overshoot)
        # Blending from the live start keeps position and velocity continuous at an interruption:
        # the profile's slope is zero at its start.
        d = motion.transition(start, self.target[None], s)
        change = self.request[None, :] - start_delta
        canon_a = motion.achieved_gaze(start, start_delta[:, 0])
        canon_b = motion.achieved_gaze(self.target, self.request[0])
        span = canon_b[None, :] - canon_a
        norm2 = np.sum(span * span, axis=1)
        # Unwrap the canonical yaw along the expected path: a 180 deg change is ambiguous against
        # either end but not against where the shift should be by now.
        c = motion.achieved_gaze(d, canon_a[:, 0] + s[:, 4] * span[:, 0])
        moving = norm2 > 1e-12
        sigma = np.where(moving, np.sum((c - canon_a) * span, axis=1) / np.where(moving, norm2, 1.0), s[:, 4])
        return d, start_delta + sigma[:, None] * change, tau, sigma


def schedule(gaze_map: ParametricGazeMap, shifts: list[Shift], seconds: np.ndarray) -> Schedule:
    """Per-frame displacement and wanted gaze change for a list of shifts (sorted by time)."""
    f = len(seconds)
    disp = np.broadcast_to(rot.IDENTITY, (f, 5, 4)).copy()
    wanted = np.zeros((f, 2))
    settled = np.ones(f, dtype=bool)
    progress = np.ones(f)
    if not shifts:
        return Schedule(disp, wanted, settled, [], progress)
    times = np.array([s.time_s for s in shifts])
    requests = np.array([[s.yaw, s.pitch] for s in shifts], dtype=float)
    targets = gaze_map.query(requests[:, 0], requests[:, 1]).offsets
    targets[np.all(requests == 0.0, axis=1)] = rot.IDENTITY

    info = []
    previous: _Segment | None = None
    for k, (t0, request, target) in enumerate(zip(times, requests, targets)):
        t1 = times[k + 1] if k + 1 < len(times) else np.inf
        inherit = previous is not None and t0 < previous.start_s + previous.motion.duration
        if previous is None:
            start_delta = np.zeros(2)
        elif inherit:
            start_delta = previous.evaluate(np.array([t0]))[1][0]
        else:
            start_delta = previous.request
        change = request - start_delta if shifts[k].timing_change is None else np.asarray(shifts[k].timing_change)
        # Timing only: the uncorrected blend is enough, and much cheaper.
        timing = gaze_map.query_full(change[0], change[1], correct=False).motions.timing
        if shifts[k].cut or timing[motion.DURATION] < shifts[k].min_duration_s:
            timing = np.array(timing, dtype=float)
            timing[motion.DURATION] = 0.0 if shifts[k].cut else shifts[k].min_duration_s
        segment = _Segment(float(t0), request, target, motion.GazeMotions(target, timing), previous, bool(inherit))
        rows = np.flatnonzero((seconds >= t0) & (seconds < t1))
        if len(rows):
            d, w, tau, sigma = segment.evaluate(seconds[rows])
            disp[rows], wanted[rows], progress[rows] = d, w, sigma
            settled[rows] = tau >= 1.0
        info.append({
            "time_s": float(t0), "yaw": float(request[0]), "pitch": float(request[1]),
            **{name: float(v) for name, v in zip(motion.TIMING_FIELDS, timing)},
            "interrupted": bool(np.isfinite(t1) and t1 < t0 + timing[0]),
        })
        previous = segment
    return Schedule(disp, wanted, settled, info, progress)


# -- world-space line of sight --------------------------------------------------------------------

def _horizontal_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """e1, e2 with (e1, e2, up) right-handed, so azimuth atan2(d.e2, d.e1) is counter-clockwise from above."""
    e1 = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = rot.normalize(e1 - (e1 @ up) * up)
    return e1, np.cross(up, e1)


def azimuth_elevation(direction: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(azimuth, elevation) in degrees of world directions ``(..., 3)`` about the stage up axis."""
    e1, e2 = _horizontal_basis(up)
    d = rot.normalize(direction)
    az = np.degrees(np.arctan2(d @ e2, d @ e1))
    el = np.degrees(np.arcsin(np.clip(d @ up, -1.0, 1.0)))
    return np.stack([az, el], axis=-1)


def direction_from(az_el: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World directions from (azimuth, elevation) degrees."""
    e1, e2 = _horizontal_basis(up)
    az, el = np.radians(az_el[..., 0]), np.radians(az_el[..., 1])
    return (np.cos(el) * np.cos(az))[..., None] * e1 + (np.cos(el) * np.sin(az))[..., None] * e2 + np.sin(el)[..., None] * up


def line_of_sight(left_pos, left_dir, right_pos, right_dir) -> tuple[np.ndarray, np.ndarray]:
    """Cyclopean origin and line of sight of two eyes: from their midpoint to the point of sight,
    the midpoint of the rays' closest approach (parallel rays: the mean direction)."""
    origin = 0.5 * (left_pos + right_pos)
    w0 = left_pos - right_pos
    a = np.sum(left_dir * left_dir, -1)
    b = np.sum(left_dir * right_dir, -1)
    c = np.sum(right_dir * right_dir, -1)
    d = np.sum(left_dir * w0, -1)
    e = np.sum(right_dir * w0, -1)
    den = a * c - b * b
    ok = den > 1e-12
    safe = np.where(ok, den, 1.0)
    s = np.where(ok, (b * e - c * d) / safe, 0.0)
    t = np.where(ok, (a * e - b * d) / safe, 0.0)
    point = 0.5 * ((left_pos + s[..., None] * left_dir) + (right_pos + t[..., None] * right_dir))
    sight = point - origin
    converging = ok & (s > 0) & (t > 0)
    sight = np.where(converging[..., None], sight, left_dir + right_dir)
    return origin, rot.normalize(sight)


# -- the pass ---------------------------------------------------------------------------------------

@dataclass
class _Rig:
    """The skeleton as the pass sees it: the clip's joints plus added eyes, and per-joint locals."""

    clip: SkelClip
    joints: list[str]
    parents: np.ndarray
    rest_local: np.ndarray
    rest_q: np.ndarray
    """Neutral-pose (bind pose) skeleton-space rotations per joint: where each joint looks ahead."""
    eyes: tuple[int, int]
    added: list[str]
    added_t: dict[int, np.ndarray]

    def __post_init__(self) -> None:
        # Each joint's columns are read and converted once, however many steps look at them.
        self.local = functools.lru_cache(maxsize=None)(self._local)

    def _local(self, j: int):
        f = len(self.clip.times)
        if j < len(self.clip.joints):
            return self.clip.local_trs(j)
        return np.tile(self.added_t[j], (f, 1)), np.tile(rot.IDENTITY, (f, 1)), np.ones((f, 3))


def _with_eyes(clip: SkelClip, chain: Chain, frame: CharacterFrame, options: PassOptions) -> _Rig:
    """The rig with its eye joints: existing ones, or a left and a right added under the head."""
    rest_world = clip.neutral()
    rest_q = rot.from_matrix(rest_world[:, :3, :3])
    if chain.eyes is not None:
        return _Rig(clip, list(clip.joints), clip.parents, clip.rest_local, rest_q, chain.eyes, [], {})
    head = chain.head
    # Eye placement scales with the character: the head joint (skull base) of an adult stands ~1.5 m up.
    height = (rest_world[head, :3, 3] - rest_world[:, :3, 3]) @ frame.up
    units_per_m = max(float(height.max()), 1e-9) / 1.5
    joints, added, locals_ = list(clip.joints), [], []
    for side, name in ((1.0, "LeftEye"), (-1.0, "RightEye")):
        offset = units_per_m * (options.eye_above_head_m * frame.up + options.eye_ahead_of_head_m * frame.forward
                                + side * 0.5 * options.interocular_m * frame.left)
        m = np.eye(4)
        m[:3, 3] = np.linalg.solve(rest_world[head, :3, :3], offset)
        locals_.append(m)
        joints.append(f"{clip.joints[head]}/{name}")
        added.append(joints[-1])
    eyes = (len(joints) - 2, len(joints) - 1)
    return _Rig(
        clip, joints,
        parents=np.concatenate([clip.parents, [head, head]]),
        rest_local=np.concatenate([clip.rest_local, np.stack(locals_)]),
        rest_q=np.concatenate([rest_q, rest_q[[head, head]]]),  # added eyes start aligned with the head
        eyes=eyes, added=added,
        added_t={e: m[:3, 3] for e, m in zip(eyes, locals_)},
    )


def _drive_chain(rig: _Rig, chain: Chain, frame: CharacterFrame, disp: np.ndarray, base: Pose
                 ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """New local rotations along the chain (parents first) and their new world rotations."""
    f = len(disp)
    canon = frame.rotation  # canonical -> skeleton space
    counts = np.zeros(4, dtype=int)
    for role, seg in SEGMENT_OF_ROLE.items():
        counts[seg] += len(chain.roles[role])
    role_of = {j: role for role in SEGMENT_OF_ROLE for j in chain.roles[role]}
    new_rot: dict[int, np.ndarray] = {}
    new_world: dict[int, np.ndarray] = {}
    for j in chain.path:
        _, q_j, _ = rig.local(j)
        p = int(rig.parents[j])
        parent_world = new_world.get(p, base.rotation.get(p)) if p >= 0 else np.tile(rot.IDENTITY, (f, 1))
        role = role_of.get(j)
        if role is None:
            q_new = q_j
        else:
            seg = SEGMENT_OF_ROLE[role]
            q = rot.power(disp[:, seg], 1.0 / counts[seg])  # a role's rotation spread over its joints
            if role == "pelvis":
                # Heading frame: the character frame turned about up to where the pelvis faces now.
                facing = rot.rotate(rot.multiply(base.rotation[j], rot.conjugate(rig.rest_q[j])), frame.forward)
                flat = facing - np.outer(facing @ frame.up, frame.up)
                heading = np.arctan2(np.cross(frame.forward, flat) @ frame.up, flat @ frame.forward)
                q_world = rot.conjugate_into(rot.multiply(rot.from_axis_angle(frame.up, heading), canon), q)
                q_new = rot.multiply(rot.conjugate_into(rot.conjugate(parent_world), q_world), q_j)
            else:
                # In the parent's frame as it sits at rest, as the paper's dress-pose offsets are.
                k = rot.multiply(rot.conjugate(rig.rest_q[p]), canon) if p >= 0 else canon
                q_new = rot.multiply(rot.conjugate_into(k, q), q_j)
        new_rot[j] = rot.normalize(q_new)
        new_world[j] = rot.normalize(rot.multiply(parent_world, new_rot[j]))
    return new_rot, new_world


def _counter_rotate_legs(rig: _Rig, chain: Chain, base: Pose, new_world: dict[int, np.ndarray]
                         ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Leg roots keep their world transform: undo the pelvis's change in the pelvis frame."""
    pelvis = chain.pelvis
    undo = rot.multiply(rot.conjugate(new_world[pelvis]), base.rotation[pelvis])
    rotations, translations = {}, {}
    for j in chain.leg_roots:
        t_j, q_j, _ = rig.local(j)
        rotations[j] = rot.normalize(rot.multiply(undo, q_j))
        translations[j] = rot.rotate(undo, t_j)
    return rotations, translations


@dataclass
class _Eyes:
    rotations: dict[int, np.ndarray]
    angles: np.ndarray
    """Eye-in-head (yaw, pitch) per frame and eye ``(F, 2, 2)``, after the range clamp."""
    positions: list[np.ndarray]
    directions: list[np.ndarray]


def _aim_eyes(rig: _Rig, frame: CharacterFrame, moved: Pose, sight_point: np.ndarray, limits: EyeRange) -> _Eyes:
    """Point each eye at the point of sight (Listing's law: no torsion), within the eye range."""
    f = len(sight_point)
    out = _Eyes({}, np.zeros((f, 2, 2)), [], [])
    for i, e in enumerate(rig.eyes):
        p = int(rig.parents[e])
        to_head = rot.conjugate(rig.rest_q[p])
        fwd_h, left_h, up_h = (rot.rotate(to_head, v) for v in (frame.forward, frame.left, frame.up))
        pos = moved.place(p, rig.local(e)[0])
        u_h = rot.rotate(rot.conjugate(moved.rotation[p]), rot.normalize(sight_point - pos))
        yaw = np.clip(np.degrees(np.arctan2(u_h @ left_h, u_h @ fwd_h)), -limits.yaw, limits.yaw)
        pitch = np.clip(np.degrees(np.arcsin(np.clip(u_h @ up_h, -1.0, 1.0))), -limits.down, limits.up)
        y, pc = np.radians(yaw), np.radians(pitch)
        u_h = ((np.cos(pc) * np.sin(y))[:, None] * left_h + (np.cos(pc) * np.cos(y))[:, None] * fwd_h
               + np.sin(pc)[:, None] * up_h)
        out.angles[:, i] = np.column_stack([yaw, pitch])
        rest_eye = rot.multiply(to_head, rig.rest_q[e])  # the eye in its parent, looking ahead
        out.rotations[e] = rot.normalize(rot.multiply(rot.shortest_arc(fwd_h, u_h), rest_eye))
        out.positions.append(pos)
        out.directions.append(rot.rotate(moved.rotation[p], u_h))
    return out


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
        if not np.any(hold) or np.abs(achieved[hold] - plan.requested[hold]).max() <= options.tolerance_deg:
            continue
        reach = achieved[hold].mean(axis=0)
        angles = eye_angles[hold]
        at_limit = np.any(np.abs(angles[..., 0]) >= limits.yaw - 1e-6) or np.any(
            (angles[..., 1] >= limits.up - 1e-6) | (angles[..., 1] <= -limits.down + 1e-6))
        if np.any(np.abs(base_ae[hold, 1] + plan.requested[hold, 1]) > 89.0):
            way = "down" if base_ae[hold, 1].mean() < 0 else "up"
            why = (f"the base line of sight already points {np.abs(base_ae[hold, 1]).max():.0f} deg {way}, "
                   f"and the gaze cannot pass straight {way}")
        elif at_limit:
            why = f"the eyes reach their range (yaw +-{limits.yaw:g}, up {limits.up:g}, down {limits.down:g} deg)"
        else:
            why = "the chain cannot turn that far"
        warnings.append(
            f"{clip.where()}: shift at {sh.time_s:g} s asks for yaw {sh.yaw:g}, pitch {sh.pitch:g} deg; "
            f"reached about yaw {reach[0]:.1f}, pitch {reach[1]:.1f} ({why})"
        )
    return warnings


def _assemble(rig: _Rig, rotations_new: dict[int, np.ndarray], translations_new: dict[int, np.ndarray]
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
    for j, q in rotations_new.items():
        column = anim_index[j]
        rotations[:, column] = rot.align_hemisphere(q, rotations[:, column].astype(float)).astype(np.float32)
    for j, t in translations_new.items():
        translations[:, anim_index[j]] = t.astype(np.float32)
    return anim_joints, rotations, translations, scales


def _to_world(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Directions through per-frame (or one) 3x3 maps, normalized."""
    return rot.normalize(np.einsum("fij,fj->fi", np.broadcast_to(m, (len(v), 3, 3)), v))


@dataclass
class Base:
    """The base motion as a pass sees it: the rig with its eyes, FK of what the pass reads, the
    base line of sight."""

    rig: _Rig
    pose: Pose
    skel_to_world: np.ndarray
    """Per-frame 3x3 linear part of skeleton -> world ``(F, 3, 3)``."""
    up: np.ndarray
    """World up."""
    line_of_sight: np.ndarray
    """World direction the base head looks along ``(F, 3)``."""
    ae: np.ndarray
    """Its (azimuth, elevation) in degrees ``(F, 2)``."""


def prepare(clip: SkelClip, chain: Chain, frame: CharacterFrame, options: PassOptions) -> Base:
    """The rig with eyes (added if missing), base FK of the chain, leg roots and eyes, and the base
    line of sight (where the head looks)."""
    rig = _with_eyes(clip, chain, frame, options)
    pose = forward(with_ancestors(list(chain.path) + list(chain.leg_roots) + list(rig.eyes), rig.parents),
                   rig.parents, rig.local)
    skel_to_world = clip.skel_to_world[:, :3, :3]
    up_w = clip.world_up
    head_axis = rot.rotate(rot.conjugate(rig.rest_q[chain.head]), frame.forward)
    sight = _to_world(skel_to_world, rot.rotate(pose.rotation[chain.head], head_axis))
    return Base(rig, pose, skel_to_world, up_w, sight, azimuth_elevation(sight, up_w))


@dataclass
class Body:
    """The chain driven by a displacement: new local rotations/translations and the moved eye parents."""

    rotations: dict[int, np.ndarray]
    translations: dict[int, np.ndarray]
    moved: Pose

    def eye_position(self, rig: _Rig, e: int) -> np.ndarray:
        return self.moved.place(int(rig.parents[e]), rig.local(e)[0])

    def eye_centre(self, rig: _Rig) -> np.ndarray:
        """Skeleton-space midpoint of the eyes ``(F, 3)``."""
        return 0.5 * sum(self.eye_position(rig, e) for e in rig.eyes)


def move_body(base: Base, chain: Chain, frame: CharacterFrame, displacement: np.ndarray) -> Body:
    """Drive the chain with per-frame segment offsets; legs keep their world pose; FK to the eyes."""
    rig = base.rig
    new_rot, new_world = _drive_chain(rig, chain, frame, displacement, base.pose)
    leg_rot, new_trans = _counter_rotate_legs(rig, chain, base.pose, new_world)
    new_rot.update(leg_rot)

    def new_local(j: int):
        t, q, s = rig.local(j)
        return new_trans.get(j, t), new_rot.get(j, q), s

    eye_parents = sorted({int(rig.parents[e]) for e in rig.eyes})
    moved = forward(with_ancestors(eye_parents, rig.parents), rig.parents, new_local)
    return Body(new_rot, new_trans, moved)


def apply_gaze(clip: SkelClip, chain: Chain, frame: CharacterFrame, gaze_map: ParametricGazeMap,
               shifts: list[Shift], options: PassOptions = PassOptions()) -> PassResult:
    """Run the gaze pass on one clip; see the module docstring."""
    shifts = sorted(shifts, key=lambda s: s.time_s)
    for a, b in zip(shifts, shifts[1:]):
        if a.time_s == b.time_s:
            raise UsdGazeError(f"{clip.where()}: two shifts at the same time {a.time_s:g} s")
    seconds = clip.seconds
    base = prepare(clip, chain, frame, options)
    rig, skel_to_world, up_w, base_ae = base.rig, base.skel_to_world, base.up, base.ae

    plan = schedule(gaze_map, shifts, seconds)
    body = move_body(base, chain, frame, plan.displacement)

    # The wanted line of sight and, at the fixation distance along it, the point of sight.
    wanted_ae = base_ae + plan.requested
    wanted_ae[:, 1] = np.clip(wanted_ae[:, 1], -89.0, 89.0)
    wanted_s = _to_world(np.linalg.inv(skel_to_world), direction_from(wanted_ae, up_w))
    centre = body.eye_centre(rig)
    world_scale = np.cbrt(np.abs(np.linalg.det(skel_to_world)))
    distance = np.broadcast_to(options.fixation_m / clip.meters_per_unit / world_scale, (len(seconds),))
    result = finish(clip, chain, frame, base, body, plan, centre + distance[:, None] * wanted_s, options,
                    requested=plan.requested)
    result.warnings = reach_warnings(clip, shifts, plan, base_ae, result.achieved, result.eye_angles, options)
    return result


def finish(clip: SkelClip, chain: Chain, frame: CharacterFrame, base: Base, body: Body, plan: Schedule,
           sight_point: np.ndarray, options: PassOptions, requested: np.ndarray | None = None,
           saccading: np.ndarray | None = None) -> PassResult:
    """Aim both eyes at the skeleton-space ``sight_point`` per frame, measure, assemble the arrays.

    ``requested`` is the wanted line-of-sight change per frame (default: toward ``sight_point``).
    """
    rig, skel_to_world, up_w, base_ae = base.rig, base.skel_to_world, base.up, base.ae
    eyes = _aim_eyes(rig, frame, body.moved, sight_point, options.eye_range)
    new_rot = dict(body.rotations)
    new_rot.update(eyes.rotations)
    new_trans = body.translations
    centre = body.eye_centre(rig)
    if requested is None:
        wanted_ae = azimuth_elevation(_to_world(skel_to_world, sight_point - centre), up_w)
        requested = np.column_stack([rot.unwrap_near(wanted_ae[:, 0] - base_ae[:, 0], plan.requested[:, 0]),
                                     wanted_ae[:, 1] - base_ae[:, 1]])

    # What was achieved, measured like a viewer would: from the eyes' midpoint to their point of sight.
    origin, sight = line_of_sight(eyes.positions[0], eyes.directions[0], eyes.positions[1], eyes.directions[1])
    sight_w = _to_world(skel_to_world, sight)
    achieved_ae = azimuth_elevation(sight_w, up_w)
    achieved = np.column_stack([
        rot.unwrap_near(achieved_ae[:, 0] - base_ae[:, 0], requested[:, 0]),
        achieved_ae[:, 1] - base_ae[:, 1],
    ])
    m = clip.skel_to_world

    def world(p: np.ndarray) -> np.ndarray:
        return np.einsum("fij,fj->fi", np.broadcast_to(m[:, :3, :3], (len(p), 3, 3)), p) + m[:, :3, 3]

    reach = np.linalg.norm(world(sight_point) - world(origin), axis=-1)

    anim_joints, rotations, translations, scales = _assemble(rig, new_rot, new_trans)
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
        segment_angles=np.degrees(rot.angle(plan.displacement)),
        shift_timing=plan.timing,
        eye_positions=np.stack([world(p) for p in eyes.positions]),
        point_of_sight=world(origin) + reach[:, None] * sight_w,
    )
    if rig.added:
        result.added_rest_local = rig.rest_local[-2:]
        result.added_bind_world = clip.bind_world[chain.head] @ rig.rest_local[-2:]
    return result
