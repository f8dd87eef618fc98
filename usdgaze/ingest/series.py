"""A trial as time series: chain landmark orientations plus the points whose speed finds the rests.

:func:`marker_series` turns a C3D capture into one (gap fill and root stabilization included);
:mod:`.skelclips` does the same for UsdSkel clips. Both feed :mod:`.build`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from usdgaze.ingest.c3dio import MM_PER_UNIT, MarkerCapture, read_c3d
from usdgaze.ingest.cleaning import fill_gaps, missing_markers, stabilize
from usdgaze.ingest.frames import (UPRIGHT_DEG, character_frame, fit_frames, landmark_frames, off_upright, square_axes,
                                   square_is_mirrored)
from usdgaze.ingest.markers import LANDMARKS, MarkerSet, MarkerSetError, resolve_labels


@dataclass(frozen=True)
class TrialSeries:
    """One trial, uncropped.

    ``orientations`` ``(F, 4, 4)``: global orientations of the pelvis, lower-spine, upper-spine and
    head landmarks (lab or skeleton space); ``points`` ``(F, P, 3)``: root-stabilized points whose
    mean speed finds the rests (the base itself excluded); ``frame_at``: the canonical character
    frame (quaternion, canonical -> this space) at a frame index.
    """

    source: str
    orientations: np.ndarray
    points: np.ndarray
    frame_at: Callable[[int], np.ndarray]
    rate: float
    units: str
    mm_per_unit: float
    filled: int = 0
    """Occluded samples filled by :func:`.cleaning.fill_gaps`."""
    longest_fill: tuple[str, int, int] | None = None
    """The longest run of filled frames: (marker, first frame, last frame), None where none was filled."""
    numbering: str = ""
    """How the file itself numbers these frames, in words ("the file numbers them 705-1044"), where that
    is not 0 to frames - 1: a crop counts samples from 0, whatever the capture software shows."""

    @property
    def frames(self) -> int:
        return self.orientations.shape[0]


def marker_series(capture: MarkerCapture, markerset: MarkerSet, where: str) -> TrialSeries:
    """Gap-fill, stabilize and turn a capture's landmark markers into a :class:`TrialSeries`."""
    markerset.require_complete()
    wanted = markerset.labels()
    idx = resolve_labels(wanted, capture.labels, markerset.subject, where)
    points = capture.points[:, idx]
    never = missing_markers(points)
    if np.any(never):
        raise MarkerSetError(f"{where}: marker '{capture.labels[idx[int(np.flatnonzero(never)[0])]]}' has no sample in the whole trial")
    filled, mask = fill_gaps(points)
    base = wanted.index(markerset.base_of_spine)
    stable = stabilize(filled, base)
    landmarks, pos = [], 0
    for name in LANDMARKS:
        n = len(markerset.landmarks[name])
        landmarks.append(stable[:, pos : pos + n])
        pos += n
    groups = list(landmarks)
    if markerset.head_top:
        top = stable[:, wanted.index(markerset.head_top)]
        if square_is_mirrored(landmarks[3], top):
            raise MarkerSetError(
                f"{where}: the head square is listed mirrored (head_top lies below it); list it left-front, left-back, right-back, right-front"
            )
        groups[3] = np.concatenate([landmarks[3], top[:, None]], axis=1)
    orientations = np.stack(
        [fit_frames(g, landmark_frames(p, f"{where}: {name} markers")) for name, p, g in zip(LANDMARKS, landmarks, groups)],
        axis=1,
    )
    _, forward = square_axes(landmarks[3])
    up = markerset.up
    _check_up(landmarks[3].mean(axis=1), markerset, where)
    _check_scale(landmarks[3].mean(axis=1), capture, where)
    keep = np.setdiff1d(np.arange(stable.shape[1]), [base])
    return TrialSeries(
        source=where,
        orientations=orientations,
        points=stable[:, keep],
        frame_at=lambda i: character_frame(forward[i], up, f"{where}: head square at frame {i}"),
        rate=capture.rate,
        units=capture.units,
        mm_per_unit=capture.mm_per_unit,
        filled=int(mask.sum()),
        longest_fill=_longest_run(mask, [capture.labels[i] for i in idx]),
        # C3D numbers frames from the header's first frame (1 in most files; ezc3d counts it from 0).
        numbering=f"the file numbers them {capture.first_frame + 1}-{capture.first_frame + capture.frames}",
    )


def _check_up(head: np.ndarray, markerset: MarkerSet, where: str) -> None:
    """Refuse a marker set whose up axis is not the capture's (a Y-up export read as the default Z).

    ``head``: the head square's centre relative to the base of the spine ``(F, 3)``. A wrong up axis
    gives no error further on, only a map of examples whose eyes would turn past their range.
    """
    angle, seen = off_upright(head, markerset.up)
    if angle > UPRIGHT_DEG:
        raise MarkerSetError(f"{where}: the head is {angle:.0f} deg from up_axis {markerset.up_axis} of {markerset.source} "
                             f"(seen from the base of the spine, the capture's up is {seen}); set up_axis = \"{seen.lstrip('+')}\" there")


HEAD_REACH_MM = (150.0, 1500.0)
"""The head's distance from the base of the spine on a person, standing or seated (~0.7 m on an adult)."""


def _check_scale(head: np.ndarray, capture: MarkerCapture, where: str) -> None:
    """Refuse points whose unit is not the file's POINT:UNITS (metres in a file that says mm, or none,
    which C3D reads as mm, as ezc3d writes by default): the rest threshold is in mm, so such a trial
    was refused as 'no motion' or 'no rest period', neither of which it is.

    ``head``: the head square's centre relative to the base of the spine ``(F, 3)``, in the file's unit."""
    reach = float(np.nanmedian(np.linalg.norm(head, axis=-1)))
    mm = reach * capture.mm_per_unit
    if HEAD_REACH_MM[0] <= mm <= HEAD_REACH_MM[1]:
        return
    likely = min(("mm", "cm", "m"), key=lambda u: abs(np.log(reach * MM_PER_UNIT[u] / 700.0)))
    raise MarkerSetError(f"{where}: the head is {mm:.3g} mm from the base of the spine by the file's POINT:UNITS "
                         f"'{capture.units}' (C3D reads none as mm), not a person's {HEAD_REACH_MM[0] / 1000:g}-"
                         f"{HEAD_REACH_MM[1] / 1000:g} m; its points look like {likely} ({reach:.3g} {likely}): "
                         "correct POINT:UNITS in the file")


def _longest_run(mask: np.ndarray, labels: list[str]) -> tuple[str, int, int] | None:
    """(label, first, last frame) of the longest run of True down a column of ``mask (F, M)``."""
    best = None
    for m in np.flatnonzero(mask.any(axis=0)):  # markers, not frames: a dozen columns
        edges = np.flatnonzero(np.diff(np.r_[0, mask[:, m].astype(np.int8), 0]))
        starts, ends = edges[::2], edges[1::2]
        k = int(np.argmax(ends - starts))
        if best is None or ends[k] - starts[k] > best[2] - best[1] + 1:
            best = (labels[m], int(starts[k]), int(ends[k]) - 1)
    return best


def read_marker_series(path: str, markerset: MarkerSet, where: str) -> TrialSeries:
    """:func:`marker_series` of a C3D file."""
    return marker_series(read_c3d(path, where), markerset, where)
