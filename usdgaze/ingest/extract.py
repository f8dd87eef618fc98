"""A gaze displacement motion from a cleaned, cropped example (Heck 5.2.2.2).

Input: the global orientations of the four chain landmarks (pelvis, lowerSpine, upperSpine, head)
on every frame of the trial, the crop, the canonical character frame, and the known target.

* P+: last-frame orientation relative to the first (``W_last * W_first^-1``, a lab-frame rotation;
  each the mean of the few still frames ending there, see :class:`BuildSettings`),
  expressed in the character frame, then made hierarchical (each segment relative to its parent's
  displacement). The head's displacement relative to the upper spine's is the neck segment. The eye
  offset is :func:`usdgaze.motion.aim_eyes`: the one that makes the chain reach the target exactly.
* Overshoot: the head's angular velocity between frames i-k and i+k, signed by projecting it on the
  head's net rotation axis; a frame j is a candidate where the sign flips, and the peak is the first
  candidate whose m frames before move toward the target and whose m frames after move back (the
  paper says "different signs"; on noisy data that also flags the onset, so we require + then -).
  t_beta is where the velocity crosses zero between frame j-1 and the flagged frame j.
  beta = peak head angle / final head angle - 1, clipped at 0. No peak: t_beta = 1, beta = 0.
* Start times: the first frame where the local (parent-relative) angular speed, differenced the same
  way, exceeds the threshold (and stays above it a few frames, so that one jittery frame is not a
  start: not in the paper); 0 when it never does (Heck: "begins moving slowly at the start").
* l = the crop's length; times are normalized by it (frame / (frames - 1)).

Warnings (reported, not fatal): segments that never start, no overshoot peak, a landmark turning
near 180 deg (its displacement is ambiguous), a head turning the other way from the target's yaw.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import motion
from .. import rotations as rot
from ..errors import UsdGazeError
from .settings import BuildSettings

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
    """The seven floats in :data:`usdgaze.motion.TIMING_FIELDS` order."""
    start_frames: np.ndarray
    """Detected start frame of each chain segment (crop-relative), -1 where none was found."""
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


def overshoot_peak(velocity: np.ndarray, m: int) -> int | None:
    """First frame j where the signed velocity flips from the m-frame mean before (> 0) to after (< 0)."""
    v = np.asarray(velocity, dtype=float)
    n = len(v)
    sign = np.sign(v)
    candidates = np.flatnonzero(sign[1:] != sign[:-1]) + 1
    if not len(candidates):
        return None
    c = np.concatenate([[0.0], np.cumsum(v)])
    lo = np.maximum(candidates - m, 0)
    hi = np.minimum(candidates + 1 + m, n)
    before = (c[candidates] - c[lo]) / np.maximum(candidates - lo, 1)
    after = (c[hi] - c[candidates + 1]) / np.maximum(hi - candidates - 1, 1)
    ok = (before > 0) & (after < 0) & (candidates + 1 < n)
    return int(candidates[ok][0]) if np.any(ok) else None


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
    k, m = settings.velocity_k, settings.peak_window_m
    warnings: list[str] = []

    # The crop starts at the end of the first rest and ends at the end of the second: the pose is
    # still over the few frames that end there, so their mean keeps marker jitter out of P+.
    n = max(int(round(settings.pose_window_s * rate)), 1)
    first = mean_pose(orientations[max(start - n + 1, 0) : start + 1])
    last = mean_pose(orientations[max(end - n + 1, start) : end + 1])
    offsets = pose_offsets(first, last, frame, yaw, pitch)
    net_angles = np.degrees(rot.angle(rot.multiply(last, rot.conjugate(first))))
    if net_angles.max() > 170.0:
        warnings.append(f"a landmark turned {net_angles.max():.0f} deg: displacements near 180 deg are ambiguous")
    body = motion.chain_rotation(offsets[:4])
    body_yaw = float(rot.direction_to_yaw_pitch(rot.rotate(body, rot.FORWARD), 0.0)[0])
    if abs(yaw) >= 20.0 and abs(body_yaw) >= 10.0 and np.sign(body_yaw) != np.sign(yaw):
        warnings.append(f"the head turned {body_yaw:+.0f} deg, the other way from the target yaw {yaw:+g}")

    local = local_orientations(orientations)
    speeds = np.stack([angular_speed(local[:, j], k, rate) for j in range(local.shape[1])])[:, start : end + 1]
    hold = max(int(round(settings.start_hold_s * rate)), 1)
    starts = np.array([first_above(s, settings.start_speed_deg_s, hold) for s in speeds])
    slow = [name for name, s in zip(CHAIN, starts) if s < 0]
    if slow:
        warnings.append(f"start 0 (never above {settings.start_speed_deg_s:g} deg/s): {', '.join(slow)}")

    head = orientations[:, 3]
    net = rot.to_rotvec(rot.multiply(last[3], rot.conjugate(first[3])))
    final = float(np.linalg.norm(net))
    peak, peak_angle, beta, t_peak = None, final, 0.0, 1.0
    if np.degrees(final) < MIN_HEAD_TURN_DEG:
        warnings.append(f"the head turns {np.degrees(final):.2f} deg: too little to look for an overshoot")
    else:
        velocity = signed_velocity(head, net / final, k, rate)[start : end + 1]
        j = overshoot_peak(velocity, m)
        if j is not None:
            peak_angle = float(rot.angle(rot.multiply(head[start + j], rot.conjugate(first[3]))))
            beta = max(peak_angle / final - 1.0, 0.0)
            # The flip lies between frames j-1 and j: place it where the velocity crosses zero.
            before, after = velocity[j - 1], velocity[j]
            peak = float(j - 1 + before / (before - after)) if before != after else float(j)
            t_peak = peak / span
    if peak is None:
        warnings.append("no overshoot peak (t_beta = 1, beta = 0)")
    timing = np.zeros(len(motion.TIMING_FIELDS))
    timing[motion.DURATION] = span / rate
    timing[motion.START_SLICE] = np.maximum(starts, 0) / span
    timing[motion.PEAK] = t_peak
    timing[motion.BETA] = beta
    return Extraction(
        offsets=offsets,
        timing=timing,
        start_frames=starts,
        peak_frame=peak,
        segment_angles_deg=net_angles,
        head_angle_deg=float(np.degrees(final)),
        peak_angle_deg=float(np.degrees(peak_angle)),
        frames=frames,
        warnings=warnings,
    )
