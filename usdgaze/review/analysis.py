"""Measurements of a composed gaze result, on arrays: lines of sight, per-joint displacement,
eye-in-head angles, line-of-sight speed, the saccade main sequence. Pure numpy (no ``pxr``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.zero_scale import singular
from usdgaze.passes.sight import azimuth_elevation, line_of_sight

MAIN_SEQUENCE_VMAX = 500.0
"""deg/s: peak velocity a large saccade saturates at (several hundred deg/s)."""
MAIN_SEQUENCE_C = 10.0
"""deg: amplitude constant of the exponential fit Vmax (1 - exp(-A / C)) (C ~ 10-15 deg is common;
10 puts a 10 deg saccade near 320 deg/s, inside the measured 300-400)."""

ROLE_ORDER = ("pelvis", "lowerSpine", "upperSpine", "neck", "head")


def main_sequence(amplitude_deg: np.ndarray) -> np.ndarray:
    """Peak saccade velocity (deg/s) for an amplitude (deg): Vmax (1 - exp(-A / C))."""
    a = np.abs(np.asarray(amplitude_deg, dtype=float))
    return MAIN_SEQUENCE_VMAX * (1.0 - np.exp(-a / MAIN_SEQUENCE_C))


def _apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Directions ``v`` (3,) or (F, 3) through per-frame linear maps ``(F, 3, 3)``, normalized."""
    v = np.broadcast_to(v, m.shape[:-2] + (3,))
    return rot.normalize(np.einsum("fij,fj->fi", m, v))


def _solve(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Directions in a frame's own axes: ``m^-1 v``, normalized (scales and all); NaN on a frame whose
    map has no inverse (a character or joint scaled to nothing, as animators hide one: nothing to see)."""
    gone = singular(m)
    if not gone.any():
        return rot.normalize(np.linalg.solve(m, v[..., None])[..., 0])
    out = rot.normalize(np.linalg.solve(np.where(gone[..., None, None], np.eye(3), m), v[..., None])[..., 0])
    return np.where(gone[..., None], np.nan, out)


def eye_local_axes(c) -> list[np.ndarray]:
    """Each eye's joint-local axis that points along the character forward in the neutral (bind) pose."""
    return [_solve(c.neutral_world[e, :3, :3], c.frame.forward) for e in c.eyes]


def sight(c, posed) -> tuple[np.ndarray, np.ndarray]:
    """Origin ``(F, 3)`` and unit line of sight ``(F, 3)`` of the two eyes in stage space."""
    (el, er), (al, ar) = c.eyes, eye_local_axes(c)
    p = posed.positions
    return line_of_sight(p[:, el], _apply(posed.axes(el), al), p[:, er], _apply(posed.axes(er), ar))


def sight_or_head(c, posed) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sight`, or for a character without eyes (a physics pass on a rig that has none writes
    none) the head joint and where the head looks."""
    if c.eyes is None:
        return posed.positions[:, c.chain.head], head_direction(c, posed)
    return sight(c, posed)


def head_direction(c, posed) -> np.ndarray:
    """Where the head looks ``(F, 3)``: its neutral-pose forward axis, carried by its pose."""
    h = c.chain.head
    return _apply(posed.axes(h), _solve(c.neutral_world[h, :3, :3], c.frame.forward))


def _unwrap_deg(a: np.ndarray) -> np.ndarray:
    return np.degrees(np.unwrap(np.radians(a)))


def achieved_change(c) -> np.ndarray:
    """Change of the line of sight against the base motion's, per frame ``(F, 2)`` (yaw, pitch deg).

    Measured as the pass defines it: the gaze pose's eyes against the base pose's head.
    """
    _, d = sight(c, c.gaze)
    a = azimuth_elevation(d, c.up)
    b = azimuth_elevation(head_direction(c, c.base), c.up)
    yaw = (a[:, 0] - b[:, 0] + 180.0) % 360.0 - 180.0
    return np.column_stack([_unwrap_deg(yaw), a[:, 1] - b[:, 1]])


def requested_steps(seconds: np.ndarray, shifts) -> np.ndarray:
    """The requests as steps ``(F, 2)``: each holds from its time until the next (0 before the first;
    NaN while a look holds, whose request is a target)."""
    out = np.zeros((len(seconds), 2))
    for t, yaw, pitch in sorted(shifts):
        out[seconds >= t] = (yaw, pitch)
    return out


def displacement_angles(c) -> np.ndarray:
    """Angle (deg) of each joint's local rotation change, gaze against base, ``(F, J)``."""
    return np.degrees(rot.angle(rot.multiply(c.gaze.local_q, rot.conjugate(c.base.local_q))))


def chain_joints(c) -> list[tuple[str, int]]:
    """(label, joint index) for the chain roles from pelvis to head, then the left eye."""
    out = []
    for role in ROLE_ORDER:
        for j in c.chain.roles.get(role, ()):
            out.append((f"{role} ({c.joints[j].rsplit('/', 1)[-1]})", j))
    if c.eyes:
        out.append((f"left eye ({c.joints[c.eyes[0]].rsplit('/', 1)[-1]})", c.eyes[0]))
    return out


@dataclass
class ShiftCurves:
    """One shift's cascade: per joint, the angle turned since the shift began."""

    index: int
    time_s: float
    yaw: float
    pitch: float
    elapsed: np.ndarray
    """Seconds since the shift began ``(n,)``."""
    labels: list[str]
    angles: np.ndarray
    """Degrees turned since the shift began ``(n, joints)``."""


def _shift_windows(seconds: np.ndarray, shifts):
    """Each shift's index (in time order), the shift and the frame rows it holds for, until the next
    one; shifts that hold for fewer than two frames are left out, and so are those that began before
    the first frame (a shot's range cut from a take): their turn since they began is not on it."""
    shifts = sorted(shifts)
    for k, shift in enumerate(shifts):
        t1 = shifts[k + 1][0] if k + 1 < len(shifts) else np.inf
        rows = np.flatnonzero((seconds >= shift[0]) & (seconds < t1))
        if len(rows) >= 2 and shift[0] >= seconds[0] - 1e-9:
            yield k, shift, rows


def shift_cascade(c, shifts) -> list[ShiftCurves]:
    """Per shift (until the next one), each chain joint's rotation away from where the shift found it."""
    joints = chain_joints(c)
    idx = [j for _, j in joints]
    disp = rot.multiply(c.gaze.local_q[:, idx], rot.conjugate(c.base.local_q[:, idx]))
    out = []
    for k, (t0, yaw, pitch), rows in _shift_windows(c.seconds, shifts):
        if np.isnan(yaw):  # a look: no change asked
            continue
        start = disp[rows[0]]
        turned = np.degrees(rot.angle(rot.multiply(disp[rows], rot.conjugate(start)[None])))
        out.append(ShiftCurves(k, float(t0), float(yaw), float(pitch), c.seconds[rows] - c.seconds[rows[0]],
                               [label for label, _ in joints], turned))
    return out


def eye_in_head(c) -> np.ndarray:
    """Eye-in-head (yaw + left, pitch + up) per frame and eye ``(F, 2, 2)`` deg, head axes from the neutral (bind) pose."""
    h = c.chain.head
    head_m = c.gaze.axes(h)
    neutral_h = c.neutral_world[h, :3, :3]
    fwd, left, up = (_solve(neutral_h, v) for v in (c.frame.forward, c.frame.left, c.frame.up))
    out = np.zeros((len(c.seconds), 2, 2))
    for i, (e, axis) in enumerate(zip(c.eyes, eye_local_axes(c))):
        d = _solve(head_m, _apply(c.gaze.axes(e), axis))
        out[:, i, 0] = np.degrees(np.arctan2(d @ left, d @ fwd))
        out[:, i, 1] = np.degrees(np.arcsin(np.clip(d @ up, -1.0, 1.0)))
    # A mirrored character (a negative scale above the skeleton): the skeleton's left is the world's
    # right, and a yaw is toward the character's left as the world shows it, as the pass takes it
    # (its eyes turned 25 deg left were plotted at -25 under a gaze change of +30).
    mirrored = np.linalg.det(c.skel_to_world[:, :3, :3]) < 0.0
    out[:, :, 0] *= np.broadcast_to(np.where(mirrored, -1.0, 1.0), (len(out),))[:, None]
    return out


def angular_speed(seconds: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Angular speed (deg/s) of unit directions over frames (central differences; ends one-sided)."""
    if len(seconds) < 2:
        return np.zeros(len(seconds))
    step = np.degrees(np.arccos(np.clip(np.sum(directions[1:] * directions[:-1], -1), -1.0, 1.0)))
    rate = step / np.maximum(np.diff(seconds), 1e-12)
    speed = np.empty(len(seconds))
    speed[0], speed[-1] = rate[0], rate[-1]
    speed[1:-1] = 0.5 * (rate[1:] + rate[:-1])
    return speed


def sight_speed(c, posed=None) -> np.ndarray:
    """Line-of-sight speed in space (deg/s) per frame."""
    _, d = sight(c, posed if posed is not None else c.gaze)
    return angular_speed(c.seconds, d)


def change_speed(c) -> np.ndarray:
    """Speed (deg/s) of the gaze change against the base motion: the pass's own motion, without
    the base motion's turning and bobbing."""
    change = achieved_change(c)
    if len(c.seconds) < 2:
        return np.zeros(len(c.seconds))
    rate = np.linalg.norm(np.diff(change, axis=0), axis=1) / np.maximum(np.diff(c.seconds), 1e-12)
    speed = np.empty(len(c.seconds))
    speed[0], speed[-1] = rate[0], rate[-1]
    speed[1:-1] = 0.5 * (rate[1:] + rate[:-1])
    return speed


def peak_speeds(c, shifts, speed: np.ndarray | None = None) -> np.ndarray:
    """Per shift: (amplitude, peak speed) of the gaze change against the base ``(S, 2)``, deg and
    deg/s; the amplitude is how far the change moved by the next shift (or the clip's end)."""
    speed = change_speed(c) if speed is None else speed
    change = achieved_change(c)
    out = []
    for _, (_, yaw, _), rows in _shift_windows(c.seconds, shifts):
        if np.isnan(yaw):  # a look's saccades are pursuit and catch-up, not one shift
            continue
        out.append((np.linalg.norm(change[rows[-1]] - change[rows[0]]), speed[rows].max()))
    return np.array(out).reshape(-1, 2)


def target_errors(c) -> dict[str, np.ndarray]:
    """Per look-at directive, the angle (deg) between the line of sight and the direction from the
    eyes to the target, on the frames the directive holds (NaN elsewhere)."""
    if not c.looks or not c.eyes:
        return {}
    origin, d = sight(c, c.gaze)
    out = {}
    for look in c.looks:
        to_target = rot.normalize(look.positions - origin)
        err = np.degrees(np.arccos(np.clip(np.sum(d * to_target, axis=-1), -1.0, 1.0)))
        out[look.label] = np.where((c.seconds >= look.start_s) & (c.seconds <= look.end_s), err, np.nan)
    return out
