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

COAST_S = 0.1
"""A segment that an interrupted shift was taking away from the new shift's target coasts to a stop,
its velocity decaying over about this long, while the new shift takes it to its own target: one that
went on toward the goal given up (the interrupted shift's own path) had to come back from further in
the new shift's shorter window (170 deg then 0 after 0.4 s at 24 fps: the pelvis 18 deg back in two
frames, the head 826 deg/s). A segment already headed toward the new target (a re-plan toward a
moving one) goes on along the interrupted path."""
_RATE_DT_S = 1e-3  # the step the interrupted shift's rates are measured over


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
    canon: np.ndarray
    """The canonical gaze change of the target: the end of this shift and the start of a next one
    that begins after it settles."""
    leaving: tuple[np.ndarray, np.ndarray] | None = None
    """With ``inherit``: the interrupted shift's offsets and wanted gaze change at this one's start and
    :data:`_RATE_DT_S` after it (:func:`_leaving`), from which its coast and this shift's timing come."""

    def __post_init__(self) -> None:
        if self.inherit:  # the state and rates the interrupted shift leaves, for its coast
            d, wanted = self.leaving
            self.coast = (d[0], rot.to_rotvec(rot.relative(d[0], d[1])) / _RATE_DT_S,
                          wanted[0], (wanted[1] - wanted[0]) / _RATE_DT_S)
            # Per segment: does the interrupted shift's goal lie nearer this one's than where it is now?
            self.goes_on = rot.angle(rot.relative(self.previous.target, self.target)) \
                < rot.angle(rot.relative(d[0], self.target))

    def _start(self, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment offsets ``(F, 5, 4)`` and wanted gaze change ``(F, 2)`` to blend from, from the
        interrupted shift: along its path where it heads for this one's target, else coasting from
        its state at this one's start (position and velocity continuous either way)."""
        if self.goes_on.all():
            return self.previous.evaluate(at)[:2]
        q0, omega, delta0, rate = self.coast
        k = COAST_S * -np.expm1(-np.maximum(at - self.start_s, 0.0) / COAST_S)
        start = rot.multiply(q0[None], rot.from_rotvec(omega[None] * k[:, None, None]))
        if self.goes_on.any():
            start[:, self.goes_on] = self.previous.evaluate(at)[0][:, self.goes_on]
        return start, delta0 + rate * k[:, None]

    def evaluate(self, at: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Segment offsets ``(F, 5, 4)``, wanted gaze change ``(F, 2)``, normalized time and gaze
        progress (fraction of the change, overshoot included) at ``at``."""
        tau = motion.normalized_time(at - self.start_s, self.motion.duration)
        keep, source = _settled_once(tau)
        d, wanted, _, sigma = self._evaluate(at[keep], tau[keep])
        return d[source], wanted[source], tau, sigma[source]

    def still_start(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where a shift that does not interrupt another starts: offsets ``(5, 4)``, wanted gaze
        change and canonical gaze change ``(2,)`` (the previous shift's target, or rest)."""
        if self.previous is None:
            return rot.IDENTITY[None].repeat(5, axis=0), np.zeros(2), np.zeros(2)  # identity changes nothing
        return self.previous.target, self.previous.request, self.previous.canon

    def _evaluate(self, at: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        # A still start is one row that broadcasts: its relative rotation and canonical gaze are
        # computed once, not per frame.
        if self.inherit:
            start, start_delta = self._start(at)
            canon_a = motion.achieved_gaze(start, start_delta[:, 0])
        else:
            start, start_delta, canon_a = (a[None] for a in self.still_start())
        m = self.motion
        d, wanted, sigma = _blend(tau, (start, start_delta, canon_a), (self.target[None], self.request[None, :],
                                  self.canon[None, :]), (m.starts[None, :], m.peak_time, m.overshoot))
        return d, wanted, tau, sigma


def _settled_once(tau: np.ndarray) -> tuple[slice | np.ndarray, slice | np.ndarray]:
    """The frames of a segment to evaluate (``keep``) and, per frame, its row among them (``source``).

    Every settled frame holds the same state, the target (from a moving start too: its share is
    none once every segment's profile is 1): one of them is evaluated. Each frame of a shift that
    took over from another was, to the end of the clip: a planner's 860 re-plans of a held target
    on a 50,000-frame shot took 13.6 s."""
    settled = np.flatnonzero(tau >= 1.0)
    if len(settled) < 2:
        return slice(None), slice(None)
    keep = np.ones(len(tau), dtype=bool)
    keep[settled[1:]] = False
    source = np.cumsum(keep) - 1
    source[settled] = source[settled[0]]
    return keep, source


def _blend(tau: np.ndarray, start: tuple, goal: tuple, timing: tuple, each: np.ndarray | None = None
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets, wanted gaze change and gaze progress at normalized times ``tau (F,)``, from ``start``
    (offsets, wanted and canonical gaze change) to ``goal`` (target offsets, request, canonical gaze
    change) with ``timing`` (segment starts, peak time, overshoot): per frame, or one row that
    broadcasts; or, with ``each`` (per frame, its row), one row per segment of several."""
    (start, start_delta, canon_a), (target, request, canon) = start, goal
    # The turn from start to target (motion.transition's), measured once per row, not per frame.
    turn = rot.to_rotvec(rot.relative(start, target))
    if each is not None:
        start, start_delta, canon_a, request, canon, turn = (
            a[each] for a in (start, start_delta, canon_a, request, canon, turn))
        timing = (timing[0][each], timing[1][each, None], timing[2][each, None])
    s = motion.profile(tau[:, None], *timing)
    # Blending from the live start keeps position and velocity continuous at an interruption:
    # the profile's slope is zero at its start.
    d = rot.multiply(start, rot.from_rotvec(turn * s[..., None]))
    change = request - start_delta
    span = canon - canon_a
    norm2 = rot.dot(span, span)
    # Unwrap the canonical yaw along the expected path: a 180 deg change is ambiguous against
    # either end but not against where the shift should be by now.
    c = motion.achieved_gaze(d, canon_a[:, 0] + s[:, 4] * span[:, 0])
    moving = norm2 > 1e-12
    sigma = np.where(moving, rot.dot(c - canon_a, span) / np.where(moving, norm2, 1.0), s[:, 4])
    return d, start_delta + sigma[:, None] * change, sigma


def _evaluate_still(segments: list[_Segment], ats: list[np.ndarray]) -> list[tuple]:
    """:meth:`_Segment.evaluate` of segments that interrupt none (their starts are still), on their
    frames ``ats``: all of them in one pass, each row with its segment's values (each frame's numbers
    are its own either way: a pass of four shifts made four passes of some 100 numpy calls each)."""
    taus = [motion.normalized_time(at - g.start_s, g.motion.duration) for g, at in zip(segments, ats)]
    kept = [_settled_once(tau) for tau in taus]
    rows = [tau[keep] for tau, (keep, _) in zip(taus, kept)]
    each = np.repeat(np.arange(len(segments)), [len(r) for r in rows])
    starts = [g.still_start() for g in segments]
    start = tuple(np.stack([st[i] for st in starts]) for i in range(3))
    goal = tuple(np.stack([getattr(g, name) for g in segments]) for name in ("target", "request", "canon"))
    timing = tuple(np.stack([getattr(g.motion, name) for g in segments]) for name in ("starts", "peak_time", "overshoot"))
    d, wanted, sigma = _blend(np.concatenate(rows), start, goal, timing, each)
    out, lo = [], 0
    for tau, r, (_, source) in zip(taus, rows, kept):
        part = slice(lo, lo + len(r))
        out.append((d[part][source], wanted[part][source], tau, sigma[part][source]))
        lo += len(r)
    return out


def schedule(gaze_map: ParametricGazeMap, shifts: list[Shift], seconds: np.ndarray) -> Schedule:
    """Per-frame displacement and wanted gaze change for a list of shifts (sorted by time)."""
    return Scheduler(gaze_map, seconds).plan(shifts)


class Scheduler:
    """:func:`schedule` for a list of shifts that grows at its end, as a planner's does.

    Each frame takes the last shift that starts at or before it, so an appended shift is evaluated on
    its own frames only; any other change of the list schedules it afresh. Every call asks the map for all
    requests at once, as one :func:`schedule` does (a :class:`~usdgaze.passes.body.CachedMap` answers
    the known ones from its rows).
    """

    def __init__(self, gaze_map: ParametricGazeMap, seconds: np.ndarray) -> None:
        self.map, self.seconds = gaze_map, seconds
        self._reset()

    def _reset(self) -> None:
        f = len(self.seconds)
        self.disp = np.broadcast_to(rot.IDENTITY, (f, 5, 4)).copy()
        self.wanted = np.zeros((f, 2))
        self.settled = np.ones(f, dtype=bool)
        self.progress = np.ones(f)
        self.shifts: list[Shift] = []
        self.info: list[dict] = []
        self.last: _Segment | None = None

    def plan(self, shifts: list[Shift]) -> Schedule:
        """The schedule of ``shifts`` (a copy: later calls do not change it)."""
        self._update(shifts)
        return Schedule(self.disp.copy(), self.wanted.copy(), self.settled.copy(), list(self.info),
                        self.progress.copy())

    def window(self, shifts: list[Shift], lo: int, hi: int) -> tuple[np.ndarray, list[dict]]:
        """The segment offsets of frames ``lo..hi`` (a copy) and each shift's timing, of the schedule of
        ``shifts``: a planner that looks a stretch ahead copies that stretch, not the whole clip."""
        self._update(shifts)
        return self.disp[lo:hi].copy(), list(self.info)

    def _update(self, shifts: list[Shift]) -> None:
        n = len(self.shifts)
        if shifts[:n] != self.shifts:
            self._reset()
            n = 0
        if len(shifts) > n:
            requests = np.array([[s.yaw, s.pitch] for s in shifts], dtype=float)
            targets = self._query(requests, shifts[n:], requests[n:]).offsets
            targets[np.all(requests == 0.0, axis=1)] = rot.IDENTITY
            canons = np.zeros((len(shifts), 2))
            canons[n:] = motion.achieved_gaze(targets[n:], requests[n:, 0])  # the new ones', at once
            added = []
            for k in range(n, len(shifts)):
                # A shift's frames end where the next known one starts (that one writes the rest).
                until = shifts[k + 1].time_s if k + 1 < len(shifts) else np.inf
                added.append(self._append(shifts[k], requests[k], targets[k], canons[k], until))
            self._write(added)

    def _query(self, requests: np.ndarray, shifts: list[Shift], new: np.ndarray):
        """The map's motions for all ``requests``; a caching map is also asked, in the same batch, for
        the timing of each new shift's change as it is when it interrupts none (from the request
        before it): :meth:`_append` finds them there (one that interrupts another asks its own)."""
        prefetching = getattr(self.map, "query_prefetching", None)
        if prefetching is None:
            return self.map.query(requests[:, 0], requests[:, 1])
        before = np.vstack([self.last.request[None] if self.last is not None else np.zeros((1, 2)), new[:-1]])
        changes = new - before
        for i, s in enumerate(shifts):
            if s.timing_change is not None:
                changes[i] = s.timing_change
        return prefetching(requests[:, 0], requests[:, 1], changes)

    def _write(self, added: list[tuple[_Segment, np.ndarray]]) -> None:
        """Evaluate the added segments on their frames: those that interrupt a shift one by one, the
        others all at once."""
        seconds = self.seconds
        added = [(g, rows) for g, rows in added if len(rows)]
        still = [(g, rows) for g, rows in added if not g.inherit]
        results = [(rows, g.evaluate(seconds[rows])) for g, rows in added if g.inherit]
        if still:
            results += zip([rows for _, rows in still], _evaluate_still([g for g, _ in still], [seconds[r] for _, r in still]))
        for rows, (d, w, tau, sigma) in results:
            self.disp[rows], self.wanted[rows], self.progress[rows] = d, w, sigma
            self.settled[rows] = tau >= 1.0

    def _append(self, shift: Shift, request: np.ndarray, target: np.ndarray, canon: np.ndarray,
                until: float = np.inf) -> tuple[_Segment, np.ndarray]:
        """Add a shift's segment; it and its frames (the caller evaluates them)."""
        seconds, previous = self.seconds, self.last
        t0 = np.float64(shift.time_s)
        if self.info:  # the previous shift now ends where this one starts
            self.info[-1] = {**self.info[-1], "interrupted": bool(t0 < self.info[-1]["time_s"] + self.info[-1]["duration"])}
        inherit = previous is not None and t0 < previous.start_s + previous.motion.duration
        leaving = _leaving(previous, t0) if inherit else None
        if previous is None:
            start_delta = np.zeros(2)
        elif inherit:
            start_delta = _where_it_stops(leaving[1], request)
        else:
            start_delta = previous.request
        change = request - start_delta if shift.timing_change is None else np.asarray(shift.timing_change)
        # Timing only: the uncorrected blend is enough, and much cheaper.
        timing = self.map.timing(change[0], change[1])
        if shift.cut or timing[motion.DURATION] < shift.min_duration_s:
            timing = np.array(timing, dtype=float)
            timing[motion.DURATION] = 0.0 if shift.cut else shift.min_duration_s
        # The target is a row of the map's checked motions (or the identity).
        segment = _Segment(float(t0), request, target, motion.GazeMotions.of_checked(target, timing), previous,
                           bool(inherit), canon, leaving)
        rows = np.flatnonzero((seconds >= t0) & (seconds < until))
        self.info.append({
            "time_s": float(t0), "yaw": float(request[0]), "pitch": float(request[1]),
            **{name: float(v) for name, v in zip(motion.TIMING_FIELDS, timing)},
            "interrupted": False,
        })
        self.shifts.append(shift)
        self.last = segment
        return segment, rows


def _leaving(previous: _Segment, t0: np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Offsets and wanted gaze change of ``previous`` at ``t0`` and :data:`_RATE_DT_S` after it."""
    d, wanted, _, _ = previous.evaluate(t0 + np.array([0.0, _RATE_DT_S]))
    return d, wanted


def _where_it_stops(wanted: np.ndarray, request: np.ndarray) -> np.ndarray:
    """The wanted gaze change an interrupted shift leaves (``wanted``: at the interruption and
    :data:`_RATE_DT_S` after it): where it is, or, when it is moving away from ``request``, where
    coasting (:data:`COAST_S`) stops it. The new shift is timed from there: a head turning away at
    speed has that much further to come back."""
    rate = (wanted[1] - wanted[0]) / _RATE_DT_S
    stops = wanted[0] + rate * COAST_S
    return stops if np.linalg.norm(request - stops) > np.linalg.norm(request - wanted[0]) else wanted[0]
