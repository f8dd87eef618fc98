"""Reading and writing raw optical marker capture in C3D (through ezc3d, the optional ``c3d`` extra).

Points keep the file's units (``POINT:UNITS``); :attr:`MarkerCapture.mm_per_unit` converts thresholds
given in millimetres. A missing sample (negative residual, NaN as ezc3d returns it, or exactly (0, 0, 0)
with any residual, as several exporters write gaps) is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdgaze.errors import UsdGazeError
from usdgaze.files.kinds import require_file

MM_PER_UNIT = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "millimeters": 1.0, "millimetres": 1.0,
               "cm": 10.0, "centimeter": 10.0, "centimetre": 10.0, "centimeters": 10.0, "centimetres": 10.0,
               "dm": 100.0, "m": 1000.0, "meter": 1000.0, "metre": 1000.0, "meters": 1000.0, "metres": 1000.0,
               "in": 25.4, "inch": 25.4, "inches": 25.4, "ft": 304.8}


class C3DError(UsdGazeError):
    """A C3D file cannot be read or written, or its header is unusable."""


@dataclass(frozen=True)
class MarkerCapture:
    """The 3D marker trajectories of one C3D file.

    ``points`` ``(F, M, 3)`` in ``units``; NaN where a marker was not seen.
    """

    path: str
    labels: tuple[str, ...]
    points: np.ndarray
    rate: float
    units: str
    mm_per_unit: float
    first_frame: int = 0
    """The header's first frame number minus 1 (ezc3d's count): C3D numbers the first frame 1 or more."""

    @property
    def frames(self) -> int:
        return self.points.shape[0]


def _ezc3d():
    # Optional dependency: only C3D sessions need it, so import it when first used.
    try:
        import ezc3d
    except ImportError:
        raise C3DError("reading C3D needs ezc3d: pip install usdgaze[c3d]") from None
    return ezc3d


def _param(group: dict, name: str):
    entry = group.get(name)
    return None if entry is None else entry.get("value")


def _units(values, path: str, n_markers: int) -> tuple[str, float, np.ndarray]:
    """The file's unit and a per-marker factor to it (Optotrak writes one unit per marker)."""
    # C3D strings are space-padded: an all-blank entry is no unit given, which C3D reads as mm.
    names = [str(u).strip().lower() for u in (values or [])]
    names = names if any(names) else ["mm"]
    for name in names:
        if name not in MM_PER_UNIT:
            raise C3DError(f"{path}: unknown POINT:UNITS '{name}' (expected one of mm, cm, m, in)")
    main = max(set(names), key=names.count)
    if len(names) == 1:
        return main, MM_PER_UNIT[main], np.ones(n_markers)
    if len(names) != n_markers:
        raise C3DError(f"{path}: POINT:UNITS has {len(names)} entries for {n_markers} markers")
    factor = np.array([MM_PER_UNIT[n] / MM_PER_UNIT[main] for n in names])
    return main, MM_PER_UNIT[main], factor


def _labels(point: dict) -> tuple[str, ...]:
    """POINT:LABELS, then LABELS2, LABELS3 ...: C3D keeps at most 255 in one parameter."""
    labels = list(_param(point, "LABELS") or [])
    k = 2
    while f"LABELS{k}" in point:
        labels += list(_param(point, f"LABELS{k}") or [])
        k += 1
    return tuple(str(s).strip() for s in labels)


PROCESSORS = {84: "Intel", 85: "DEC", 86: "MIPS"}
"""C3D's processor types (the parameter section's fourth byte): byte order and float format."""


def _processor(path: str) -> int | None:
    """The processor type a C3D file was written for, None where its header is not C3D's (or it cannot
    be read: ezc3d then says why)."""
    try:
        with open(path, "rb") as f:
            head = f.read(2)
            if len(head) < 2 or head[1] != 0x50 or head[0] < 1:  # 0x50: C3D's key byte
                return None
            f.seek((head[0] - 1) * 512 + 3)
            byte = f.read(1)
    except OSError:
        return None
    return byte[0] if byte else None


def read_c3d(path: str | Path, where: str | None = None) -> MarkerCapture:
    """Read the points of a C3D file (analogs are ignored); ``where`` names it in errors (the path)."""
    path = str(path)
    where = where or path
    require_file(path, C3DError, where)
    ezc3d = _ezc3d()
    if _processor(path) == 86:
        # ezc3d refuses it asking for an issue on its own tracker: say what the file is and what reads.
        raise C3DError(f"{where}: written for a MIPS processor (C3D processor type 86, big-endian), which the C3D "
                       "reader (ezc3d) cannot read; save it again for Intel or DEC (types 84, 85)")
    try:
        c3d = ezc3d.c3d(path)
    except Exception as exc:  # ezc3d raises plain RuntimeError/IOError with its own text
        raise C3DError(f"{where}: not a readable C3D file ({str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__})") from None
    point = c3d["parameters"].get("POINT", {})
    labels = _labels(point)
    data = np.asarray(c3d["data"]["points"], dtype=float)
    if data.ndim != 3 or data.shape[1] == 0 or data.shape[2] == 0:
        raise C3DError(f"{where}: no marker data (POINT:USED is 0 or no frames)")
    n_markers = data.shape[1]
    if len(labels) < n_markers:
        labels = labels + tuple(f"unlabeled{i + 1}" for i in range(len(labels), n_markers))
    labels = labels[:n_markers]
    rate_value = _param(point, "RATE")
    rate = float(rate_value[0]) if rate_value is not None and len(rate_value) else float(c3d["header"]["points"]["frame_rate"])
    if not rate > 0:
        raise C3DError(f"{where}: POINT:RATE is {rate}, not a frame rate")
    units, mm_per_unit, factor = _units(_param(point, "UNITS"), where, n_markers)
    points = np.transpose(data[:3], (2, 1, 0)) * factor[None, :, None]
    residuals = c3d["data"].get("meta_points", {}).get("residuals")
    if residuals is not None and np.size(residuals):
        missing = np.asarray(residuals)[0].T < 0
        points[missing] = np.nan
    # Some exporters write a gap as (0, 0, 0) with residual 0; a real marker never sits exactly on the
    # lab origin, and taken as seen it would jump there (a 50 deg error in P+, or a degenerate landmark).
    points[np.all(points == 0.0, axis=-1)] = np.nan
    return MarkerCapture(
        path=path,
        labels=labels,
        points=points,
        rate=rate,
        units=units,
        mm_per_unit=mm_per_unit,
        first_frame=int(c3d["header"]["points"].get("first_frame", 0)),
    )


def write_c3d(path: str | Path, labels: list[str] | tuple[str, ...], points: np.ndarray, rate: float,
              units: str = "mm") -> None:
    """Write marker trajectories ``(F, M, 3)`` (NaN = not seen) to a C3D file."""
    ezc3d = _ezc3d()
    points = np.asarray(points, dtype=float)
    if points.ndim != 3 or points.shape[1] != len(labels) or points.shape[2] != 3:
        raise C3DError(f"{path}: points must be (frames, {len(labels)}, 3), got {points.shape}")
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = [units]
    data = np.ones((4, points.shape[1], points.shape[0]))
    data[:3] = np.transpose(points, (2, 1, 0))
    c3d["data"]["points"] = data
    try:
        c3d.write(str(path))
    except Exception as exc:
        raise C3DError(f"{path}: cannot write C3D ({str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__})") from None
