"""The ``usdgaze build-map`` command (registered by :mod:`usdgaze.console.main`)."""

from __future__ import annotations

from pathlib import Path

import click

from usdgaze.gaze.definition import SynthesisSettings
from usdgaze.errors import UsdGazeError
from usdgaze.files.transaction import Outputs
from usdgaze.ingest.build import build, require_definition, write_map
from usdgaze.ingest.report import check_report_path, format_table, write_report, write_series
from usdgaze.ingest.settings import BuildSettings
from usdgaze.ingest.sheet import load_sheet

_DEFAULTS = BuildSettings()


@click.command("build-map")
@click.argument("sheet", type=click.Path(dir_okay=False))
@click.option("--markers", "markers", default=None, type=click.Path(dir_okay=False), metavar="MARKERSET",
              help="Marker-set TOML naming the triangles, head square and base-of-spine marker "
                   "(needed for C3D trials unless the sheet names one; UsdSkel trials may use its [skeleton] table).")
@click.option("--out", required=True, type=click.Path(dir_okay=False), metavar="MAP.usda",
              help="Gaze map file to write (.usda/.usdc/.usd).")
@click.option("--report", "report_path", default=None, type=click.Path(dir_okay=False), metavar="REPORT",
              help="Also write the per-trial report as .csv or .json.")
@click.option("--series", "series_dir", default=None, type=click.Path(file_okay=False), metavar="DIR",
              help="Write each good trial's per-frame landmark orientations (CSV) into DIR.")
@click.option("--rest-speed", default=_DEFAULTS.rest_speed_mm_s, show_default=True, type=float,
              help="V: mean marker speed below which a frame is still, mm/s (converted to the file's units).")
@click.option("--rest-merge", default=_DEFAULTS.rest_merge_s, show_default="1/6", type=float,
              help="Rests closer than this merge, seconds.")
@click.option("--min-rest", default=_DEFAULTS.min_rest_s, show_default=True, type=float,
              help="Shorter still periods are not rests, seconds.")
@click.option("--speed-span", default=_DEFAULTS.speed_span_s, show_default=True, type=float,
              help="Half-span of the finite differences of marker speed, seconds.")
@click.option("--k", "velocity_k", default=_DEFAULTS.velocity_k, show_default=True, type=int,
              help="k: angular velocities difference frames i-k and i+k.")
@click.option("--m", "peak_window_m", default=_DEFAULTS.peak_window_m, show_default=True, type=int,
              help="m: frames averaged either side of an overshoot candidate.")
@click.option("--pose-window", default=_DEFAULTS.pose_window_s, show_default=True, type=float,
              help="First/last poses are means over this many seconds of still frames (0: single frames).")
@click.option("--start-speed", default=_DEFAULTS.start_speed_deg_s, show_default=True, type=float,
              help="A joint starts moving when its local angular speed exceeds this, deg/s.")
@click.option("--start-hold", default=_DEFAULTS.start_hold_s, show_default=True, type=float,
              help="...and stays above it this long, seconds.")
@click.option("--start-refine/--no-start-refine", default=_DEFAULTS.start_refine, show_default=True,
              help="Refine each detected start back to where the model's ease-in began (off: the paper's bare "
                   "threshold crossing, which lags the real onset by several frames).")
@click.option("--min-trials", default=_DEFAULTS.min_trials, show_default=True, type=int,
              help="Fewest good trials to build a map from.")
@click.option("--quiet", is_flag=True, help="Do not print the report table (a skipped trial is still said on stderr).")
@click.option("--no-clobber", is_flag=True, help="Refuse to replace an existing output file.")
def build_map(sheet, markers, out, report_path, series_dir, rest_speed, rest_merge, min_rest, speed_span,
              velocity_k, peak_window_m, pose_window, start_speed, start_hold, start_refine, min_trials, quiet,
              no_clobber) -> None:
    """Build a gaze map from the example trials listed in SHEET (CSV or TOML) and write it to --out.

    Each trial is a C3D marker capture (with --markers) or a UsdSkel clip, with its known target
    (yaw, pitch) and an optional manual crop: crop_start and crop_end count the trial's samples from
    0, end inclusive (a C3D file's frame 1 is 0). A trial that fails is reported and skipped.
    """
    settings = BuildSettings(
        rest_speed_mm_s=rest_speed, rest_merge_s=rest_merge, min_rest_s=min_rest, speed_span_s=speed_span,
        velocity_k=velocity_k, peak_window_m=peak_window_m, pose_window_s=pose_window,
        start_speed_deg_s=start_speed, start_hold_s=start_hold, start_refine=start_refine, min_trials=min_trials,
    )
    with Outputs(no_clobber=no_clobber) as tx:
        _claim(tx, out, report_path, series_dir)
        parsed = load_sheet(sheet)
        _reads(tx, parsed, sheet, markers)
        tx.check_replaceable()  # before the trials are read
        result = build(parsed, markers, settings, SynthesisSettings())
        if not quiet:
            click.echo(format_table(result.reports))
        if report_path:
            write_report(report_path, result.reports, tx)
        if series_dir:
            write_series(series_dir, result, tx)
        require_definition(result)
        write_map(result, parsed, out, tx)
    if quiet:  # the table is left out, not why a trial was (a map that cannot be built says its first)
        for r in result.reports:
            if r.status != "ok":
                click.echo(f"usdgaze: warning: trial {r.trial} skipped: {r.error}", err=True)
    failed = len(result.reports) - len(result.good)
    note = f" ({failed} trial{'s' if failed != 1 else ''} skipped)" if failed else ""
    click.echo(f"wrote {out}: {len(result.good)} examples{note}")
    if report_path:
        click.echo(f"wrote {report_path}")


def _claim(tx: Outputs, out, report_path, series_dir) -> None:
    """Every output path, checked before any work (series files are claimed as the trials are known)."""
    from usdgaze.usd.schema import check_map_path

    check_map_path(out)
    tx.claim(out, "--out")
    if report_path:
        check_report_path(report_path)
        tx.claim(report_path, "--report")
    if series_dir and Path(series_dir).exists() and not Path(series_dir).is_dir():
        raise UsdGazeError(f"{series_dir}: --series names a file, expected a folder")


def _reads(tx: Outputs, parsed, sheet, markers) -> None:
    """The sheet, the marker set and every trial file are inputs no output may be."""
    tx.read(sheet, "trial sheet")
    for m in {markers, parsed.markers} - {None}:
        if Path(m).exists():
            tx.read(m, "marker set")
    for trial in parsed.trials:
        if trial.file.exists():
            tx.read(trial.file, f"trial file of '{trial.name}'")
            if trial.is_skeletal:
                from usdgaze.usd.stage import layer_dependencies

                for path in layer_dependencies(trial.file):
                    tx.read(path, f"layer composed by the trial '{trial.name}'")


__all__ = ["build_map", "UsdGazeError"]
