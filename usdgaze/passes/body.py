"""The body's part of looking at a target: gaze shifts through the map, re-planned as it moves (numpy).

:class:`TargetPlanner` appends body :class:`~usdgaze.passes.shift.Shift` requests and eye events for
one look directive. See :mod:`usdgaze.passes.look` for the policy and docs/look-at.md for the numbers.
"""

from __future__ import annotations

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.gaze import motion
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.options import EyeRange, Shift
from usdgaze.passes.schedule import Scheduler


TRACK_WINDOW_S = 2.0
"""How far ahead a held target's next re-plan or let-go is looked for at a time."""


class CachedMap:
    """A gaze map that answers each (yaw, pitch) once: the planner re-schedules the same shifts many
    times as it adds new ones, and a corrected query costs tens of milliseconds."""

    def __init__(self, gaze_map: ParametricGazeMap) -> None:
        self.map = gaze_map
        self._rows: dict[tuple[float, float], motion.GazeMotions] = {}
        self._full: dict[tuple[float, float, bool], object] = {}
        self._timing: dict[tuple[float, float], np.ndarray] = {}

    def query(self, yaw_deg, pitch_deg) -> motion.GazeMotions:
        return self.query_prefetching(yaw_deg, pitch_deg, None)

    def query_prefetching(self, yaw_deg, pitch_deg, changes: np.ndarray | None) -> motion.GazeMotions:
        """:meth:`query`, with the timing of ``changes (N, 2)`` prefetched as :meth:`prefetch_timing`
        does: where both miss, the map is asked for both at once (one k-NN interpolation)."""
        yaw, pitch = np.broadcast_arrays(np.asarray(yaw_deg, float), np.asarray(pitch_deg, float))
        keys = list(zip(yaw.ravel().tolist(), pitch.ravel().tolist()))
        missing = [k for k in dict.fromkeys(keys) if k not in self._rows]
        timed = self._untimed(changes) if changes is not None else []
        if missing:
            ys, ps = np.array([k[0] for k in missing]), np.array([k[1] for k in missing])
            if timed and hasattr(self.map, "query_with_timing"):
                answer, timing = self.map.query_with_timing(ys, ps, np.array([k[0] for k in timed]),
                                                            np.array([k[1] for k in timed]))
                answer = answer.motions
                self._timing.update(zip(timed, timing))
            else:
                answer = self.map.query(ys, ps)
            for i, k in enumerate(missing):
                self._rows[k] = answer[i]
        if changes is not None:
            self.prefetch_timing(changes)  # whatever the joint answer did not hold
        rows = [self._rows[k] for k in keys]
        return motion.GazeMotions.of_checked(np.stack([r.offsets for r in rows]).reshape(yaw.shape + (5, 4)),
                                             np.stack([r.timing for r in rows]).reshape(yaw.shape + (7,)))

    def query_full(self, yaw_deg, pitch_deg, correct: bool = True):
        key = (float(yaw_deg), float(pitch_deg), bool(correct))
        if key not in self._full:
            self._full[key] = self.map.query_full(yaw_deg, pitch_deg, correct=correct)
        return self._full[key]

    def prefetch_timing(self, changes: np.ndarray) -> None:
        """Answer the timing of several changes ``(N, 2)`` in one batch of the map, so that the
        :meth:`timing` calls that follow find them (a scheduler asks one shift at a time)."""
        keys = self._untimed(changes)
        if keys:
            answer = self.map.timing(np.array([k[0] for k in keys]), np.array([k[1] for k in keys]))
            self._timing.update(zip(keys, answer))

    def _untimed(self, changes: np.ndarray) -> list[tuple[float, float]]:
        """The distinct changes ``(N, 2)`` whose timing is not known yet, in order."""
        return [k for k in dict.fromkeys(map(tuple, np.asarray(changes, float).tolist())) if k not in self._timing]

    def timing(self, yaw_deg, pitch_deg) -> np.ndarray:
        """The uncorrected answer's timing floats ``(7,)`` for one change (see ``ParametricGazeMap.timing``)."""
        key = (float(yaw_deg), float(pitch_deg))
        if key not in self._timing:
            self._timing[key] = self.map.timing(yaw_deg, pitch_deg)
        return self._timing[key]


class TargetPlanner:
    """Body shifts toward one target over a stretch of frames.

    ``rel`` is the target's (azimuth, elevation) against the base line of sight per frame (yaw
    wrapped), seen from the base motion's eyes. ``events`` receives ``(frame, "target" | "base",
    cut)``: where the eyes take the target up, or let it go.
    """

    def __init__(self, gaze_map: ParametricGazeMap, shifts: list[Shift], events: list, seconds: np.ndarray,
                 rel: np.ndarray, base_ae: np.ndarray, limits: EyeRange, opts, scheduler: Scheduler | None = None
                 ) -> None:
        self.map, self.shifts, self.events, self.seconds = gaze_map, shifts, events, seconds
        self.scheduler = scheduler or Scheduler(gaze_map, seconds)  # re-plans evaluate only the new shift
        self.rel, self.base_ae, self.limits, self.opts = rel, base_ae, limits, opts
        self.reach = np.array([opts.reach_yaw_deg, opts.reach_pitch_deg])
        # The line of sight reaches as far as the head turns for a shift at the reach, plus the eyes.
        self.sight_limit = float(head_of(gaze_map, np.array([opts.reach_yaw_deg, 0.0]))[0]) + limits.yaw - 2.0
        self.current = np.zeros(2)
        self.last = 0.0
        self.end = len(seconds)

    def run(self, start: int, end: int) -> None:
        """Plan frames ``start .. end``."""
        self.end, self.last = end, self.seconds[start]
        if abs(self.rel[start, 0]) > self.sight_limit:  # out of reach from the start: keep looking ahead
            self.shifts.append(Shift(float(self.seconds[start]), 0.0, 0.0))
            self.events.append((start, "base", False))
            lost = True
        else:
            self.current = self._request(start, self.rel[start, 0], None)[0]
            self.shifts.append(Shift(float(self.seconds[start]), *self.current))
            self.events.append((start, "target", False))
            lost = False
        cursor = start + 1
        while cursor is not None and cursor < end:
            cursor, lost = self._reacquire(cursor) if lost else self._track(cursor)

    def _track(self, cursor: int) -> tuple[int | None, bool]:
        """While the target is held: the next re-plan, or the let-go when it goes out of reach; looked
        for ``TRACK_WINDOW_S`` ahead at a time (each frame's test is its own, so the first found is the
        same: over the whole rest of the clip at every re-plan, a 50,000-frame shot's took 36 s)."""
        s, opts, lim, rel = self.seconds, self.opts, self.limits, self.rel
        hi = min(self.end, max(cursor + 1, int(np.searchsorted(s, s[cursor] + TRACK_WINDOW_S))))
        # ``soon`` looks ahead of each frame: the stretch reaches that far past the window.
        ext = min(len(s), int(np.searchsorted(s, s[hi - 1] + opts.anticipation_s, "right")) + 1)
        sl = slice(cursor, ext)
        disp, timing = self.scheduler.window(self.shifts, cursor, ext)
        near = rot.unwrap_near(rel[sl, 0], self.current[0])
        head = motion.achieved_gaze(body_only(disp), float(self.current[0]))
        # Let a shift get well under way before the next one takes over from it.
        wait = max(opts.replan_interval_s, 0.5 * timing[-1]["duration"]) if timing else 0.0
        need_yaw, need_pitch = near - head[:, 0], rel[sl, 1] - head[:, 1]
        # Azimuth degrees are arc degrees only at the horizon (72 deg down, 40 of azimuth are 12 of arc).
        need_yaw = need_yaw * np.cos(np.radians(np.clip(self.base_ae[sl, 1] + rel[sl, 1], -90.0, 90.0)))
        f = opts.replan_fraction
        # A body already at its reach the way the eyes need more cannot help them: a target by the feet
        # (72 deg down, past the -80 deg reach's comfort) re-planned the body every 0.2 s as the base
        # head bobbed, each request's yaw another (89 -> 131 -> 102 deg), the head swinging at 327 deg/s.
        at = np.abs(self.current) >= self.reach - 1e-6
        trig = ((np.abs(need_yaw) > f * lim.yaw) & ~(at[0] & (need_yaw * self.current[0] > 0.0))) \
            | ((need_pitch > f * lim.up) & ~(at[1] & (self.current[1] > 0.0))) \
            | ((need_pitch < -f * lim.down) & ~(at[1] & (self.current[1] < 0.0)))
        trig = soon(trig, s[sl], opts.anticipation_s)
        window = np.arange(ext - cursor) < hi - cursor
        out = np.flatnonzero(window & (np.abs(near) > self.sight_limit))
        go = np.flatnonzero(window & trig & (s[sl] >= self.last + wait))
        j_out = cursor + int(out[0]) if len(out) else self.end
        j_go = cursor + int(go[0]) if len(go) else self.end
        if j_out >= self.end and j_go >= self.end:
            return (hi, False) if hi < self.end else (None, False)
        if j_out <= j_go:  # behind the character: let go, look ahead
            self._add(j_out, np.zeros(2), start=disp[j_out - cursor])
            self.current, self.last = np.zeros(2), s[j_out]
            self.events.append((j_out, "base", False))
            return j_out + 1, True
        new, timing = self._request(j_go, near[j_go - cursor], self.current)
        if np.abs(new - self.current).max() < 5.0:  # e.g. already at the edge of reach
            return int(np.searchsorted(s, s[j_go] + opts.replan_interval_s)), False
        self._add(j_go, new, timing, disp[j_go - cursor])
        self.current, self.last = new, s[j_go]
        return j_go + 1, False

    def _reacquire(self, cursor: int) -> tuple[int | None, bool]:
        """While let go: take the target up again once it is within reach (with some margin)."""
        s = self.seconds
        frames = np.arange(len(s))
        back = np.flatnonzero((frames >= cursor) & (frames < self.end)
                              & (np.abs(self.rel[:, 0]) <= self.sight_limit - 10.0)
                              & (s >= self.last + self.opts.replan_interval_s))
        if not len(back):
            return None, True
        j = int(back[0])
        new = self._request(j, self.rel[j, 0], None)[0]
        self._add(j, new)
        self.current, self.last = new, s[j]
        self.events.append((j, "target", False))
        return j + 1, False

    def _request(self, j: int, yaw: float, previous: np.ndarray | None) -> tuple[np.ndarray, tuple | None]:
        """Map request toward the target seen from frame ``j``, and the change whose timing it takes."""
        rel, opts = self.rel, self.opts
        want = np.array([yaw, rel[j, 1]])
        if previous is None:
            return body_request(self.map, want, self.reach, self.limits, opts.comfort_fraction), None
        # Aim where the target will be, against the base gaze, once the shift is done: the paths of
        # the body and of the target are known to the animator (and to the character).
        change = want - previous
        lead = float(self.map.timing(change[0], change[1])[0])
        ahead = max(min(int(np.searchsorted(self.seconds, self.seconds[j] + lead)), self.end - 1), j)
        # Not past where it goes out of reach (behind, or nearer than the near point): a target coming
        # at the face turned the head toward where it would be once it had passed through.
        gone = np.flatnonzero(np.abs(rot.unwrap_near(rel[j:ahead + 1, 0], yaw)) > self.sight_limit)
        ahead = j + max(int(gone[0]) - 1, 0) if len(gone) else ahead
        want = np.array([rot.unwrap_near(rel[ahead, 0], yaw), rel[ahead, 1]])
        new = body_request(self.map, want, self.reach, self.limits, opts.comfort_fraction)
        # How far the head turns in the world, not against a base gaze that may be swinging.
        world = (self.base_ae[ahead] + new) - (self.base_ae[j] + previous)
        world[0] = (world[0] + 180.0) % 360.0 - 180.0
        return new, (float(world[0]), float(world[1]))

    def _add(self, j: int, new: np.ndarray, timing=None, start=None) -> None:
        """A body shift at frame j, never faster per segment than the pace allows from where the
        body is then (``start``, its segment offsets there; a shift in progress included)."""
        if start is None:
            start = self.scheduler.window(self.shifts, j, j + 1)[0][0]
        change = timing if timing is not None else tuple(new - self.current)
        self.shifts.append(Shift(float(self.seconds[j]), *new, timing_change=timing,
                                 min_duration_s=min_duration(self.map, start, new, change, self.opts.body_pace_deg_s)))


def body_only(offsets: np.ndarray) -> np.ndarray:
    """Segment offsets with the eyes left at rest."""
    out = np.array(offsets, dtype=float)
    out[..., 4, :] = rot.IDENTITY
    return out


def head_of(gaze_map: ParametricGazeMap, request: np.ndarray) -> np.ndarray:
    """Settled gaze change of the body alone (no eyes) for a map request, on the canonical chain.

    The uncorrected blend: its body split is the corrected one's within a degree or two, ten times cheaper.
    """
    offsets = gaze_map.query_full(float(request[0]), float(request[1]), correct=False).motions.offsets.reshape(1, 5, 4)
    return motion.achieved_gaze(body_only(offsets), request[0])[0]


def min_duration(gaze_map: ParametricGazeMap, start: np.ndarray, b: np.ndarray, timing_change, pace: float) -> float:
    """Shortest duration of a body shift from segment offsets ``start`` to request ``b`` that keeps every body
    segment's own peak speed under ``pace`` deg/s: the map's split can change much more than the gaze
    does, and its cascade gives late segments a short window."""
    q = gaze_map.query(np.array([b[0]]), np.array([b[1]])).offsets.reshape(5, 4)
    turn = np.degrees(rot.angle(rot.relative(start[:4], q[:4])))
    timing = np.array(gaze_map.timing(timing_change[0], timing_change[1]), dtype=float)
    starts, peak, beta = timing[motion.START_SLICE], timing[motion.PEAK], timing[motion.BETA]
    window = np.where(starts < peak, peak - starts, 1.0 - starts)
    scale = np.where(starts < peak, 1.0 + beta, 1.0)
    # The quintic's peak slope is 1.875 times its mean.
    return float(np.max(1.875 * turn * scale / (np.maximum(window, 0.05) * pace)))


def body_request(gaze_map: ParametricGazeMap, want: np.ndarray, reach: np.ndarray, limits: EyeRange,
                  comfort: float) -> np.ndarray:
    """The map request toward line-of-sight change ``want``: the map's own head-eye split, unless that
    leaves the eyes beyond ``comfort`` of their range; then enough more body to bring them back."""
    natural = np.clip(want, -reach, reach)
    head = head_of(gaze_map, natural)
    eyes = want - head
    lo = np.array([-limits.yaw, -limits.down]) * comfort
    hi = np.array([limits.yaw, limits.up]) * comfort
    if np.all((eyes >= lo) & (eyes <= hi)):
        return natural
    out = (eyes < lo) | (eyes > hi)
    goal = want - np.clip(eyes, lo, hi)
    best, best_miss = natural, np.abs(goal - head)[out].max()
    request = natural
    for _ in range(4):  # fixed point on the canonical chain: the head change is near-linear in the request
        request = np.where(out, np.clip(request + goal - head, -reach, reach), natural)
        head = head_of(gaze_map, request)
        miss = np.abs(goal - head)[out].max()
        if miss < best_miss:
            best, best_miss = request, miss
    return best


def soon(flags: np.ndarray, seconds: np.ndarray, within_s: float) -> np.ndarray:
    """True where ``flags`` is true now or within the next ``within_s`` seconds."""
    count = np.concatenate([[0], np.cumsum(flags)])
    ahead = np.searchsorted(seconds, seconds + within_s, side="right")
    return count[ahead] - count[np.arange(len(flags))] > 0
