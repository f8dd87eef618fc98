"""Inputs that are not regular files (a named pipe, /dev/null) and outputs of one command that name
one file: exit 2, one line naming the path and what it is, the folder as it was.

Before: a marker set or batch manifest that is a named pipe hung the command (the open waits for a
writer); /dev/null read as an empty TOML table ("[markers] lacks ..."); a trial sheet that is a pipe
was "no such trial sheet"; ``build-map --report DIR/TRIAL.csv --series DIR`` wrote the trial's
series over the report, exit 0.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import threading
from pathlib import Path

import numpy as np
import pytest

from usdgaze.console.main import main

from . import ingest_synth as syn
from .bad_common import JOB, manifest, sheet, snapshot


@contextlib.contextmanager
def _unblocked(fifo: Path):
    """Whoever opens ``fifo`` to read gets end-of-file at once instead of waiting for a writer, so a
    command that opens it finishes (and fails its test) rather than hanging the suite. Yields a list
    that holds one entry per such open: a command that hung on the pipe is one that opened it."""
    stop = threading.Event()
    opened: list[int] = []

    def writer() -> None:
        while not stop.wait(0.002):
            try:
                fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)  # succeeds only once a reader waits
            except OSError as exc:
                if exc.errno != errno.ENXIO:
                    raise
                continue
            opened.append(fd)
            os.close(fd)

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        yield opened
    finally:
        stop.set()
        thread.join()


def _argv(d: Path, special: Path, where: str) -> list[str]:
    """A command that reads ``special`` as its ``where`` (a marker set, a manifest, a trial sheet)."""
    if where == "marker set":
        return ["build-map", str(sheet(d)), "--markers", str(special), "--out", str(d / "map.usda")]
    if where == "manifest":
        manifest(d, f"[[job]]\n{JOB}")
        return ["batch", str(special)]
    return ["build-map", str(special), "--out", str(d / "map.usda")]


@pytest.mark.parametrize("where", ["marker set", "manifest", "trial sheet"])
@pytest.mark.parametrize("kind", ["a named pipe", "a character device"])
def test_an_input_that_is_not_a_regular_file_is_one_line(tmp_path, capsys, where, kind):
    if kind == "a named pipe":
        special = tmp_path / "input.toml"
        os.mkfifo(special)
    else:
        special = Path(os.devnull)
    argv = _argv(tmp_path, special, where)
    before = snapshot(tmp_path)
    with _unblocked(special) if kind == "a named pipe" else contextlib.nullcontext([]) as opened:
        code = main(argv)
    err = capsys.readouterr().err.splitlines()
    assert (code, err, opened) == (2, [f"usdgaze: error: {special}: is {kind}, not a regular file"], [])
    assert snapshot(tmp_path) == before


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    params = np.array([[0.0, 0.0], [36.0, 0.0], [-36.0, 0.0]])
    return syn.write_c3d_session(tmp_path_factory.mktemp("special"), seed=5, params=params)


@pytest.mark.parametrize("spelled", ["plain", "symlink"])
def test_a_report_that_is_a_series_file_is_refused(session, tmp_path, capsys, spelled):
    """--report DIR/TRIAL.csv (or a symlink to it) with --series DIR: both outputs are one file."""
    series = tmp_path / "series"
    series.mkdir()
    trial = session.trials[1].name
    report = series / f"{trial}.csv"
    if spelled == "symlink":
        report = tmp_path / "report.csv"
        report.symlink_to(series / f"{trial}.csv")
    before = snapshot(tmp_path)
    code = main(["build-map", str(session.sheet), "--markers", str(session.markerset), "--out",
                 str(tmp_path / "map.usda"), "--report", str(report), "--series", str(series), "--quiet"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and err == [f"usdgaze: error: {series / (trial + '.csv')}: --series file of trial '{trial}' "
                                 "and --report name the same file; give each output its own path"]
    assert snapshot(tmp_path) == before


def test_a_clip_trial_or_a_batch_input_that_is_a_named_pipe_is_one_line(tmp_path, capsys):
    """The files a UsdSkel trial or a batch shot composes were listed by opening it with USD, which waits
    on a pipe for a writer (build-map and batch hung); now the trial fails, and the shot, saying what it is."""
    pipe = tmp_path / "in.usda"
    os.mkfifo(pipe)
    (tmp_path / "sheet.toml").write_text('[[trial]]\nname = "t"\nfile = "in.usda"\nyaw = 72\npitch = 12\n')
    (tmp_path / "jobs.toml").write_text(f"[[job]]\n{JOB}")
    before = snapshot(tmp_path)
    with _unblocked(pipe) as opened:
        code = main(["build-map", str(tmp_path / "sheet.toml"), "--out", str(tmp_path / "map.usda"), "--min-trials", "1"])
        err = capsys.readouterr().err.splitlines()
        assert (code, err) == (2, ["usdgaze: error: only 0 of 1 trials gave an example, a map needs at least 1; first "
                                   f"failure: trial t (in.usda): {pipe}: is a named pipe, not a regular file (the sheet's 'in.usda', "
                                   "relative to the sheet's folder)"])
        assert snapshot(tmp_path) == before
        code = main(["batch", str(tmp_path / "jobs.toml")])
    [shot] = json.loads((tmp_path / "jobs.summary.json").read_text())["shots"]
    assert code == 2 and (shot["status"], shot["message"]) == ("bad input", f"{pipe}: is a named pipe, not a regular file")
    assert opened == []  # neither command opened the pipe (it waited there for a writer)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda", "jobs.summary.json", "jobs.toml", "sheet.toml"]
