"""The per-trial build report (stdout table, CSV, JSON) and per-frame orientation series (CSV)."""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError
from usdgaze.files.transaction import Outputs, outputs_of
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


def check_report_path(path: str | Path) -> str:
    """The report format from the suffix (``csv`` or ``json``), else a one-line error."""
    fmt = Path(path).suffix.lower().lstrip(".")
    if fmt not in ("csv", "json"):
        raise ReportError(f"{path}: a report must be .csv or .json")
    return fmt


def write_report(path: str | Path, reports: list[TrialReport], outputs: Outputs | None = None) -> None:
    """Write the report; the format follows the suffix (.csv or .json)."""
    path = Path(path)
    fmt = check_report_path(path)
    with outputs_of(outputs) as tx:
        if not tx.claimed(path):
            tx.claim(path, "--report")
        tx.stage_text(path, report_text(reports, fmt))


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


def series_name(trial: str) -> str:
    """A trial's series file name: separators and control characters become '_', never hidden, never a path."""
    name = re.sub(r"[\x00-\x1f/\\:]", "_", trial)
    if not name or name.startswith("."):
        name = "_" + name
    return f"{name}.csv"


def series_paths(directory: str | Path, trials: list[str]) -> list[Path]:
    """Where each trial's series goes: inside ``directory`` whatever the trial's name."""
    return [Path(directory) / series_name(t) for t in trials]


def write_series(directory: str | Path, result: BuildResult, outputs: Outputs | None = None) -> list[Path]:
    """One CSV per good trial (``TRIAL.csv``, see :func:`series_name`) with its per-frame landmark displacements.

    A symlink planted at a series path is replaced, not written through.
    """
    directory = Path(directory)
    trials = [report.trial for report in result.good]
    paths = series_paths(directory, trials)
    owner: dict[Path, str] = {}
    for trial, path in zip(trials, paths):  # two trials on one file: the second would replace the first
        if path in owner:
            raise UsdGazeError(f"{path}: the --series file of both trial '{owner[path]}' and trial '{trial}' (a "
                               "name's separators become '_'); rename one of them in the sheet")
        owner[path] = trial
    written = []
    with outputs_of(outputs) as tx:
        tx.make_folder(directory)
        for report, path in zip(result.good, paths):
            flag = tx.claimed_by(path)
            if flag is None:
                tx.claim(path, "--series file", follow=False)
            elif flag != "--series file":  # --report named DIR/TRIAL.csv: the series replaced the report
                raise UsdGazeError(f"{path}: --series file of trial '{report.trial}' and {flag} name the same "
                                   "file; give each output its own path")
            header, rows = series_rows(result, report.trial)
            text = io.StringIO()
            writer = csv.writer(text, lineterminator="\n")
            writer.writerow(header)
            for row in rows:
                writer.writerow([int(row[0])] + [f"{v:.6g}" for v in row[1:]])
            tx.stage_text(path, text.getvalue())
            written.append(path)
    return written
