"""Captures at an NTSC rate (1000/1001 of the nominal: 59.94 Hz beside 60) are one session: each trial
is timed by its own rate, so a 0.1% rate difference is not a reason to drop a trial."""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.ingest import build

from . import ingest_synth as syn

PARAMS = np.array([[0.0, 0.0], [36.0, 0.0], [-72.0, 0.0], [108.0, 12.0], [-144.0, -12.0]])


def _build_with(tmp_path, rate):
    session = syn.write_c3d_session(tmp_path, seed=5, params=PARAMS)
    truth = session.trials[2]
    points, _ = syn.simulate_trial(truth.motion, np.random.default_rng(3), rate=rate)
    syn.write_points(truth.file, syn.LABELS, points, rate)
    result = build(session.sheet, session.markerset)
    return result, {r.trial: r for r in result.reports}[truth.name]


@pytest.mark.parametrize("other", [59.94, 60000 / 1001, 60.06])
def test_a_trial_at_an_ntsc_rate_joins_the_session(tmp_path, other):
    _, twin = _build_with(tmp_path / "60", 60.0)  # the same capture at the nominal rate
    result, report = _build_with(tmp_path / "ntsc", other)

    assert [r.status for r in result.reports] == ["ok"] * len(PARAMS), [r.error for r in result.reports]
    assert result.rate == 60.0
    assert report.rate == pytest.approx(other, rel=1e-6)
    # Timed by its own rate: its crop and the head's peak are where the twin's are, in seconds.
    row, twin_row = report.row(), twin.row()
    for key in ("duration_s", "peak_s"):
        assert row[key] == pytest.approx(twin_row[key], abs=2.0 / 60.0), key
