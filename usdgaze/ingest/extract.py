"""A gaze displacement motion from a cleaned, cropped example (Heck 5.2.2.2).

Input: the global orientations of the four chain landmarks (pelvis, lowerSpine, upperSpine, head)
on every frame of the trial, the crop, the canonical character frame, and the known target.

* P+: last-frame orientation relative to the first (``W_last * W_first^-1``, a lab-frame rotation;
  each the mean of the few still frames ending there, see :class:`BuildSettings`),
  expressed in the character frame, then made hierarchical (each segment relative to its parent's
  displacement). The head's displacement relative to the upper spine's is the neck segment. The eye
  offset is :func:`usdgaze.gaze.motion.aim_eyes`: the one that makes the chain reach the target exactly.
* Overshoot: the head's angular velocity between frames i-k and i+k, signed by projecting it on the
  head's net rotation axis; a frame j is a candidate where the sign flips, and the peak is the first
  candidate whose m frames before move toward the target and whose m frames after move back (the
  paper says "different signs"; on noisy data that also flags the onset, so we require + then -,
  and only past half the head's net turn: at 240 Hz m frames are 25 ms, and the still head's jitter
  at the crop's start passes + then - as well).
  t_beta is where the velocity crosses zero between frame j-1 and the flagged frame j.
  beta = peak head angle / final head angle - 1, clipped at 0. No peak: t_beta = 1, beta = 0.
* Start times: the first frame where the local (parent-relative) angular speed, differenced the same
  way, exceeds the threshold (and stays above it a few frames, so that one jittery frame is not a
  start: not in the paper); 0 when it never does (Heck: "begins moving slowly at the start").
  The model's t_j is where the quintic ease-in leaves zero speed, which the threshold sees 2-10
  frames later; with ``start_refine`` (not in the paper) each detected start is then moved back to
  the t_j whose model rise ``A * ease((t - t_j) / (t_peak - t_j))`` fits the segment's measured angle
  from its first pose best (:func:`onset_fit`), within [0, detection].
* l = the crop's length; times are normalized by it (frame / (frames - 1)).

Warnings (reported, not fatal): segments that never start, no overshoot peak, a landmark turning
near 180 deg (its displacement is ambiguous), a head turning the other way from the target's yaw.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.gaze import motion
from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError
from usdgaze.ingest.settings import BuildSettings
from usdgaze.passes.options import EyeRange

CHAIN = ("pelvis", "lowerSpine", "upperSpine", "neck")
"""The four measured segments, in P+ order; the last one's landmark is the head."""

MIN_HEAD_TURN_DEG = 1.0
"""Below this net head rotation (the (0, 0) trial) the rotation axis is jitter, so no overshoot is sought."""


class ExtractionError(UsdGazeError):
    """A cropped example does not give a gaze displacement motion."""


@dataclass(frozen=True)
class Extraction:
    """One example's gaze displacement motion and what was detected on the way."""

    offsets: np.ndarray
    """P+ ``(5, 4)`` in the canonical character frame."""
    timing: np.ndarray
    """The seven floats in :data:`usdgaze.gaze.motion.TIMING_FIELDS` order."""
    start_frames: np.ndarray
    """Start frame of each chain segment (crop-relative, fractional): the model's t_j fitted back from
    the detection (or the detection itself without ``start_refine``), -1 where none was detected."""
    detected_frames: np.ndarray
    """Frame where each segment's local speed first crossed the threshold (crop-relative), -1 where never."""
    peak_frame: float | None
    """Overshoot peak (crop-relative, fractional: the velocity's zero crossing), None where none was found."""
    segment_angles_deg: np.ndarray
    """Net rotation of each landmark (pelvis, lower spine, upper spine, head) from first to last pose."""
    head_angle_deg: float
    """Final head rotation from the first cropped frame."""
    peak_angle_deg: float
    frames: int
    warnings: list[str] = field(default_factory=list)


def _window(frames: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    i = np.arange(frames)
    return np.maximum(i - k, 0), np.minimum(i + k, frames - 1)


def angular_speed(q: np.ndarray, k: int, rate: float) -> np.ndarray:
    """Angle between orientations ``q[i-k]`` and ``q[i+k]`` over their time apart, deg/s (ends one-sided)."""
    lo, hi = _window(len(q), k)
    dt = np.maximum(hi - lo, 1) / rate
    return np.degrees(rot.angle(rot.relative(q[lo], q[hi]))) / dt


def signed_velocity(q: np.ndarray, axis: np.ndarray, k: int, rate: float) -> np.ndarray:
    """Angular velocity (deg/s) of global orientations ``q`` projected on a lab-frame ``axis``."""
    lo, hi = _window(len(q), k)
    dt = np.maximum(hi - lo, 1) / rate
    step = rot.to_rotvec(rot.multiply(q[hi], rot.conjugate(q[lo])))
    return np.degrees(step @ axis) / dt


def local_orientations(orientations: np.ndarray) -> np.ndarray:
    """Each landmark relative to its parent (the pelvis relative to the stabilized root, i.e. as is)."""
    local = orientations.copy()
    local[:, 1:] = rot.relative(orientations[:, :-1], orientations[:, 1:])
    return local


def mean_pose(orientations: np.ndarray) -> np.ndarray:
    """Chordal mean of orientations ``(n, ..., 4)`` over the first axis (rotation matrices averaged, then
    projected back to a rotation)."""
    return rot.from_matrix(rot.to_matrix(orientations).mean(axis=0))


def pose_offsets(first: np.ndarray, last: np.ndarray, frame: np.ndarray, yaw: float, pitch: float) -> np.ndarray:
    """P+ ``(5, 4)`` from the first and last poses ``(4, 4)``: hierarchical displacements in the
    character frame, eyes aimed at the target."""
    global_lab = rot.multiply(last, rot.conjugate(first))
    global_char = rot.conjugate_into(rot.conjugate(frame), global_lab)
    body = global_char.copy()
    body[1:] = rot.relative(global_char[:-1], global_char[1:])
    eyes = motion.aim_eyes(body, np.asarray(yaw, dtype=float), np.asarray(pitch, dtype=float))
    return rot.positive_w(np.concatenate([body, eyes[None]], axis=0))


def first_above(speed: np.ndarray, threshold: float, hold: int = 1) -> int:
    """First index where ``speed`` exceeds ``threshold`` and stays above it ``hold`` frames, or -1."""
    above = np.asarray(speed) > threshold
    if hold > 1:
        run = np.convolve(above.astype(int), np.ones(hold, dtype=int), mode="valid")
        above = np.zeros_like(above)
        above[: len(run)] = run == hold
    hits = np.flatnonzero(above)
    return int(hits[0]) if len(hits) else -1


def overshoot_peak(velocity: np.ndarray, m: int, earliest: int = 0) -> int | None:
    """First frame j >= ``earliest`` where the signed velocity flips from the m-frame mean before (> 0)
    to after (< 0)."""
    v = np.asarray(velocity, dtype=float)
    n = len(v)
    sign = np.sign(v)
    candidates = np.flatnonzero(sign[1:] != sign[:-1]) + 1
    candidates = candidates[candidates >= max(earliest, 1)]
    if not len(candidates):
        return None
    c = np.concatenate([[0.0], np.cumsum(v)])
    lo = np.maximum(candidates - m, 0)
    hi = np.minimum(candidates + 1 + m, n)
    before = (c[candidates] - c[lo]) / np.maximum(candidates - lo, 1)
    after = (c[hi] - c[candidates + 1]) / np.maximum(hi - candidates - 1, 1)
    ok = (before > 0) & (after < 0) & (candidates + 1 < n)
    return int(candidates[ok][0]) if np.any(ok) else None


def _rise_cost(theta: np.ndarray, used: np.ndarray, amplitude: np.ndarray, onset: np.ndarray,
               end: np.ndarray) -> np.ndarray:
    """Squared misfit ``(S, K)`` of rises ``A * ease((t - onset) / (end - onset))`` with candidate
    ``onset`` and ``end`` ``(S, K)`` to ``theta`` ``(n, S)`` over the frames marked ``used`` ``(n, S)``."""
    i = np.arange(len(theta), dtype=float)
    u = (i[None, None, :] - onset[..., None]) / np.maximum(end - onset, 1e-9)[..., None]  # (S, K, n)
    curve = motion.ease(u) * used.T[:, None, :]
    y = (theta * used).T[:, None, :]
    return ((y - amplitude[:, None, None] * curve) ** 2).sum(axis=-1)


def onset_fit(theta: np.ndarray, detected: np.ndarray, peak: np.ndarray, amplitude: np.ndarray,
              fit_fraction: float = 0.9, late: float = 3.0) -> np.ndarray:
    """Model start times ``t_j`` (fractional frames) from threshold detections, by inverting the ease-in.

    ``theta`` ``(F, S)``: each segment's signed rotation angle from its first pose, frame by frame;
    ``detected`` ``(S,)``: its threshold-crossing frame (-1: none); ``peak`` ``(S,)``: the frame of its
    largest angle (the overshoot peak, or somewhere on the final plateau) and ``amplitude`` ``(S,)``
    that angle. During the rise :mod:`usdgaze.gaze.motion` gives
    ``theta(t) = A * ease((t - t_j) / (t_end - t_j))``, ``t_end`` the overshoot peak ``t_beta`` (or
    where the segment reaches its final angle when it does not overshoot). That
    curve is fitted (least squares) to ``theta`` from the first frame to the first frame at or after
    the detection where ``theta`` reaches ``fit_fraction * A``, over candidate ``t_j`` in
    ``[0, detected]`` and ``t_end`` after the detection and at most ``late`` frames past ``peak``
    (a peak found on a noisy plateau is rough), on a grid of 1 by 2 frames, then finer ones around
    its best down to 1/20 by 1/10 frame. Returns ``detected`` (as floats) where there is no
    detection or nothing to fit (amplitude not positive, peak not after the detection).
    """
    theta = np.asarray(theta, dtype=float)
    detected = np.asarray(detected)
    peak = np.asarray(peak, dtype=float)
    amplitude = np.asarray(amplitude, dtype=float)
    frames = len(theta)
    out = detected.astype(float)
    ok = (detected >= 0) & (amplitude > 0) & (peak > detected)
    if not np.any(ok):
        return out
    i = np.arange(frames)
    # last frame of each fit: the first at or after the detection reaching fit_fraction of the amplitude
    reached = (i[:, None] >= detected) & (theta >= fit_fraction * amplitude)
    last = np.where(reached.any(axis=0), reached.argmax(axis=0), frames - 1)
    last = np.minimum(last, np.floor(peak)).astype(int)
    n = int(last[ok].max()) + 1
    theta, used = theta[:n], (i[:n, None] <= last)
    d = np.where(ok, detected, 0).astype(float)
    low = d + 0.5  # (S,) the rise's end: after the detection...
    high = np.where(ok, peak + late, low)  # ...and not long after the peak

    def search(onsets: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Best (onset, end) per segment among the candidate grids ``(S, A)`` x ``(S, B)``."""
        c = np.repeat(onsets, ends.shape[1], axis=1)
        e = np.tile(ends, (1, onsets.shape[1]))
        cost = _rise_cost(theta, used, amplitude, c, e)
        cost[(c < 0) | (c > d[:, None])] = np.inf
        k = np.argmin(cost, axis=1)
        rows = np.arange(len(k))
        return c[rows, k], e[rows, k]

    # a grid of 1 x 2 frames over the whole range, then finer grids (1/5, 1/20 frame) around the best
    onsets = np.tile(np.arange(d.max() + 1.0), (len(d), 1))
    ends = np.minimum(low[:, None] + np.arange(0.0, (high - low).max() + 2.0, 2.0)[None, :], high[:, None])
    c, e = search(onsets, ends)
    for step, reach in ((0.2, 1.0), (0.05, 0.2)):
        around = np.arange(-reach, reach + step / 2, step)
        ends = np.clip(e[:, None] + 2 * around[None, :], low[:, None], high[:, None])
        c, e = search(c[:, None] + around[None, :], ends)
    out[ok] = np.clip(c, 0.0, d)[ok]
    return out


def start_angles(local: np.ndarray, first: np.ndarray, detected: np.ndarray,
                 window: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inputs of :func:`onset_fit` from the cropped local orientations ``(F, S, 4)``.

    Each segment's peak is the frame, at or after its detection, where its rotation from the first
    local pose ``first`` ``(S, 4)`` is largest (averaged over ``window`` frames either side, so one
    noisy frame does not make it); its amplitude is that rotation vector averaged over those frames,
    and theta each frame's rotation vector projected on that amplitude's axis (the model turns each
    segment about one axis). Returns theta ``(F, S)`` (deg), peak frames and amplitudes (deg).
    """
    rotvec = rot.to_rotvec(rot.relative(first[None], local))  # (F, S, 3)
    frames = len(local)
    lo, hi = _window(frames, window)
    total = np.concatenate([np.zeros((1, rotvec.shape[1])), np.cumsum(np.linalg.norm(rotvec, axis=-1), axis=0)])
    smooth = (total[hi + 1] - total[lo]) / (hi - lo + 1)[:, None]  # (F, S)
    i = np.arange(frames)
    smooth[i[:, None] < np.asarray(detected)[None, :]] = -np.inf
    peak = smooth.argmax(axis=0)
    near = np.abs(i[:, None] - peak[None, :]) <= window  # (F, S)
    mean = (rotvec * near[..., None]).sum(axis=0) / near.sum(axis=0)[:, None]
    amplitude = np.linalg.norm(mean, axis=-1)
    axis = mean / np.maximum(amplitude, 1e-12)[:, None]
    theta = np.degrees((rotvec * axis[None]).sum(axis=-1))
    return theta, peak.astype(float), np.degrees(amplitude)


def _end_poses(orientations: np.ndarray, start: int, end: int, rate: float,
               settings: BuildSettings) -> tuple[np.ndarray, np.ndarray]:
    """First and last poses ``(4, 4)``: each the mean of the still frames ending at the crop's ends."""
    # The crop starts at the end of the first rest and ends at the end of the second: the pose is
    # still over the few frames that end there, so their mean keeps marker jitter out of P+.
    n = max(int(round(settings.pose_window_s * rate)), 1)
    first = mean_pose(orientations[max(start - n + 1, 0) : start + 1])
    last = mean_pose(orientations[max(end - n + 1, start) : end + 1])
    return first, last


def _pose_warnings(offsets: np.ndarray, net_angles: np.ndarray, yaw: float) -> list[str]:
    """Warnings about the displacement itself: an ambiguous near-180 deg turn, a head turning away."""
    warnings = []
    if net_angles.max() > 170.0:
        warnings.append(f"a landmark turned {net_angles.max():.0f} deg: displacements near 180 deg are ambiguous")
    body = motion.chain_rotation(offsets[:4])
    body_yaw = float(rot.direction_to_yaw_pitch(rot.rotate(body, rot.FORWARD), 0.0)[0])
    if abs(yaw) >= 20.0 and abs(body_yaw) >= 10.0 and np.sign(body_yaw) != np.sign(yaw):
        warnings.append(f"the head turned {body_yaw:+.0f} deg, the other way from the target yaw {yaw:+g}")
    # The eyes take what the body left of the target: past their range, the trial never reached it
    # (a head turned 15 deg up for a target at (150, -60) was stored with the eyes 130 deg in the head).
    eye_yaw, eye_pitch = (float(v) for v in rot.direction_to_yaw_pitch(rot.rotate(offsets[4], rot.FORWARD), 0.0))
    limits = EyeRange()
    if abs(eye_yaw) > limits.yaw + 1.0 or not -limits.down - 1.0 <= eye_pitch <= limits.up + 1.0:
        warnings.append(f"the eyes would turn yaw {eye_yaw:+.0f}, pitch {eye_pitch:+.0f} deg in the head to reach the "
                        f"target, past their range (yaw +-{limits.yaw:g}, up {limits.up:g}, down {limits.down:g}): the "
                        f"trial did not reach its target, or the sheet names another")
    return warnings


def _detect_starts(local: np.ndarray, start: int, end: int, rate: float,
                   settings: BuildSettings) -> tuple[np.ndarray, list[str]]:
    """Crop-relative frame where each segment's local speed first holds above the threshold (-1: never)."""
    k = settings.velocity_k
    speeds = np.stack([angular_speed(local[:, j], k, rate) for j in range(local.shape[1])])[:, start : end + 1]
    hold = max(int(round(settings.start_hold_s * rate)), 1)
    detected = np.array([first_above(s, settings.start_speed_deg_s, hold) for s in speeds])
    slow = [name for name, s in zip(CHAIN, detected) if s < 0]
    warnings = [f"start 0 (never above {settings.start_speed_deg_s:g} deg/s): {', '.join(slow)}"] if slow else []
    return detected, warnings


def _overshoot(orientations: np.ndarray, first: np.ndarray, last: np.ndarray, start: int, end: int,
               rate: float, settings: BuildSettings) -> tuple[float | None, float, float, float, float, list[str]]:
    """The head's overshoot: peak frame (or None), peak and final angles (rad), beta, t_beta, warnings."""
    k, m = settings.velocity_k, settings.peak_window_m
    span = end - start
    warnings = []
    head = orientations[:, 3]
    net = rot.to_rotvec(rot.multiply(last[3], rot.conjugate(first[3])))
    final = float(np.linalg.norm(net))
    peak, peak_angle, beta, t_peak = None, final, 0.0, 1.0
    if np.degrees(final) < MIN_HEAD_TURN_DEG:
        warnings.append(f"the head turns {np.degrees(final):.2f} deg: too little to look for an overshoot")
    else:
        velocity = signed_velocity(head, net / final, k, rate)[start : end + 1]
        # A peak lies past half the head's net turn (not in the paper): m frames are 25 ms at 240 Hz,
        # and the still head's jitter at the crop's start passes the + then - test there.
        turned = rot.angle(rot.multiply(head[start : end + 1], rot.conjugate(first[3]))) >= 0.5 * final
        j = overshoot_peak(velocity, m, int(np.argmax(turned)))
        if j is not None:
            peak_angle = float(rot.angle(rot.multiply(head[start + j], rot.conjugate(first[3]))))
            beta = max(peak_angle / final - 1.0, 0.0)
            # The flip lies between frames j-1 and j: place it where the velocity crosses zero.
            before, after = velocity[j - 1], velocity[j]
            peak = float(j - 1 + before / (before - after)) if before != after else float(j)
            t_peak = peak / span
    if peak is None:
        warnings.append("no overshoot peak (t_beta = 1, beta = 0)")
    return peak, peak_angle, final, beta, t_peak, warnings


def _model_starts(local: np.ndarray, first: np.ndarray, start: int, end: int, detected: np.ndarray,
                  settings: BuildSettings) -> np.ndarray:
    """Start frames of the model: the detections, moved back to the fitted t_j with ``start_refine``."""
    # The threshold crossing comes after the model's t_j (the ease-in leaves it at zero speed): fit
    # each detected segment's rise to move its start back to t_j.
    starts = detected.astype(float)
    if settings.start_refine:
        first_local = local_orientations(first[None])[0]
        theta, peaks, amplitude = start_angles(local[start : end + 1], first_local, detected)
        starts = onset_fit(theta, detected, peaks, amplitude, settings.start_fit_fraction)
    return starts


def _timing(span: int, rate: float, starts: np.ndarray, t_peak: float, beta: float) -> np.ndarray:
    """The seven timing floats in :data:`usdgaze.gaze.motion.TIMING_FIELDS` order."""
    timing = np.zeros(len(motion.TIMING_FIELDS))
    timing[motion.DURATION] = span / rate
    timing[motion.START_SLICE] = np.maximum(starts, 0) / span
    timing[motion.PEAK] = t_peak
    timing[motion.BETA] = beta
    return timing


def extract(orientations: np.ndarray, crop: tuple[int, int], frame: np.ndarray, rate: float, yaw: float,
            pitch: float, settings: BuildSettings = BuildSettings()) -> Extraction:
    """Gaze displacement motion of one example.

    ``orientations`` ``(F, 4, 4)``: global orientations of the pelvis, lower-spine, upper-spine and head
    landmarks on every frame of the trial; ``crop``: first and last kept frame (inclusive);
    ``frame``: the canonical character frame in the same space. Velocities are differenced on the
    whole trial (the frames around the crop are real neighbours), then read inside the crop.
    """
    orientations = rot.normalize(np.asarray(orientations, dtype=float))
    start, end = crop
    if not 0 <= start < end < len(orientations):
        raise ExtractionError(f"crop {start}-{end} is not inside frames 0-{len(orientations) - 1} with at least 2 frames")
    frames = end - start + 1
    span = frames - 1

    first, last = _end_poses(orientations, start, end, rate, settings)
    offsets = pose_offsets(first, last, frame, yaw, pitch)
    net_angles = np.degrees(rot.angle(rot.multiply(last, rot.conjugate(first))))
    warnings = _pose_warnings(offsets, net_angles, yaw)
    local = local_orientations(orientations)
    detected, slow = _detect_starts(local, start, end, rate, settings)
    peak, peak_angle, final, beta, t_peak, missed = _overshoot(orientations, first, last, start, end, rate, settings)
    starts = _model_starts(local, first, start, end, detected, settings)
    return Extraction(
        offsets=offsets,
        timing=_timing(span, rate, starts, t_peak, beta),
        start_frames=starts,
        detected_frames=detected,
        peak_frame=peak,
        segment_angles_deg=net_angles,
        head_angle_deg=float(np.degrees(final)),
        peak_angle_deg=float(np.degrees(peak_angle)),
        frames=frames,
        warnings=warnings + slow + missed,
    )
