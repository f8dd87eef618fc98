"""``usdgaze build-map``: the command, the map file it writes, the report and series files."""

from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest
from pxr import Sdf

from usdgaze.console.main import main
from usdgaze.ingest import build

from . import ingest_synth as syn

PARAMS = np.array([[0.0, 0.0], [36.0, 0.0], [-36.0, 0.0], [108.0, 12.0], [-144.0, -12.0], [180.0, 0.0]])


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    return syn.write_c3d_session(tmp_path_factory.mktemp("cli"), seed=5, params=PARAMS)


def test_build_map_writes_map_report_and_series(session, tmp_path, capsys):
    out, report, series = tmp_path / "map.usda", tmp_path / "report.csv", tmp_path / "series"
    code = main(["build-map", str(session.sheet), "--markers", str(session.markerset), "--out", str(out),
                 "--report", str(report), "--series", str(series)])
    stdout = capsys.readouterr().out
    assert code == 0
    lines = stdout.splitlines()
    assert lines[0].split()[:3] == ["trial", "status", "crop"]
    assert all(any(line.startswith(t.name) for line in lines) for t in session.trials)
    assert f"wrote {out}: 6 examples" in stdout

    expected = build(session.sheet, session.markerset)
    from usdgaze.usd.schema import load_map

    stored = load_map(str(out))
    np.testing.assert_array_equal(stored.params, PARAMS)  # examples in sheet order
    np.testing.assert_allclose(stored.motions.offsets, expected.definition.motions.offsets, atol=1e-6)
    np.testing.assert_allclose(stored.motions.timing, expected.definition.motions.timing, rtol=1e-6, atol=1e-6)

    data = Sdf.Layer.FindOrOpen(str(out)).customLayerData["usdgaze:buildMap"]
    rel = os.path.relpath(session.sheet, tmp_path)
    assert data["sheet"] == (rel if rel.startswith("..") else "./" + rel)  # from the map's folder
    assert data["trials"]["y+000_p+00"]["file"] == session.trials[0].file.name  # as the sheet writes it
    assert data["thresholds"]["rest_speed_mm_s"] == 6.0 and data["thresholds"]["start_speed_deg_s"] == 18.0
    assert data["trials"]["y+000_p+00"]["cropSource"] == "manual"
    assert data["trials"]["y+036_p+00"]["yaw"] == 36.0

    with report.open() as f:
        rows = list(csv.DictReader(f))
    assert [r["trial"] for r in rows] == [t.name for t in session.trials]
    for row, rep in zip(rows, expected.reports):
        assert row["status"] == "ok"
        assert (int(row["crop_start"]), int(row["crop_end"])) == rep.crop
        assert float(row["beta"]) == pytest.approx(rep.extraction.timing[6], abs=1e-6)
    assert sorted(p.name for p in series.iterdir()) == sorted(f"{t.name}.csv" for t in session.trials)


def test_two_trials_whose_series_would_be_one_file_are_one_line(session, tmp_path, capsys):
    """Trials 'x/y' and 'x_y' both name the series file x_y.csv: the second replaced the first."""
    rows = session.sheet.read_text().splitlines()
    sheet = tmp_path / "sheet.csv"
    first, second = rows[1].split(",", 1), rows[2].split(",", 1)
    sheet.write_text("\n".join([rows[0], "x/y," + first[1], "x_y," + second[1], *rows[3:]]) + "\n")
    for trial in session.trials:  # the sheet names its files relative to its folder
        (tmp_path / trial.file.name).symlink_to(trial.file)
    out, series = tmp_path / "map.usda", tmp_path / "series"
    code = main(["build-map", str(sheet), "--markers", str(session.markerset), "--out", str(out),
                 "--series", str(series), "--quiet"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and err == [f"usdgaze: error: {series / 'x_y.csv'}: the --series file of both trial 'x/y' and "
                                 "trial 'x_y' (a name's separators become '_'); rename one of them in the sheet"]
    assert not out.exists() and not series.exists()


def test_thresholds_reach_the_build_and_the_layer(session, tmp_path, capsys):
    out, report = tmp_path / "map.usda", tmp_path / "report.json"
    code = main(["build-map", str(session.sheet), "--markers", str(session.markerset), "--out", str(out),
                 "--report", str(report), "--start-speed", "1000", "--k", "4", "--quiet"])
    assert code == 0
    assert "trial" not in capsys.readouterr().out.splitlines()[0]  # --quiet: no table
    rows = json.loads(report.read_text())
    # nothing turns at 1000 deg/s: every start is 0 and the report says so
    assert all(r["neck_start_s"] == 0.0 and "start 0" in r["warnings"] for r in rows)
    data = Sdf.Layer.FindOrOpen(str(out)).customLayerData["usdgaze:buildMap"]
    assert data["thresholds"]["start_speed_deg_s"] == 1000.0 and data["thresholds"]["velocity_k"] == 4


@pytest.mark.parametrize(
    "args, message",
    [
        (["--report", "r.txt"], "a report must be .csv or .json"),
        (["--k", "0"], "velocity_k = 0 is out of range"),
        (["--min-trials", "7"], "only 6 of 6 trials gave an example, a map needs at least 7"),
    ],
)
def test_bad_options_exit_2(session, tmp_path, capsys, args, message):
    code = main(["build-map", str(session.sheet), "--markers", str(session.markerset),
                 "--out", str(tmp_path / "m.usda"), "--quiet"] + [a if a != "r.txt" else str(tmp_path / a) for a in args])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "m.usda").exists()


def test_quiet_still_says_which_trial_was_skipped_and_why(session, tmp_path, capsys):
    """``--quiet`` leaves the table out; a skipped trial was left out with it ("6 examples (1 trial
    skipped)" and nothing saying which one or why)."""
    sheet = tmp_path / "sheet.csv"
    rows = session.sheet.read_text().splitlines()
    rows.append("Gone,gone.c3d,72,0,,")
    sheet.write_text("\n".join(rows) + "\n")
    for t in session.trials:  # the sheet names its trials relative to its own folder
        (tmp_path / t.file.name).symlink_to(t.file)
    out = tmp_path / "map.usda"
    assert main(["build-map", str(sheet), "--markers", str(session.markerset), "--out", str(out), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "(1 trial skipped)" in captured.out and out.exists()
    (line,) = captured.err.strip().splitlines()
    assert line.startswith("usdgaze: warning: trial Gone skipped: ") and "no such file" in line, line


def test_the_same_build_from_another_working_folder_writes_the_same_bytes(session, tmp_path, monkeypatch):
    """The map records its sheet from the map's folder and each trial's file as the sheet writes it:
    recorded as opened through the working folder, the same inputs gave other bytes run from another
    folder."""
    maps = []
    for cwd in (session.sheet.parent, tmp_path):
        monkeypatch.chdir(cwd)
        out = tmp_path / "out" / "map.usda"
        out.parent.mkdir(exist_ok=True)
        sheet, markers = (os.path.relpath(p, cwd) for p in (session.sheet, session.markerset))
        assert main(["build-map", sheet, "--markers", markers, "--out", os.path.relpath(out, cwd), "--quiet"]) == 0
        maps.append(out.read_bytes())
    assert maps[0] == maps[1]



def test_a_missing_marker_set_named_by_the_sheet_is_said_with_the_sheet(session, tmp_path, capsys):
    """A TOML sheet's ``markers = "nope.toml"`` that names no file said 'nope.toml: no such file', not
    where it was named."""
    rows = "".join(f'[[trial]]\nfile = "{t.file}"\nyaw = {t.yaw:g}\npitch = {t.pitch:g}\n' for t in session.trials)
    sheet = tmp_path / "sheet.toml"
    sheet.write_text('markers = "nope.toml"\n' + rows)
    out = tmp_path / "map.usda"
    assert main(["build-map", str(sheet), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{sheet}: markers names {tmp_path / 'nope.toml'}" in err[0], err
    assert not out.exists()
