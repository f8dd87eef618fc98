"""Cleaning raw marker trajectories as Heck 5.2.2.1 does: gap filling, root stabilization, rest cropping.

All functions work on ``(F, M, 3)`` arrays in the data's units and are vectorized over frames.

Two additions to the paper. Marker speeds are central differences over +-``span`` frames instead of
neighbouring frames. Heck's V = 6 mm/s is a tenth of a millimetre per frame at 60 Hz, far below the
jitter of optical markers (0.5 mm RMS of noise alone reads as 20-40 mm/s on differences of
neighbouring frames), so the paper's data must have been smoothed before; a wider difference is the
smallest change that lets the same V separate rest from motion on unsmoothed captures. And rests shorter than a minimum
length are ignored: all joints reach the overshoot peak together, so the markers almost stop there
for a moment, which the paper's rule would take for the reading rest and crop the settle away.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.errors import UsdGazeError


class CleaningError(UsdGazeError):
    """A trial cannot be cleaned or cropped."""


@dataclass(frozen=True)
class Rest:
    """A period of rest: first and last still frame (inclusive)."""

    start: int
    end: int


def missing_markers(points: np.ndarray) -> np.ndarray:
    """Per-marker mask ``(M,)`` of markers that have no sample at all."""
    return ~np.any(np.all(np.isfinite(points), axis=-1), axis=0)


def fill_gaps(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fill occluded samples linearly in time from the marker's last known and next known samples.

    Gaps at the start or end of a trial have only one known neighbour and hold it. Returns the
    filled ``(F, M, 3)`` points and the ``(F, M)`` mask of filled samples. Markers never seen stay NaN
    (see :func:`missing_markers`).
    """
    points = np.asarray(points, dtype=float)
    f = points.shape[0]
    seen = np.all(np.isfinite(points), axis=-1)
    frames = np.arange(f)[:, None]
    prev = np.maximum.accumulate(np.where(seen, frames, -1), axis=0)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(seen, frames, f), axis=0), axis=0), axis=0)
    lo = np.where(prev >= 0, prev, nxt)
    hi = np.where(nxt < f, nxt, prev)
    lo_c, hi_c = np.clip(lo, 0, f - 1), np.clip(hi, 0, f - 1)
    cols = np.arange(points.shape[1])[None, :]
    a, b = points[lo_c, cols], points[hi_c, cols]
    span = (hi - lo).astype(float)
    w = np.divide(frames - lo, span, out=np.zeros_like(span), where=span > 0)
    filled = a + (b - a) * w[..., None]
    out = np.where(seen[..., None], points, filled)
    never = missing_markers(points)
    out[:, never] = np.nan
    return out, ~seen & ~never[None, :]


def stabilize(points: np.ndarray, base: int) -> np.ndarray:
    """Shift every frame so that marker ``base`` (the base of the spine) sits at the origin."""
    return points - points[:, base : base + 1, :]


def mean_marker_speed(points: np.ndarray, rate: float, span: int, exclude: list[int] | None = None) -> np.ndarray:
    """Mean over markers of the speed magnitude per frame (units/s), central differences over +-span.

    Near the ends the 2*span window slides inward instead of shrinking, so the first and last frames
    are as smooth as the rest. ``exclude`` drops markers (the stabilized base is 0).
    """
    f = points.shape[0]
    if exclude:
        keep = np.setdiff1d(np.arange(points.shape[1]), exclude)
        points = points[:, keep]
    width = min(2 * span, f - 1)
    lo = np.clip(np.arange(f) - span, 0, f - 1 - width)
    hi = lo + width
    velocity = (points[hi] - points[lo]) * (rate / max(width, 1))
    return np.linalg.norm(velocity, axis=-1).mean(axis=1)


def rest_periods(speed: np.ndarray, threshold: float, merge_frames: float, min_frames: float = 0.0) -> list[Rest]:
    """Runs of still frames (speed < threshold); runs closer than ``merge_frames`` merge.

    Merged runs shorter than ``min_frames`` are dropped: every joint reverses at once at the overshoot
    peak, and that brief dip of the marker speed is not a rest (not in the paper; see BuildSettings).
    """
    still = np.asarray(speed) < threshold
    edges = np.diff(np.concatenate([[0], still.astype(int), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    rests: list[Rest] = []
    for s, e in zip(starts.tolist(), ends.tolist()):
        if rests and s - rests[-1].end < merge_frames:
            rests[-1] = Rest(rests[-1].start, e)
        else:
            rests.append(Rest(s, e))
    return [r for r in rests if r.end - r.start + 1 >= min_frames]


def crop_by_rest(rests: list[Rest], frames: int) -> tuple[int, int]:
    """Heck's crop: from the end of the first rest to the end of the second (inclusive frames)."""
    if not rests:
        raise CleaningError("no rest period found (the mean marker speed never falls below the rest threshold)")
    if len(rests) == 1:
        only = rests[0]
        if only.start == 0 and only.end == frames - 1:
            raise CleaningError("no motion (the whole trial is one rest period)")
        if only.start == 0:
            raise CleaningError(f"no rest after the motion (one rest, frames 0-{only.end}; the trial ends moving)")
        raise CleaningError(f"no rest before the motion (one rest, frames {only.start}-{only.end})")
    return rests[0].end, rests[1].end
