"""The eye controller of the look pass: a world point of sight per frame (pure numpy).

Events (frame, goal) come from the look pass's planner. From each event the eyes make one gaze
shift toward the goal (a main-sequence saccade, or the map's gaze progress with ``eye_timing
model``), starting from the world point they fixated just before, so the start is held against head
motion (VOR); then they stay on the goal: a direction goal (shift, release) is followed exactly,
a target is pursued (:func:`usdgaze.gaze.saccade.pursue`) with catch-up saccades.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.gaze import saccade
from usdgaze.gaze.motion import ease
from usdgaze.passes.sight import azimuth_elevation, direction_from

AROUND_DEG = 90.0
"""A shift over this (asked, or between where the eyes are and where they go) turns the eyes about up,
the way it asks or else the shorter way round: the great circle between nearly opposite directions may
go round either side, over the head, or through the back of it (each eye then swaps the limit of its
range for the other in one frame)."""


@dataclass
class Scene:
    """What the eyes see, per frame, in world space."""

    seconds: np.ndarray
    eye: np.ndarray
    """Midpoint of the eyes ``(F, 3)``."""
    base_point: np.ndarray
    """Point of sight of the base motion (along the head, at the fixation distance) ``(F, 3)``."""
    up: np.ndarray | None = None
    """World up, about which a large shift turns (see :data:`AROUND_DEG`)."""
    near: float = 0.0
    """The eyes' near point in stage units: a fixated point nearer than this (a target passing through
    the head), or behind the base motion's head, is not held as a point when a shift leaves it, only
    its direction at the shift's start."""


@dataclass
class Goal:
    kind: str
    """``target`` (a moving point), ``direction`` or ``base``."""
    points: np.ndarray
    """World point to look at per frame ``(F, 3)`` (for direction goals: at the fixation distance)."""
    cut: bool = False
    turn: float = 0.0
    """The azimuth change (deg) asked of the eyes' shift to the goal, + toward the left; 0: the
    shortest way."""
    side: float = 0.0
    """Where the goal is behind the head, the side of it the eyes keep: +1 left, -1 right, 0 either
    (see :func:`usdgaze.passes.aim.held_side`)."""


@dataclass
class Sight:
    point: np.ndarray
    """World point of sight ``(F, 3)``."""
    saccading: np.ndarray
    """Frames inside a saccade (or the model's gaze shift) ``(F,)``."""
    saccades: list
    """(onset s, amplitude deg, duration s) of every saccade."""
    side: np.ndarray | None = None
    """Per frame, the side of the head the eyes keep for a goal behind it ``(F,)`` (:attr:`Goal.side`)."""


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = rot.length(v)
    return v / np.where(d > 0, d, 1.0)[..., None], d


def _around(a: np.ndarray, b: np.ndarray, s: np.ndarray, turn: float, up: np.ndarray) -> np.ndarray:
    """Directions from ``a`` to ``b`` by fractions ``s``, azimuth and elevation about ``up`` interpolated,
    the azimuth going round the way the sign of ``turn`` says (0: the shorter way)."""
    ae_a, ae_b = azimuth_elevation(a, up), azimuth_elevation(b, up)
    left = (ae_b[:, 0] - ae_a[:, 0]) % 360.0
    if turn == 0.0:
        change = np.where(left > 180.0, left - 360.0, left)
    else:
        change = np.where(turn > 0.0, left, np.where(left > 0.0, left - 360.0, 0.0))
    # The way round is chosen once, at the start: a held point near the zenith changes its azimuth fast
    # as the eyes move, and choosing per frame flipped the path by s * 360 deg in a frame.
    change = np.unwrap(change, period=360.0)
    return direction_from(ae_a + s[:, None] * np.column_stack([change, ae_b[:, 1] - ae_a[:, 1]]), up)


def _shift(scene: Scene, out: Sight, i0: int, i1: int, start: np.ndarray, goal: np.ndarray,
           progress: np.ndarray, turn: float = 0.0) -> int:
    """Frames ``i0..`` move from the held world point ``start`` to ``goal`` with fractions ``progress``
    (one per frame from i0 to i1); returns the first frame at which the shift is done. ``turn``: the
    azimuth change asked (see :data:`AROUND_DEG`)."""
    e = scene.eye[i0:i1]
    done = np.flatnonzero(progress >= 1.0)
    n = int(done[0]) if len(done) else i1 - i0
    if n == 0:
        return i0
    s = progress[:n]
    from_dir, d0 = _unit(start[None] - e[:n])
    behind = from_dir[0] @ (scene.base_point[i0] - e[0]) < 0.0  # behind the base motion's head
    if d0[0] < scene.near or behind:
        # A point that near, or behind the head, is no point the eyes can be held on as the body moves:
        # its direction turns through the back of the head (each eye swapped the limit of its range for
        # the other in a frame). Its direction at the shift's start is held instead.
        from_dir, d0 = np.broadcast_to(from_dir[0], from_dir.shape), np.full(n, max(float(d0[0]), scene.near))
    to_dir, d1 = _unit(goal[:n] - e[:n])
    sc = np.clip(s, 0.0, 1.0)
    # Vergence changes with the inverse distance, as the eyes' convergence angle does.
    inv = (1.0 - sc) / np.maximum(d0, 1e-12) + sc / np.maximum(d1, 1e-12)
    wide = abs(turn) > AROUND_DEG or saccade.angle_deg(from_dir[:1], to_dir[:1])[0] > AROUND_DEG
    if wide and scene.up is not None:
        path = _around(from_dir, to_dir, s, turn, scene.up)
    else:
        path = saccade.slerp(from_dir, to_dir, s)
    out.point[i0:i0 + n] = e[:n] + path / inv[:, None]
    out.saccading[i0:i0 + n] = True
    return i0 + n


def _saccade_progress(scene: Scene, i0: int, i1: int, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    e = scene.eye[i0]
    amplitude = float(saccade.angle_deg(_unit(start - e)[0], _unit(goal[i0] - e)[0]))
    return saccade.progress(scene.seconds[i0:i1] - scene.seconds[i0], amplitude), amplitude


def _landing(scene: Scene, i0: int, i1: int, start: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, float, float, int]:
    """A saccade from the held point ``start`` to a moving target ``goal``: its progress (frames i0 to
    where it is done), amplitude and duration. It lands on the target at the first frame by which a
    main-sequence saccade to where the target is then could be done, and takes until then: aimed at the
    live target instead, the eyes moved the saccade's profile plus the target's own motion (a ball
    dropping past the chin: 1,391 deg/s)."""
    # No saccade lasts longer than half a turn's: the frames after that one are never needed (a long
    # shot's catch-up saccades each measured every frame to the end, quadratic in its length).
    hi = min(i1, int(np.searchsorted(scene.seconds, scene.seconds[i0] + float(saccade.duration(180.0)), "right")) + 1)
    t = scene.seconds[i0:hi] - scene.seconds[i0]
    e = scene.eye[i0:hi]
    reach = saccade.angle_deg(_unit(start[None] - e)[0], _unit(goal[i0:hi] - e)[0])
    can = np.flatnonzero(t >= saccade.duration(reach))
    k = int(can[0]) if len(can) else len(t) - 1
    if k == 0:
        return np.ones(1), 0.0, 0.0, 0
    # The main sequence's duration, unless that would land before frame k (on a target that was not there).
    lasts = float(saccade.duration(reach[k]))
    lasts = lasts if lasts > t[k - 1] else float(t[k])
    return ease(t[:k + 1] / lasts), float(reach[k]), lasts, k


PURSUIT_WINDOW_S = 1.0
"""Pursuit is traced this far ahead at a time (then twice as far, ...) until a catch-up saccade fires."""


def _pursue(scene: Scene, out: Sight, i: int, i1: int, onset_s: float, goal: np.ndarray, opts) -> None:
    """Pursuit of a target from frame ``i`` (on it) to ``i1``, with catch-up saccades. Each stretch is
    traced only as far as its catch-up saccade (a frame's tracked point does not depend on how far the
    trace goes): traced to the end each time, a 50,000-frame shot's pursuit took 29 s."""
    last_end = scene.seconds[i] if i < len(scene.seconds) else np.inf
    goal, eye, seconds = goal[:i1], scene.eye[:i1], scene.seconds[:i1]
    rates = saccade.target_rates(goal, eye, seconds)
    step = max(2, int(np.searchsorted(seconds, seconds[0] + PURSUIT_WINDOW_S)))
    while i < i1:
        span = step
        while True:
            hi = min(i1, i + span)
            tracked = saccade.pursue(goal, eye, seconds, i, onset_s, opts.pursuit_latency_s, opts.pursuit_max_deg_s,
                                     rates=rates, stop=hi)
            n = len(tracked)
            error = saccade.angle_deg(_unit(tracked - eye[i:i + n])[0], _unit(goal[i:i + n] - eye[i:i + n])[0])
            late = seconds[i:i + n] >= last_end + opts.refractory_s
            fire = np.flatnonzero((error > opts.catch_up_deg) & late)
            if (len(fire) and i + fire[0] > 0) or hi >= i1:
                break
            span *= 2
        out.point[i:i + n] = tracked
        if not len(fire) or i + fire[0] == 0:
            return
        j = i + int(fire[0])
        start = out.point[j - 1].copy()
        progress, amplitude, lasts, k = _landing(scene, j, i1, start, goal)
        i = _shift(scene, out, j, i1, start, np.broadcast_to(goal[j + k], (len(progress), 3)), progress)
        last_end = scene.seconds[j] + lasts
        out.saccades.append((float(scene.seconds[j]), amplitude, lasts))


def point_of_sight(scene: Scene, events: list[tuple[int, Goal]], opts,
                   model_progress: Callable[[int, np.ndarray, np.ndarray], np.ndarray] | None = None) -> Sight:
    """The eyes' world point of sight for events ``(frame, goal)`` sorted by frame.

    ``model_progress(frame, start_point, goal_points)``, when given, replaces the saccade profile for
    event shifts (``eye_timing model``); catch-up saccades stay saccades.
    """
    f = len(scene.seconds)
    out = Sight(scene.base_point.copy(), np.zeros(f, dtype=bool), [], np.zeros(f))
    for k, (i0, goal) in enumerate(events):
        i1 = events[k + 1][0] if k + 1 < len(events) else f
        if i0 >= i1:
            continue
        out.side[i0:i1] = goal.side
        start = out.point[i0 - 1].copy() if i0 > 0 else scene.base_point[0].copy()
        on_base = goal.kind == "base" and (i0 == 0 or np.array_equal(start, scene.base_point[i0 - 1]))
        if goal.cut or on_base:  # on_base: the eyes are on the base's gaze already (a target let go at once)
            land = i0
        elif model_progress is not None:
            land = _shift(scene, out, i0, i1, start, goal.points[i0:i1], model_progress(i0, start, goal.points)[:i1 - i0],
                          goal.turn)
        elif goal.kind == "target":
            progress, amplitude, lasts, k = _landing(scene, i0, i1, start, goal.points)
            land = _shift(scene, out, i0, i1, start, np.broadcast_to(goal.points[i0 + k], (len(progress), 3)), progress,
                          goal.turn)
            out.saccades.append((float(scene.seconds[i0]), amplitude, lasts))
        else:
            progress, amplitude = _saccade_progress(scene, i0, i1, start, goal.points)
            land = _shift(scene, out, i0, i1, start, goal.points[i0:i1], progress, goal.turn)
            out.saccades.append((float(scene.seconds[i0]), amplitude, float(saccade.duration(amplitude))))
        if land >= i1:
            continue
        if goal.kind == "target":
            _pursue(scene, out, land, i1, float(scene.seconds[i0]), goal.points, opts)
        else:
            out.point[land:i1] = goal.points[land:i1]
    return out
