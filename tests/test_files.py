"""The one writer, measured from outside: modes under a umask, --sublayer-into semantics, one commit per
command (rollback included), SIGTERM and SIGKILL in the middle of writing a large animation, the
sweep of a killed run's temporaries, build-map's series names and planted symlinks, batch jobs.

Most run the console entry point in this process (``run_inprocess``); the signal tests need a real
``python -m usdgaze`` process to signal.
"""

from __future__ import annotations

import os
import re
import signal
import stat
import subprocess
import time
from pathlib import Path

import pytest
from pxr import Sdf

from usdgaze import api
from usdgaze.errors import UsdGazeError
from usdgaze.files import transaction

from . import measure
from . import synthetic as syn
from .bad_common import CLI, rig, run_inprocess, snapshot

SHIFT = ["--shift", "0.5s:30:0"]


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.fixture
def umask():
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


@pytest.mark.parametrize("mask, expected", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
def test_new_files_get_0666_under_the_umask(tmp_path, umask, mask, expected):
    src = rig(tmp_path).path
    umask(mask)
    code, _, err = run_inprocess(["apply", str(src), *SHIFT, "--out", str(tmp_path / "gaze.usdc"),
                                  "--preview", str(tmp_path / "preview.usda"), "--plot", str(tmp_path / "plot.png")],
                                 tmp_path)
    code2, _, err2 = run_inprocess(["dump-map", str(tmp_path / "map.usda")], tmp_path)
    assert (code, code2) == (0, 0), err + err2
    for name in ("gaze.usdc", "preview.usda", "plot.png", "map.usda"):
        assert _mode(tmp_path / name) == expected, name
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(transaction.TMP_PREFIX)]


def test_a_replaced_output_keeps_its_mode(tmp_path):
    src = rig(tmp_path).path
    out = tmp_path / "gaze.usdc"
    out.write_bytes(b"old")
    os.chmod(out, 0o640)
    api.apply(src, ["0.5s:30:0"], out)
    assert _mode(out) == 0o640 and out.read_bytes()[:8] == b"PXR-USDC"


def _shot(d: Path, body: str = "") -> Path:
    shot = d / "shot.usda"
    shot.write_text('#usda 1.0\n(\n    doc = "shot"\n    subLayers = [\n        @./in.usda@\n    ]\n)\n\n'
                    'over "Character" (\n    kind = "component"\n)\n{\n' + body + '}\n')
    return shot


def test_sublayer_into_keeps_mode_and_everything_but_the_sublayers(tmp_path):
    src = rig(tmp_path).path
    shot = _shot(tmp_path, '    custom string note = "hero"\n')
    os.chmod(shot, 0o640)
    before = Sdf.Layer.OpenAsAnonymous(str(shot)).ExportToString()
    api.apply(src, ["0.5s:30:0"], tmp_path / "gaze.usdc", sublayer_into=shot)
    assert _mode(shot) == 0o640
    after = Sdf.Layer.OpenAsAnonymous(str(shot))
    assert list(after.subLayerPaths) == ["./gaze.usdc", "./in.usda"]
    del after.subLayerPaths[0]
    assert after.ExportToString() == before


def test_sublayer_into_a_symlink_edits_its_target(tmp_path):
    src = rig(tmp_path).path
    real = _shot(tmp_path)
    (tmp_path / "shots").mkdir()
    link = tmp_path / "shots" / "link.usda"
    link.symlink_to(real)
    api.apply(src, ["0.5s:30:0"], tmp_path / "gaze.usdc", sublayer_into=link)
    assert link.is_symlink() and os.readlink(link) == str(real)
    edited = Sdf.Layer.OpenAsAnonymous(str(real))
    assert list(edited.subLayerPaths)[0] == "./gaze.usdc"


def test_an_out_symlink_is_written_through(tmp_path):
    src = rig(tmp_path).path
    (tmp_path / "store").mkdir()
    target = tmp_path / "store" / "gaze.usdc"
    target.write_bytes(b"old")
    (tmp_path / "gaze.usdc").symlink_to(target)
    api.apply(src, ["0.5s:30:0"], tmp_path / "gaze.usdc")
    assert (tmp_path / "gaze.usdc").is_symlink() and target.read_bytes()[:8] == b"PXR-USDC"


def test_a_failing_later_output_leaves_the_earlier_ones_as_they_were(tmp_path):
    src = rig(tmp_path).path
    out = tmp_path / "gaze.usdc"
    out.write_bytes(b"an older override")
    shot = _shot(tmp_path)
    os.chmod(shot, 0o444)  # the sublayer edit, staged last, is refused
    before = snapshot(tmp_path)
    with pytest.raises(UsdGazeError, match="read-only"):
        api.apply(src, ["0.5s:30:0"], out, sublayer_into=shot)
    assert snapshot(tmp_path) == before


def test_a_failed_rename_at_commit_puts_back_what_was_replaced(tmp_path, monkeypatch):
    src = rig(tmp_path).path
    out, preview = tmp_path / "gaze.usdc", tmp_path / "preview.usda"
    out.write_bytes(b"old override")
    before = snapshot(tmp_path)
    real_replace = os.replace
    calls = []

    def second_fails(a, b):
        calls.append(b)
        if len(calls) == 2:
            raise OSError(28, os.strerror(28))
        return real_replace(a, b)

    monkeypatch.setattr(transaction.os, "replace", second_fails)
    with pytest.raises(UsdGazeError, match=r"preview.usda: cannot write \(No space left on device\)"):
        api.apply(src, ["0.5s:30:0"], out, preview=preview)
    monkeypatch.undo()
    assert snapshot(tmp_path) == before  # the override renamed first was put back


# -- signals --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def big(tmp_path_factory):
    """A large animation (12000 frames, a 10 MB override) so that the write takes a while."""
    d = tmp_path_factory.mktemp("big")
    return syn.make_rig(d / "in.usdc", frames=12000, mesh=False)


def _stops_default() -> None:
    """The stopping signals at their default action in the command, as a terminal starts it: a suite
    run under nohup or in a background job would hand them down ignored."""
    for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGQUIT):
        signal.signal(sig, signal.SIG_DFL)


def _start_and_catch_writing(src: Path, d: Path) -> subprocess.Popen:
    """Start an apply and return once its override is being written in the temporary folder.

    The plot staged after the override keeps the command writing for a second or more, so that a
    loaded machine still catches it between the first staged byte and the commit."""
    proc = subprocess.Popen([*CLI, "apply", str(src), *SHIFT, "--out", str(d / "gaze.usdc"),
                             "--plot", str(d / "plot.png")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_stops_default)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        staged = [p for p in d.glob(f"{transaction.TMP_PREFIX}*/gaze.usdc")]
        if staged:
            return proc
        time.sleep(0.001)
    proc.kill()
    raise AssertionError(f"never caught the write in progress (exit {proc.returncode}): {proc.communicate()}")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT],
                         ids=lambda s: signal.Signals(s).name)
def test_a_stopping_signal_while_writing_leaves_nothing(tmp_path, big, sig):
    """SIGHUP (a closed terminal, a dropped ssh) and SIGQUIT left the temporary folder and the partial
    override behind: only SIGTERM and SIGINT were handled."""
    src = tmp_path / "in.usdc"
    os.link(big.path, src)
    before = snapshot(tmp_path)
    proc = _start_and_catch_writing(src, tmp_path)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    assert err.splitlines() == [f"usdgaze: error: interrupted by {signal.Signals(sig).name}; nothing was written"]
    assert snapshot(tmp_path) == before


def test_a_signal_during_the_renames_lets_them_finish(tmp_path, monkeypatch):
    """SIGTERM between two renames of the commit: both outputs are the new ones, and the line says so."""
    src = rig(tmp_path).path
    out, preview = tmp_path / "gaze.usdc", tmp_path / "preview.usda"
    out.write_bytes(b"old override")
    preview.write_bytes(b"old preview")
    real_replace = os.replace

    def first_then_signal(a, b):
        real_replace(a, b)
        if Path(b) == out:
            os.kill(os.getpid(), signal.SIGTERM)  # a real signal, delivered to this (main) thread's handler

    monkeypatch.setattr(transaction.os, "replace", first_then_signal)
    code, _, err = run_inprocess(["apply", str(src), *SHIFT, "--out", str(out), "--preview", str(preview)], tmp_path)
    monkeypatch.undo()
    assert code == 128 + signal.SIGTERM, err
    assert err.splitlines() == ["usdgaze: error: interrupted by SIGTERM; every output had been written when it stopped"]
    assert out.read_bytes()[:8] == b"PXR-USDC" and preview.read_text().startswith("#usda")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(transaction.TMP_PREFIX)]


@pytest.mark.parametrize("how", ["done", "failed", "interrupted"])
def test_a_signal_during_the_cleanup_waits_for_it_and_is_not_lost(tmp_path, monkeypatch, how):
    """A SIGTERM while the temporaries are removed (a process pool signals a stopping worker twice)
    lets the removal finish and the handlers be put back, then stops the command."""
    from usdgaze.errors import Interrupted

    before = signal.getsignal(signal.SIGTERM)
    real_rmtree = transaction.shutil.rmtree

    def signal_then_rmtree(path, *args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)  # handled on this line's return, in the main thread
        real_rmtree(path, *args, **kwargs)

    monkeypatch.setattr(transaction.shutil, "rmtree", signal_then_rmtree)
    out = tmp_path / "out.txt"
    with pytest.raises(Interrupted) as caught:
        with transaction.Outputs() as tx:
            tx.claim(out, "--out")
            tx.stage_text(out, "new\n")
            if how == "failed":
                raise UsdGazeError("bad input")
            if how == "interrupted":
                raise Interrupted(signal.SIGTERM)
    monkeypatch.undo()
    assert signal.getsignal(signal.SIGTERM) is before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(transaction.TMP_PREFIX)]
    assert out.exists() == (how == "done")
    if how == "done":
        assert caught.value.detail == "every output had been written when it stopped"
    assert isinstance(caught.value.__cause__, UsdGazeError) == (how == "failed")


@pytest.mark.parametrize("workers, earlier, sig", [("1", False, signal.SIGTERM), ("2", False, signal.SIGTERM),
                                                   ("1", True, signal.SIGTERM), ("2", False, signal.SIGHUP)])
def test_a_stop_in_a_batch_keeps_finished_shots_and_says_so(tmp_path, big, workers, earlier, sig):
    """``earlier``: an earlier run's summary is beside the manifest. It is left as it is (an interrupted
    command writes nothing of its own), and the line says whose it is: a dashboard reading it took
    that run's exit code 0 for this one's. SIGHUP goes to the whole process group, as a closed
    terminal sends it: it left the shots' temporary folders behind."""
    rig(tmp_path)
    os.link(big.path, tmp_path / "big.usdc")
    (tmp_path / "m.toml").write_text(
        '[[job]]\nname = "small"\ninput = "in.usda"\nout = "small.usdc"\nshifts = ["0.5s:30:0"]\n'
        '[[job]]\nname = "big"\ninput = "big.usdc"\nout = "big_gaze.usdc"\nplot = "big.png"\nshifts = ["0.5s:30:0"]\n')
    old_summary = '{"started": "2026-01-02T03:04:05+00:00", "exit_code": 0, "shots": []}\n'
    if earlier:
        (tmp_path / "m.summary.json").write_text(old_summary)
    proc = subprocess.Popen([*CLI, "batch", str(tmp_path / "m.toml"), "--workers", workers],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_stops_default,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while not (tmp_path / "small.usdc").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    if sig == signal.SIGHUP:
        os.killpg(proc.pid, sig)  # the workers too
    else:
        proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    # The small shot may be between its renames and its report when the signal comes: 0 or 1 reported.
    said = (rf" \({re.escape(str(tmp_path / 'm.summary.json'))} is an earlier run's, started 2026-01-02T03:04:05\+00:00\)"
            if earlier else "")
    assert re.fullmatch(rf"usdgaze: error: interrupted by {signal.Signals(sig).name}; [01] of 2 shots were "
                        r"reported finished; finished shots keep their outputs \(a rerun skips them\), no shot is "
                        r"half-written, no summary was written" + said, err.splitlines()[-1]), err
    assert "Traceback" not in err
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(["big.usdc", "in.usda", "m.toml", "small.usdc"] + (["m.summary.json"] if earlier else [])), left
    if earlier:
        assert (tmp_path / "m.summary.json").read_text() == old_summary


def test_sigkill_while_writing_leaves_the_target_and_the_next_run_sweeps(tmp_path, big):
    src = tmp_path / "in.usdc"
    os.link(big.path, src)
    (tmp_path / "gaze.usdc").write_bytes(b"the previous override")
    before = snapshot(tmp_path)
    proc = _start_and_catch_writing(src, tmp_path)
    proc.kill()
    proc.wait(timeout=60)
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(transaction.TMP_PREFIX)]
    assert len(leftovers) == 1 and f"-{proc.pid}-" in leftovers[0]
    assert {k: v for k, v in snapshot(tmp_path).items() if not k.startswith(transaction.TMP_PREFIX)} == before
    # The next run that writes into the folder removes the dead run's temporaries.
    small = rig(tmp_path, "small.usda").path
    code, _, err = run_inprocess(["apply", str(small), *SHIFT, "--out", str(tmp_path / "other.usdc")], tmp_path)
    assert code == 0, err
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(transaction.TMP_PREFIX)]
    assert measure.sha256(tmp_path / "gaze.usdc") == before["gaze.usdc"][1]


def test_a_live_runs_temporaries_are_not_swept(tmp_path):
    live = tmp_path / f"{transaction.TMP_PREFIX}{transaction._host()}-{os.getpid()}-abcd"
    live.mkdir()
    dead = tmp_path / f"{transaction.TMP_PREFIX}{transaction._host()}-999999999-abcd"
    dead.mkdir()
    assert transaction.sweep(tmp_path) == [dead.name]
    assert live.exists()


def test_another_hosts_temporaries_are_not_swept_when_the_names_share_32_characters(tmp_path, monkeypatch):
    """Farm nodes writing into one shared output folder: host names were cut to 32 characters, so
    gke-render-pool-0a1b2c3d-default-node-7 and ...-node-8 were one host to the sweep, which judged the
    other node's live temporaries by a pid of its own host (not running here: removed mid-write)."""
    import socket

    def named(host: str) -> str:
        monkeypatch.setattr(socket, "gethostname", lambda: host)
        return transaction._host()

    other = tmp_path / f"{transaction.TMP_PREFIX}{named('gke-render-pool-0a1b2c3d-default-node-8')}-999999999-abcd"
    other.mkdir()  # a run on the other node, writing right now
    named("gke-render-pool-0a1b2c3d-default-node-7")
    assert transaction.sweep(tmp_path) == []
    assert other.exists()
    dead = tmp_path / f"{transaction.TMP_PREFIX}{transaction._host()}-999999999-abcd"
    dead.mkdir()  # this node's own dead run is still swept
    assert transaction.sweep(tmp_path) == [dead.name]


# -- build-map and batch --------------------------------------------------------------------------

def test_series_names_stay_inside_the_folder_and_planted_symlinks_are_replaced(tmp_path):
    from types import SimpleNamespace

    from usdgaze.ingest import report

    victim = tmp_path / "victim.csv"
    victim.write_text("precious\n")
    series = tmp_path / "series"
    series.mkdir()
    (series / "y0.csv").symlink_to(victim)
    names = ["../escape", "a/b", "..", ".hidden", "y0"]
    paths = report.series_paths(series, names)
    assert all(p.parent == series and not p.name.startswith(".") for p in paths)
    assert len(set(paths)) == len(paths)
    result = SimpleNamespace(good=[SimpleNamespace(trial=n) for n in names])
    rows = (["frame", "time_s"], [[0, 0.0]])
    orig = report.series_rows
    report.series_rows = lambda result, trial: (rows[0], __import__("numpy").array(rows[1]))
    try:
        written = report.write_series(series, result)
    finally:
        report.series_rows = orig
    assert victim.read_text() == "precious\n"
    assert not (series / "y0.csv").is_symlink() and (series / "y0.csv").read_text().startswith("frame,time_s")
    assert sorted(p.name for p in series.iterdir()) == sorted(p.name for p in written)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["series", "victim.csv"]


def test_batch_creates_missing_folders_only_for_jobs_that_succeed(tmp_path):
    rig(tmp_path)
    (tmp_path / "m.toml").write_text(
        '[[job]]\nname = "good"\ninput = "in.usda"\nout = "a/good.usdc"\nshifts = ["0.5s:30:0"]\n'
        '[[job]]\nname = "bad"\ninput = "in.usda"\nout = "b/bad.usdc"\nshifts = ["0.5s:30:0"]\nskel_root = "/None"\n')
    code, out, err = run_inprocess(["batch", str(tmp_path / "m.toml"), "--summary", str(tmp_path / "r.json")], tmp_path)
    assert code == 2, err
    assert (tmp_path / "a" / "good.usdc").exists() and not (tmp_path / "b").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "in.usda", "m.toml", "r.json"]
