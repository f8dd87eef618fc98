"""Broken inputs give clear per-trial errors; the map is built from the trials that remain."""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest

from usdgaze.console.main import main
from usdgaze.ingest import BuildError, BuildSettings, build, require_definition

from . import ingest_synth as syn

GOOD = np.array([[0.0, 0.0], [36.0, 0.0], [-72.0, 0.0], [108.0, 12.0], [-144.0, -12.0]])


def _append(sheet, rows):
    with sheet.open("a", newline="") as f:
        writer = csv.writer(f)
        for row in rows:
            writer.writerow(row)


@pytest.fixture(scope="module")
def broken_session(tmp_path_factory):
    """Five good trials and one broken trial of each kind."""
    directory = tmp_path_factory.mktemp("broken")
    session = syn.write_c3d_session(directory, seed=3, params=GOOD)
    rng = np.random.default_rng(11)
    motions = syn.known_motions(np.array([[72.0, 0.0], [180.0, 0.0]]))
    labels = list(syn.LABELS)

    points, _ = syn.simulate_trial(session.motions[1], rng)
    points[:, labels.index("UB2")] = np.nan  # never seen in the whole trial
    syn.write_points(directory / "gone.c3d", syn.LABELS, points, syn.RATE)

    points, _ = syn.simulate_trial(motions[0], rng)
    t = np.arange(len(points)) / syn.RATE
    fidget = 15.0 * np.sin(2 * np.pi * 0.7 * t)[:, None, None] * np.array([1.0, 0.5, 0.0])
    moving = np.array([label != "BOS" for label in labels])
    points[:, moving] += fidget  # the subject never stands still
    syn.write_points(directory / "fidget.c3d", syn.LABELS, points, syn.RATE)

    still = syn.known_motions(np.array([[0.0, 0.0]]))[0]
    points, _ = syn.simulate_trial(still, rng)
    syn.write_points(directory / "still.c3d", syn.LABELS, points, syn.RATE)

    points, _ = syn.simulate_trial(motions[1], rng, rate=100.0)
    syn.write_points(directory / "fast.c3d", syn.LABELS, points, 100.0)

    points, onset = syn.simulate_trial(motions[0], rng, rest_after=0.0)
    syn.write_points(directory / "endsmoving.c3d", syn.LABELS, points[: onset + 30], syn.RATE)

    shutil.copy(session.trials[2].file, directory / "latecrop.c3d")
    _append(session.sheet, [
        ["gone", "gone.c3d", 72, 12, "", ""],
        ["fidget", "fidget.c3d", 72, 0, "", ""],
        ["still", "still.c3d", 144, 0, "", ""],
        ["fast", "fast.c3d", 180, 0, "", ""],
        ["endsmoving", "endsmoving.c3d", 72, -12, "", ""],
        ["latecrop", "latecrop.c3d", -36, 12, 10, 100000],
        ["nofile", "nofile.c3d", 0, 12, "", ""],
        ["dupe", session.trials[1].file.name, 36, 0, "", ""],
        ["neardupe", session.trials[1].file.name, 36.0000001, 0, "", ""],  # 36 as the map stores it (float32)
        ["notc3d", "sheet.csv", 180, 12, "", ""],
    ])
    return session, build(session.sheet, session.markerset)


EXPECTED = {
    "gone": "marker 'UB2' has no sample in the whole trial",
    "fidget": "no rest period found",
    "still": "no motion",
    "fast": "frame rate 100 Hz differs from the session's 60 Hz",
    "endsmoving": "no rest after the motion",
    "latecrop": "crop_end 100000 is past the last frame",
    "nofile": "no such file",
    "dupe": "same target (36, 0) as trial y+036_p+00",
    "neardupe": "same target (36, 0) as trial y+036_p+00",
    "notc3d": "unknown file type '.csv'",
}


@pytest.mark.parametrize("trial", sorted(EXPECTED))
def test_each_broken_trial_is_reported_with_its_reason(broken_session, trial):
    _, result = broken_session
    report = {r.trial: r for r in result.reports}[trial]
    assert report.status == "failed"
    assert report.error.startswith(f"trial {trial} (")  # names the trial and its file
    assert EXPECTED[trial] in report.error
    assert "\n" not in report.error
    if trial in ("still", "fidget", "endsmoving"):
        assert report.error.endswith("give crop_start and crop_end in the sheet")


def test_the_map_is_built_from_the_good_trials(broken_session):
    session, result = broken_session
    assert [r.trial for r in result.good] == [t.name for t in session.trials]
    np.testing.assert_array_equal(result.definition.params, GOOD)
    assert result.rate == 60.0


def test_too_few_good_trials_is_one_clear_error(broken_session):
    session, _ = broken_session
    result = build(session.sheet, session.markerset, BuildSettings(min_trials=6))
    assert result.definition is None
    with pytest.raises(BuildError) as err:
        require_definition(result)
    message = str(err.value)
    assert message.startswith("only 5 of 15 trials gave an example, a map needs at least 6; first failure: trial gone")


def test_a_marker_set_naming_absent_markers_fails_every_trial(broken_session, tmp_path):
    session, _ = broken_session
    markers = tmp_path / "bad.toml"
    markers.write_text(syn.MARKERSET_TOML.replace('"NB3"', '"C7"'))
    result = build(session.sheet, markers)
    for report in result.reports:
        if report.trial not in ("nofile", "notc3d"):
            assert "marker 'C7' is not in the file" in report.error, report.error
    with pytest.raises(BuildError, match="only 0 of 15 trials"):
        require_definition(result)


def test_cli_exit_code_2_and_one_line(broken_session, tmp_path, capsys):
    session, _ = broken_session
    markers = tmp_path / "bad.toml"
    markers.write_text(syn.MARKERSET_TOML.replace('"NB3"', '"C7"'))
    code = main(["build-map", str(session.sheet), "--markers", str(markers), "--out", str(tmp_path / "m.usda"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("usdgaze: error: only 0 of 15 trials gave an example")
    assert not (tmp_path / "m.usda").exists()
    code = main(["build-map", str(tmp_path / "none.csv"), "--out", str(tmp_path / "m.usda")])
    assert code == 2 and "no such trial sheet" in capsys.readouterr().err


def test_a_mirrored_head_square_is_caught_by_the_head_top(broken_session, tmp_path):
    session, _ = broken_session
    markers = tmp_path / "mirrored.toml"
    markers.write_text(syn.MARKERSET_TOML.replace('["HLF", "HLB", "HRB", "HRF"]', '["HRF", "HRB", "HLB", "HLF"]'))
    report = build(session.sheet, markers).reports[1]
    assert report.error == (
        f"trial {report.trial} ({report.trial}.c3d): the head square is listed mirrored (head_top lies below it); "
        "list it left-front, left-back, right-back, right-front"
    )
