"""The schedule of a gaze pass: per-frame segment offsets and wanted gaze change from a list of shifts.

Shift k blends every segment from the state the previous shift left it in to the map's answer for the
request (identity for (0, 0)), with the map's timing for the *change* (Heck 5.2.3: cascade, overshoot,
settle). Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.gaze import motion
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.options import Shift


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
