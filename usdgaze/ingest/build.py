"""``build-map`` orchestration: sheet -> per-trial series -> crop -> extraction -> gaze map + report.

A trial that fails is reported (one line: trial, file, what is wrong) and skipped; the map is built
from the rest when at least ``BuildSettings.min_trials`` remain. All trials must share one frame rate
(the session's most common, within ``BuildSettings.rate_tolerance``: a 59.94 Hz trial joins a 60 Hz
session, its windows 0.1% longer in seconds), because k and m count frames.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from usdgaze.gaze.definition import GazeMapDefinition, SynthesisSettings
from usdgaze.errors import UsdGazeError
from usdgaze.gaze.motion import GazeMotions
from usdgaze.ingest.cleaning import CleaningError, crop_by_rest, mean_marker_speed, rest_periods
from usdgaze.ingest.extract import CHAIN, Extraction, extract
from usdgaze.ingest.markers import MarkerSet, SkeletonBinding, load_markerset
from usdgaze.ingest.series import TrialSeries, read_marker_series
from usdgaze.ingest.settings import BuildSettings
from usdgaze.ingest.sheet import Sheet, SheetError, Trial, load_sheet
from usdgaze.files.kinds import not_a_file


LANDMARK_NAMES = ("pelvis", "lowerSpine", "upperSpine", "head")
"""The measured landmarks; the report gives each one's net rotation over the crop."""


class TrialError(UsdGazeError):
    """One trial cannot become an example."""


class BuildError(UsdGazeError):
    """The session as a whole cannot become a map."""


LONG_FILL_S = 0.25
"""An occlusion filled longer than this is warned about: a head turn is a straight line there (gaps of
a few frames, 0.15 s at most at 60 Hz, are what every capture has)."""


@dataclass
class TrialReport:
    """What happened to one trial: the report table's row."""

    trial: str
    file: str
    yaw: float
    pitch: float
    status: str = "failed"
    crop: tuple[int, int] | None = None
    crop_source: str = ""
    rate: float | None = None
    units: str = ""
    filled_samples: int = 0
    extraction: Extraction | None = None
    error: str = ""
    warnings: list[str] = field(default_factory=list)

    def row(self) -> dict:
        """Flat, JSON/CSV-friendly values (times in seconds from the crop start, angles in degrees).

        ``*_start_s`` are the start times the map keeps (0 where the segment never crossed the start
        threshold; the model's t_j fitted back from the crossing with ``start_refine``), and
        ``*_detected_s`` the threshold crossings themselves (None where never).
        ``peak_angle_deg`` is the head's rotation at the overshoot peak and ``*_angle_deg`` each
        landmark's net rotation from the first to the last pose, both from the first pose.
        """
        ex = self.extraction
        row = {
            "trial": self.trial,
            "file": self.file,
            "yaw": self.yaw,
            "pitch": self.pitch,
            "status": self.status,
            "crop_start": self.crop[0] if self.crop else None,
            "crop_end": self.crop[1] if self.crop else None,
            "crop_source": self.crop_source,
            "rate": self.rate,
            "units": self.units,
            "filled_samples": self.filled_samples,
            "duration_s": None,
        }
        for name in CHAIN:
            row[f"{name}_start_s"] = None
        for name in CHAIN:
            row[f"{name}_detected_s"] = None
        row.update({"peak_s": None, "t_beta": None, "beta": None, "peak_angle_deg": None})
        for name in LANDMARK_NAMES:
            row[f"{name}_angle_deg"] = None
        if ex is not None:
            row["duration_s"] = round(float(ex.timing[0]), 6)
            for name, frame, crossing in zip(CHAIN, ex.start_frames, ex.detected_frames):
                row[f"{name}_start_s"] = round(max(float(frame), 0.0) / self.rate, 6)
                row[f"{name}_detected_s"] = None if crossing < 0 else round(int(crossing) / self.rate, 6)
            row["peak_s"] = None if ex.peak_frame is None else round(ex.peak_frame / self.rate, 6)
            row["t_beta"] = round(float(ex.timing[5]), 6)
            row["beta"] = round(float(ex.timing[6]), 6)
            row["peak_angle_deg"] = round(ex.peak_angle_deg, 4)
            for name, value in zip(LANDMARK_NAMES, ex.segment_angles_deg):
                row[f"{name}_angle_deg"] = round(float(value), 4)
        row["warnings"] = "; ".join(self.warnings)
        row["error"] = self.error
        return row


@dataclass
class BuildResult:
    """The map definition (None if too few trials survived) and one report per sheet trial."""

    definition: GazeMapDefinition | None
    reports: list[TrialReport]
    settings: BuildSettings
    rate: float | None
    series: dict[str, TrialSeries] = field(default_factory=dict)
    """Cropped series of the good trials (for exporting per-frame orientations)."""

    @property
    def good(self) -> list[TrialReport]:
        return [r for r in self.reports if r.status == "ok"]


def _require_trial_file(trial: Trial, where: str) -> None:
    """A one-line error unless the trial's file is a regular file: it names the full path looked at and,
    for a relative one, the sheet's spelling (``trial A (A.c3d): no such file`` left both to guess)."""
    problem = not_a_file(trial.file)
    if not problem:
        return
    spelled = trial.written
    said = (f" (the sheet's '{spelled}', relative to the sheet's folder)"
            if spelled is not None and not Path(spelled).is_absolute() else "")
    raise TrialError(f"{where}: {os.path.abspath(trial.file)}: {problem}{said}")


def load_series(trial: Trial, markerset: MarkerSet | None, binding: SkeletonBinding, where: str) -> TrialSeries:
    """Read one trial's file into a :class:`TrialSeries` (C3D markers or a UsdSkel clip)."""
    _require_trial_file(trial, where)
    if trial.is_skeletal:
        from usdgaze.ingest.skelclips import read_skeleton_series  # pxr only for skeletal sessions

        return read_skeleton_series(trial.file, binding, trial.skeleton, where)
    if trial.file.suffix.lower() != ".c3d":
        raise TrialError(f"{where}: unknown file type '{trial.file.suffix}' (expected .c3d or a USD file)")
    if markerset is None:
        raise TrialError(f"{where}: a C3D trial needs a marker set (--markers)")
    return read_marker_series(str(trial.file), markerset, where)


def find_crop(trial: Trial, series: TrialSeries, settings: BuildSettings, where: str) -> tuple[tuple[int, int], str]:
    """The sheet's manual crop, else Heck's rest-period crop."""
    last = series.frames - 1
    if trial.crop is not None:
        start, end = trial.crop
        if end > last:
            # Frame numbers from the capture software or the DCC (C3D's 1-based, a shot's 1001) are a
            # likely cause: say how the crop counts and how the file numbers its frames.
            how = f" ({series.numbering})" if series.numbering else ""
            raise TrialError(f"{where}: crop_end {end} is past the last frame {last}; crop frames count the "
                             f"trial's samples from 0{how}")
        return (start, end), "manual"
    span = max(int(round(settings.speed_span_s * series.rate)), 1)
    speed = mean_marker_speed(series.points, series.rate, span)
    threshold = settings.rest_speed_mm_s / series.mm_per_unit
    rests = rest_periods(speed, threshold, settings.rest_merge_s * series.rate, settings.min_rest_s * series.rate)
    try:
        return crop_by_rest(rests, series.frames), "auto"
    except CleaningError as exc:
        raise TrialError(f"{where}: {exc}; give crop_start and crop_end in the sheet") from None


def process(trial: Trial, series: TrialSeries, settings: BuildSettings, where: str) -> tuple[Extraction, tuple[int, int], str]:
    """Crop and extract one trial."""
    (start, end), source = find_crop(trial, series, settings, where)
    need = 2 * settings.velocity_k + 1  # angular velocities difference frames i-k and i+k
    if end - start + 1 < need:
        raise TrialError(f"{where}: the crop {start}-{end} holds {end - start + 1} frame(s); a gaze shift's "
                         f"velocities need at least {need} (2k + 1, k = {settings.velocity_k})")
    frame = series.frame_at(start)
    try:
        ex = extract(series.orientations, (start, end), frame, series.rate, trial.yaw, trial.pitch, settings)
    except UsdGazeError as exc:
        raise TrialError(f"{where}: {exc}") from None
    return ex, (start, end), source


def _session_rate(rates: list[float], tolerance: float) -> float:
    """The most common rate (ties: the first trial's)."""
    groups: list[list[float]] = []
    for r in rates:
        for g in groups:
            if abs(r - g[0]) <= tolerance * g[0]:
                g.append(r)
                break
        else:
            groups.append([r])
    best = max(groups, key=len)  # max keeps the first of equal lengths
    return best[0]


def _session_inputs(sheet: Sheet | str | Path, markerset: MarkerSet | str | Path | None):
    """The loaded sheet and marker set, and the skeleton binding that wins (the sheet's over the set's)."""
    if not isinstance(sheet, Sheet):
        sheet = load_sheet(sheet)
    if markerset is None and sheet.markers is not None:
        markerset = sheet.markers
        if not Path(markerset).is_file():  # 'nope.toml: no such file' said nothing of where it was named
            raise SheetError(f"{sheet.path}: markers names {markerset}, which is not a file (a relative path is "
                             "taken from the sheet's folder)")
    if markerset is not None and not isinstance(markerset, MarkerSet):
        markerset = load_markerset(markerset)
    # The sheet's [skeleton] table wins over the marker set's.
    binding = sheet.skeleton
    if binding == SkeletonBinding() and markerset is not None:
        binding = markerset.skeleton

    if markerset is not None and any(not t.is_skeletal for t in sheet.trials):
        markerset.require_complete()
    return sheet, markerset, binding


def _load_trials(sheet: Sheet, markerset: MarkerSet | None,
                 binding: SkeletonBinding) -> tuple[list[TrialReport], dict[str, TrialSeries]]:
    """One report per trial, and the series of each trial that loaded (a failure goes in its report)."""
    reports: list[TrialReport] = []
    loaded: dict[str, TrialSeries] = {}
    for trial in sheet.trials:
        where = f"trial {trial.name} ({trial.file.name})"
        report = TrialReport(trial.name, str(trial.file), trial.yaw, trial.pitch)
        reports.append(report)
        try:
            series = load_series(trial, markerset, binding, where)
        except UsdGazeError as exc:
            report.error = str(exc)
            continue
        loaded[trial.name] = series
        report.rate, report.units, report.filled_samples = series.rate, series.units, series.filled
        longest = series.longest_fill
        if longest is not None and (longest[2] - longest[1] + 1) / series.rate > LONG_FILL_S:
            marker, first, last = longest
            report.warnings.append(f"marker '{marker}' occluded over frames {first}-{last} "
                                   f"({(last - first + 1) / series.rate:.2f} s), filled with a straight line")
    return reports, loaded


def _check_fits_session(trial: Trial, series: TrialSeries, rate: float, targets: dict[tuple[float, float], str],
                        settings: BuildSettings, where: str) -> tuple[float, float]:
    """The trial's target key, once its rate matches the session's and no earlier trial has its target."""
    if abs(series.rate - rate) > settings.rate_tolerance * rate:
        raise TrialError(f"{where}: frame rate {series.rate:g} Hz differs from the session's {rate:g} Hz")
    # Compared as the map stores them (float32): 36 and 36.0000001 would be one example there.
    key = (float(np.float32(trial.yaw)), float(np.float32(trial.pitch)))
    if key in targets:
        raise TrialError(f"{where}: same target ({trial.yaw:g}, {trial.pitch:g}) as trial {targets[key]}; a map holds one example per target")
    return key


def _stored_timing(ex: Extraction) -> np.ndarray:
    """The extraction's timing clipped to the ranges a map stores (a clipped overshoot is warned about)."""
    timing_row = ex.timing.copy()
    span = ex.frames - 1
    # Stored ranges: starts in [0, 1), t_beta in (0, 1], overshoot in [0, 1].
    timing_row[1:5] = np.minimum(timing_row[1:5], (span - 1) / span)
    timing_row[5] = np.clip(timing_row[5], 1.0 / span, 1.0)
    if timing_row[6] > 1.0:
        ex.warnings.append(f"overshoot {timing_row[6]:.2f} clipped to 1")
        timing_row[6] = 1.0
    return timing_row


def _cropped(series: TrialSeries, crop: tuple[int, int]) -> TrialSeries:
    """The series restricted to the crop's frames (inclusive), frame indices counted from the crop."""
    return TrialSeries(
        source=series.source,
        orientations=series.orientations[crop[0] : crop[1] + 1],
        points=series.points[crop[0] : crop[1] + 1],
        frame_at=(lambda i, f=series.frame_at, c=crop[0]: f(i + c)),
        rate=series.rate,
        units=series.units,
        mm_per_unit=series.mm_per_unit,
        filled=series.filled,
    )


def _warn_same_motion(seen: dict[tuple[str, tuple[int, int]], str], trial: Trial, crop: tuple[int, int],
                      report: TrialReport) -> None:
    """Warn of a trial whose file and crop an earlier one has (a row copied and its file left unchanged):
    its example is that trial's motion under another target, the eyes asked to make up the difference."""
    key = (os.path.realpath(trial.file), crop)
    if key in seen:
        report.warnings.append(f"the same file and crop as trial {seen[key]}: one motion stored for two targets")
    seen.setdefault(key, trial.name)


def _extract_trials(sheet: Sheet, reports: list[TrialReport], loaded: dict[str, TrialSeries],
                    rate: float | None, settings: BuildSettings):
    """Offsets, stored timing and target of every trial that extracts, and its cropped series by name."""
    offsets, timing, params, kept = [], [], [], {}
    targets: dict[tuple[float, float], str] = {}
    motions: dict[tuple[str, tuple[int, int]], str] = {}
    for trial, report in zip(sheet.trials, reports):
        series = loaded.get(trial.name)
        if series is None:
            continue
        where = f"trial {trial.name} ({trial.file.name})"
        try:
            key = _check_fits_session(trial, series, rate, targets, settings, where)
            ex, crop, source = process(trial, series, settings, where)
        except UsdGazeError as exc:
            report.error = str(exc)
            continue
        targets[key] = trial.name
        _warn_same_motion(motions, trial, crop, report)
        timing_row = _stored_timing(ex)
        report.status, report.extraction, report.crop, report.crop_source = "ok", ex, crop, source
        report.warnings.extend(ex.warnings)
        offsets.append(ex.offsets)
        timing.append(timing_row)
        params.append(key)
        kept[trial.name] = _cropped(series, crop)
    return offsets, timing, params, kept


def build(sheet: Sheet | str | Path, markerset: MarkerSet | str | Path | None = None,
          settings: BuildSettings = BuildSettings(), synthesis: SynthesisSettings = SynthesisSettings()) -> BuildResult:
    """Build a gaze map definition from a session; never raises for one bad trial."""
    sheet, markerset, binding = _session_inputs(sheet, markerset)
    reports, loaded = _load_trials(sheet, markerset, binding)
    rate = _session_rate([s.rate for s in loaded.values()], settings.rate_tolerance) if loaded else None
    offsets, timing, params, kept = _extract_trials(sheet, reports, loaded, rate, settings)

    definition = None
    if len(offsets) >= settings.min_trials:
        motions = GazeMotions(np.array(offsets), np.array(timing))
        definition = GazeMapDefinition(params=np.array(params), motions=motions, settings=synthesis)
    return BuildResult(definition=definition, reports=reports, settings=settings, rate=rate, series=kept)


def require_definition(result: BuildResult) -> GazeMapDefinition:
    """The definition, or a one-line error saying how many trials failed and the first reason."""
    if result.definition is not None:
        return result.definition
    failed = [r for r in result.reports if r.status != "ok"]
    first = f"; first failure: {failed[0].error}" if failed else ""
    raise BuildError(
        f"only {len(result.good)} of {len(result.reports)} trials gave an example, "
        f"a map needs at least {result.settings.min_trials}{first}"
    )


def layer_data(result: BuildResult, sheet: Sheet, sheet_path: str) -> dict:
    """What goes into the map layer's customLayerData: the sheet (``sheet_path``: as the map names it),
    the thresholds and the outcome. Each trial's file is recorded as the sheet writes it, relative to
    the sheet: recorded as opened (through the working folder), one build gave other bytes run from
    another folder."""
    trials = {}
    for trial, report in zip(sheet.trials, result.reports):
        entry = {"file": trial.written or str(trial.file), "yaw": float(trial.yaw), "pitch": float(trial.pitch), "status": report.status}
        if report.crop:
            entry["cropStart"], entry["cropEnd"] = int(report.crop[0]), int(report.crop[1])
            entry["cropSource"] = report.crop_source
        if report.error:
            entry["error"] = report.error
        trials[trial.name] = entry
    settings = {k: (v if isinstance(v, bool) else float(v) if isinstance(v, float) else int(v))
                for k, v in result.settings.as_dict().items()}
    return {
        "usdgaze:buildMap": {
            "sheet": sheet_path,
            "rate": float(result.rate or 0.0),
            "thresholds": settings,
            "trials": trials,
        }
    }


def write_map(result: BuildResult, sheet: Sheet, out: str | Path, outputs=None) -> GazeMapDefinition:
    """Write the map (``usdgaze.usd.schema.dump_map``) with the sheet and thresholds as layer data."""
    from usdgaze.usd.layers import relative_asset_path
    from usdgaze.usd.schema import dump_map  # pxr only when writing

    definition = require_definition(result)
    record = layer_data(result, sheet, relative_asset_path(sheet.path, out))  # the map's folder's view
    dump_map(definition, out, prim_path="/GazeMap", custom_layer_data=record,
             outputs=outputs, flag="--out")
    return definition
