"""The per-trial build report (stdout table, CSV, JSON) and per-frame orientation series (CSV)."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError
from usdgaze.ingest.build import BuildResult, TrialReport
from usdgaze.ingest.extract import CHAIN

TABLE_COLUMNS = (
    ("trial", "trial"),
    ("status", "status"),
    ("crop", "crop"),
    ("l (s)", "duration_s"),
    ("starts (s) pel/low/up/neck", "starts"),
    ("peak (s)", "peak_s"),
    ("beta", "beta"),
    ("head (deg)", "head_angle_deg"),
    ("notes", "notes"),
)


class ReportError(UsdGazeError):
    """A report or series file cannot be written."""


def _cell(row: dict, key: str) -> str:
    if key == "crop":
        return "" if row["crop_start"] is None else f"{row['crop_start']}-{row['crop_end']} {row['crop_source']}"
    if key == "starts":
        values = [row[f"{name}_start_s"] for name in CHAIN]
        return "" if values[0] is None else "/".join(f"{v:.3f}" for v in values)
    if key == "notes":
        return row["error"] or row["warnings"]
    value = row[key]
    if value is None:
        return ""
    return f"{value:.3f}" if isinstance(value, float) else str(value)


def format_table(reports: list[TrialReport]) -> str:
    """A fixed-width text table, one line per trial."""
    rows = [r.row() for r in reports]
    cells = [[_cell(row, key) for _, key in TABLE_COLUMNS] for row in rows]
    heads = [h for h, _ in TABLE_COLUMNS]
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, h in enumerate(heads)]
    widths[-1] = len(heads[-1])  # the notes run on

    def line(values: list[str]) -> str:
        return "  ".join(v.ljust(w) for v, w in zip(values, widths)).rstrip()

    return "\n".join([line(heads)] + [line(c) for c in cells])


def report_text(reports: list[TrialReport], fmt: str) -> str:
    """The report as ``csv`` or ``json`` text."""
    rows = [r.row() for r in reports]
    if fmt == "json":
        return json.dumps(rows, indent=2) + "\n"
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=list(rows[0]) if rows else ["trial"], lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return out.getvalue()


def write_report(path: str | Path, reports: list[TrialReport]) -> None:
    """Write the report; the format follows the suffix (.csv or .json)."""
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in ("csv", "json"):
        raise ReportError(f"{path}: a report must be .csv or .json")
    try:
        path.write_text(report_text(reports, fmt))
    except OSError as exc:
        raise ReportError(f"{path}: cannot write the report ({exc.strerror})") from None


def series_rows(result: BuildResult, trial: str) -> tuple[list[str], np.ndarray]:
    """Header and rows of one good trial's per-frame landmark displacements.

    Each landmark's global orientation relative to the first cropped frame, in the character frame
    (the space of P+), as a quaternion and its angle in degrees; time in seconds from the crop start.
    """
    series = result.series[trial]
    frame = series.frame_at(0)
    q = series.orientations
    displacement = rot.multiply(q, rot.conjugate(q[:1]))
    local = rot.positive_w(rot.conjugate_into(rot.conjugate(frame), displacement))
    angles = np.degrees(rot.angle(local))
    names = ("pelvis", "lowerSpine", "upperSpine", "head")
    header = ["frame", "time_s"]
    for name in names:
        header += [f"{name}_qx", f"{name}_qy", f"{name}_qz", f"{name}_qw", f"{name}_angle_deg"]
    n = len(q)
    columns = [np.arange(n), np.arange(n) / series.rate]
    for j in range(len(names)):
        columns += [local[:, j, 0], local[:, j, 1], local[:, j, 2], local[:, j, 3], angles[:, j]]
    return header, np.column_stack(columns)


def write_series(directory: str | Path, result: BuildResult) -> list[Path]:
    """One CSV per good trial (``TRIAL.csv``) with its per-frame landmark displacements."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ReportError(f"{directory}: cannot create the series folder ({exc.strerror})") from None
    written = []
    for report in result.good:
        header, rows = series_rows(result, report.trial)
        path = directory / f"{report.trial}.csv"
        with path.open("w", newline="") as f:
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(header)
            for row in rows:
                writer.writerow([int(row[0])] + [f"{v:.6g}" for v in row[1:]])
        written.append(path)
    return written
