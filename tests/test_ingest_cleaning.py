"""Cleaning (Heck 5.2.2.1): stabilization, marker speed, rest periods, cropping, unit handling."""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.ingest.build import TrialError, find_crop
from usdgaze.ingest.cleaning import CleaningError, Rest, crop_by_rest, mean_marker_speed, rest_periods, stabilize
from usdgaze.ingest.markers import load_markerset
from usdgaze.ingest.series import read_marker_series
from usdgaze.ingest.settings import BuildSettings, SettingsError
from usdgaze.ingest.sheet import Trial

from . import ingest_synth as syn


def test_stabilize_puts_the_base_at_the_origin_and_keeps_distances():
    rng = np.random.default_rng(1)
    p = rng.normal(0.0, 100.0, (20, 5, 3))
    s = stabilize(p, 2)
    np.testing.assert_allclose(s[:, 2], 0.0)
    np.testing.assert_allclose(s[:, 0] - s[:, 4], p[:, 0] - p[:, 4])


def test_mean_marker_speed_of_known_motion():
    frames, rate = 30, 60.0
    t = np.arange(frames) / rate
    p = np.zeros((frames, 2, 3))
    p[:, 0, 0] = 10.0 * t  # 10 units/s along x
    p[:, 1, 1] = -30.0 * t  # 30 units/s along -y
    for span in (1, 4, 9):
        np.testing.assert_allclose(mean_marker_speed(p, rate, span), 20.0)  # ends are one-sided, same speed
    # a marker excluded (e.g. the stabilized base) does not count
    np.testing.assert_allclose(mean_marker_speed(p, rate, 3, exclude=[1]), 10.0)


def test_rest_periods_merge_close_rests_and_drop_short_ones():
    speed = np.full(60, 10.0)
    speed[0:10] = 1.0  # rest A
    speed[12:20] = 1.0  # 2 moving frames after A: merges into A
    speed[30:33] = 1.0  # 3 still frames: too short alone
    speed[45:60] = 1.0  # rest B
    assert rest_periods(speed, 6.0, merge_frames=5) == [Rest(0, 19), Rest(30, 32), Rest(45, 59)]
    assert rest_periods(speed, 6.0, merge_frames=5, min_frames=5) == [Rest(0, 19), Rest(45, 59)]
    assert rest_periods(speed, 6.0, merge_frames=1) == [Rest(0, 9), Rest(12, 19), Rest(30, 32), Rest(45, 59)]
    assert crop_by_rest(rest_periods(speed, 6.0, 5, 5), 60) == (19, 59)  # end of 1st .. end of 2nd


@pytest.mark.parametrize(
    "rests, message",
    [
        ([], "no rest period found"),
        ([Rest(0, 99)], "no motion"),
        ([Rest(0, 40)], "no rest after the motion"),
        ([Rest(60, 99)], "no rest before the motion"),
    ],
)
def test_crop_failures_say_why(rests, message):
    with pytest.raises(CleaningError, match=message):
        crop_by_rest(rests, 100)


def test_thresholds_in_mm_follow_the_file_units(tmp_path):
    """The same trial written in mm and in metres crops identically (V = 6 mm/s = 0.006 m/s)."""
    m = syn.known_motions(np.array([[108.0, 0.0]]))[0]
    points, onset = syn.simulate_trial(m, np.random.default_rng(4))
    syn.write_points(tmp_path / "mm.c3d", syn.LABELS, points, syn.RATE, "mm")
    syn.write_points(tmp_path / "m.c3d", syn.LABELS, points / 1000.0, syn.RATE, "m")
    (tmp_path / "markers.toml").write_text(syn.MARKERSET_TOML)
    markerset = load_markerset(tmp_path / "markers.toml")
    crops = []
    for name in ("mm", "m"):
        series = read_marker_series(str(tmp_path / f"{name}.c3d"), markerset, name)
        crops.append(find_crop(Trial(name, tmp_path / f"{name}.c3d", 108.0, 0.0), series, BuildSettings(), name)[0])
    assert crops[0] == crops[1]
    assert crops[0][0] <= onset + 3 and crops[0][1] == len(points) - 1
    # and a threshold not converted (6 m/s on the metre file) would see no motion at all
    series = read_marker_series(str(tmp_path / "m.c3d"), markerset, "m")
    with pytest.raises(TrialError, match="no motion"):
        find_crop(Trial("m", tmp_path / "m.c3d", 108.0, 0.0), series, BuildSettings(rest_speed_mm_s=6000.0), "m")


def test_settings_out_of_range_are_user_errors():
    with pytest.raises(SettingsError, match="velocity_k = 0"):
        BuildSettings(velocity_k=0)


def test_gaps_written_as_zeros_are_gaps(tmp_path):
    """Exporters that write an occluded sample as (0, 0, 0) with a residual of 0 (not -1) give the
    same examples as residual -1 gaps: each trial's P+ within 1 deg of the known motion."""
    params = np.array([[-36.0, -12.0], [72.0, 12.0], [180.0, 0.0]])
    motions = syn.known_motions(params)
    rng = np.random.default_rng(0)
    rows = ["trial,file,yaw,pitch"]
    for i, (yaw, pitch) in enumerate(params):
        points, _ = syn.simulate_trial(motions[i], rng, gaps=8)
        assert np.isnan(points).any()
        name = syn.trial_name(yaw, pitch)
        syn.write_points(tmp_path / f"{name}.c3d", syn.LABELS, np.nan_to_num(points, nan=0.0), syn.RATE)
        rows.append(f"{name},{name}.c3d,{yaw:g},{pitch:g}")
    (tmp_path / "sheet.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "markers.toml").write_text(syn.MARKERSET_TOML)
    from usdgaze.core import rotations as rot
    from usdgaze.ingest.build import build

    result = build(tmp_path / "sheet.csv", tmp_path / "markers.toml")
    assert [r.error for r in result.reports] == [""] * len(params)
    for i, report in enumerate(result.reports):
        error = np.degrees(rot.angle(rot.relative(report.extraction.offsets[:4], motions.offsets[i][:4])))
        assert error.max() < 1.0, (report.trial, error)
        assert report.filled_samples > 0
