"""Batch checks: manifest values checked up front; a second stop signal while the first one unwinds
still cleans up the writer's temporaries; a pool worker whose shot was stopped takes no other."""

from __future__ import annotations

import errno
import json
import os
import signal

import pytest

from usdgaze.batch.manifest import load_manifest
from usdgaze.console.main import main
from usdgaze.errors import Interrupted, UsdGazeError
from usdgaze.files.transaction import TMP_PREFIX, Outputs


def _manifest(tmp_path, extra: str):
    (tmp_path / "in.usda").write_text("#usda 1.0\n")
    path = tmp_path / "m.toml"
    path.write_text('[[job]]\nname = "w"\ninput = "in.usda"\nout = "gaze.usdc"\n' + extra)
    return path


@pytest.mark.parametrize("extra, words", [
    ('shifts = ["1s:10:0:weight=2"]\n', ["job 0 'w': shifts = '1s:10:0:weight=2'", "weight must be a number in [0, 1]"]),
    ('shifts = ["1s:10:0:blend=-1"]\n', ["job 0 'w': shifts = '1s:10:0:blend=-1'", "blend must be >= 0"]),
    ('shifts = ["1s:10:0:foo=1"]\n', ["job 0 'w': shifts = '1s:10:0:foo=1'", "unknown or repeated option"]),
    ('shifts = ["2s:abc"]\n', ["job 0 'w': shifts = '2s:abc'", "expected TIME:YAW:PITCH"]),
    ('shifts = ["1s:10:0"]\nplot = "gaze.txt"\n', ["job 0 'w': plot = 'gaze.txt'", "must end in .png, .pdf or .svg"]),
    ('shifts = ["1s:10:0"]\nskel_root = "Body"\n', ["job 0 'w': skel_root = 'Body'", "absolute prim path"]),
    ('shifts = ["1s:10:0"]\nskel_root = "/a b"\n', ["job 0 'w': skel_root = '/a b'", "absolute prim path"]),
    ('shifts = ["1s:10:0"]\nmap = "in.usda:/Bad Prim"\n', ["job 0 'w': map = 'in.usda:/Bad Prim'", "absolute prim path"]),
])
def test_values_are_refused_naming_manifest_job_and_key(tmp_path, extra, words):
    path = _manifest(tmp_path, extra)
    with pytest.raises(UsdGazeError) as info:
        load_manifest(path)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    assert "--shift" not in message
    for word in words:
        assert word in message


@pytest.mark.parametrize("defaults, job, said", [
    ('shifts = ["2s:abc"]', "", "[defaults] shifts = '2s:abc': YAW 'abc' is not a number; expected TIME:YAW:PITCH"),
    ('shifts = ["1s:10:0:weight=2"]', "", "[defaults] shifts = '1s:10:0:weight=2': weight must be"),
    ("fixation = -1", 'shifts = ["1s:10:0"]', "[defaults] fixation = -1.0: must be a positive distance"),
    ('plot = "gaze.txt"', 'shifts = ["1s:10:0"]', "[defaults] plot = 'gaze.txt': must end in .png"),
    ('eye_timing = "fast"', 'shifts = ["1s:10:0"]', "[defaults] eye_timing = 'fast': expected one of"),
    ('command = "render"', 'shifts = ["1s:10:0"]', "[defaults] command = 'render': expected one of"),
])
def test_a_bad_value_in_defaults_is_named_as_the_defaults_key_as_written(tmp_path, capsys, defaults, job, said):
    """A bad [defaults] value was said of the first job that inherits it, and a shift under the CLI's
    name: 'job 0 'w': shift = ...'. The fix is in [defaults]: the message names that table and the key
    as written there; the same value written in the job still names the job."""
    path = _manifest(tmp_path, job + "\n")
    job_only = path.read_text()
    for body, place in ((f"[defaults]\n{defaults}\n\n{job_only}", f"{path}: "),
                        (job_only.replace('name = "w"', f'name = "w"\n{defaults}'), f"{path}: job 0 'w': ")):
        path.write_text(body)
        assert main(["batch", str(path)]) == 2
        err = capsys.readouterr().err.strip()
        if place == f"{path}: ":  # from [defaults]: no job named
            assert err.count("\n") == 0 and f"{place}{said}" in err and "job 0" not in err, err
        else:  # written in the job: that job, the key as written
            assert f"{place}{said.removeprefix('[defaults] ')}" in err, err
        assert not (tmp_path / "gaze.usdc").exists() and not list(tmp_path.glob("*.summary.json"))


def test_a_defaults_value_that_clashes_with_a_jobs_own_names_both(tmp_path):
    """A check of several keys at once (bind with forward, sublayer_into with preview) names the job and
    says which of its values came from [defaults]."""
    path = _manifest(tmp_path, 'shifts = ["1s:10:0"]\npreview = "p.usda"\n')
    path.write_text('[defaults]\nbind = ["skull=j5"]\nsublayer_into = "s.usda"\n\n' + path.read_text())
    with pytest.raises(UsdGazeError) as info:
        load_manifest(path)
    assert f"{path}: job 0 'w': [defaults] " in str(info.value), info.value


def test_good_plot_and_skel_root_pass(tmp_path):
    shot, = load_manifest(_manifest(tmp_path, 'shifts = ["1s:10:0:weight=0.5"]\nplot = "g.PNG"\nskel_root = "/Body"\n'))
    assert shot.values["skel_root"] == "/Body" and shot.values["plot"].endswith("g.PNG")


class _SecondSignalAtExit(Outputs):
    """A SIGTERM whose handler runs as ``__exit__`` begins, while SIGINT's Interrupted unwinds: what a
    pool worker sees on Ctrl-C (the terminal's SIGINT, then the parent's SIGTERM)."""

    def __exit__(self, *exc):
        signal.getsignal(signal.SIGTERM)(signal.SIGTERM, None)
        return super().__exit__(*exc)


def test_second_signal_while_interrupted_leaves_no_temporaries(tmp_path):
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    with pytest.raises(Interrupted) as info:
        with _SecondSignalAtExit() as tx:
            tx.claim(tmp_path / "gaze.usda", "--out")
            tx.stage_text(tmp_path / "gaze.usda", "#usda 1.0\n")
            signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
    assert info.value.signum == signal.SIGINT
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(TMP_PREFIX)] == []
    assert not (tmp_path / "gaze.usda").exists()
    assert {sig: signal.getsignal(sig) for sig in before} == before


def test_a_pool_worker_ends_once_a_stop_signal_interrupted_its_shot(monkeypatch):
    """The pool handed a worker whose shot a stop signal interrupted the next queued shot: 2-3 more
    shots ran after a Ctrl-C. The worker now ends there, with the signal's exit status."""
    import multiprocessing

    from usdgaze.batch import engine

    def interrupted(shot, force=False, limit=False):
        raise Interrupted(signal.SIGINT)

    monkeypatch.setattr(engine, "run_shot", interrupted)
    worker = multiprocessing.get_context("fork").Process(target=engine._pool_shot, args=(None, False))
    worker.start()
    worker.join(30)
    assert worker.exitcode == 128 + signal.SIGINT


def _run_refused(manifest, capsys, names: str) -> None:
    """``batch MANIFEST`` refuses in one line naming ``names``, exit 2, before any shot: no output
    folder, no summary."""
    from usdgaze.console.main import main

    capsys.readouterr()
    assert main(["batch", str(manifest)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and names in err, err
    folder = manifest.parent
    assert not (folder / "out").exists() and not list(folder.glob("*.summary.json"))


def test_a_shot_composing_another_shots_output_is_refused_before_that_output_exists(tmp_path, capsys):
    """Shot b's input sublayers shot a's output. Once a had run that was refused as a clash, but on
    the first run (the layer not there yet) both ran: b composed a's output or not depending on the
    order (or raced it on a farm), and the rerun then refused the manifest it had just run."""
    from . import synthetic as syn

    syn.make_rig(tmp_path / "rig.usda", frames=48)
    (tmp_path / "wrap.usda").write_text('#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n'
                                        '    subLayers = [@./out/a.usdc@, @./rig.usda@]\n)\n')
    manifest = tmp_path / "m.toml"
    manifest.write_text('[defaults]\nshifts = ["0.2s:30:0"]\n'
                        '[[job]]\nname = "a"\ninput = "rig.usda"\nout = "out/a.usdc"\n'
                        '[[job]]\nname = "b"\ninput = "wrap.usda"\nout = "out/b.usdc"\n')
    _refused_naming(manifest, str(tmp_path / "out" / "a.usdc"), "job 0 'a' out", "job 1 'b'")
    _run_refused(manifest, capsys, "job 1 'b'")


def test_a_shot_whose_map_composes_another_shots_output_is_refused(tmp_path, capsys):
    """Shot b's map file sublayers shot a's output. The input's layers were checked, the map's only as
    its one file: both shots ran, and b's map composed a's override or, run first (a pool, a farm),
    failed on it missing ('composition failed: Could not load sublayer'), by the order they ran in."""
    from . import synthetic as syn

    syn.make_rig(tmp_path / "rig.usda", frames=48)
    syn.make_rig(tmp_path / "rig2.usda", frames=48)
    (tmp_path / "map.usda").write_text('#usda 1.0\n(\n    subLayers = [@./out/a.usda@]\n)\n')
    manifest = tmp_path / "m.toml"
    manifest.write_text('[defaults]\nshifts = ["0.2s:30:0"]\n'
                        '[[job]]\nname = "a"\ninput = "rig.usda"\nout = "out/a.usda"\n'
                        '[[job]]\nname = "b"\ninput = "rig2.usda"\nout = "out/b.usdc"\nmap = "map.usda:/GazeMap"\n')
    _refused_naming(manifest, str(tmp_path / "out" / "a.usda"), "job 0 'a' out", "map of job 1 'b'")
    _run_refused(manifest, capsys, "job 1 'b'")


def test_an_output_folder_name_too_long_is_bad_input(tmp_path, capsys):
    """A folder name over the file system's 255 bytes: pathlib's exists()/is_dir() raise for it (they
    swallow only 'no such file'), and the shot was an internal error (exit 1: 'OSError: [Errno 36]')."""
    from usdgaze.console.main import main

    from . import synthetic as syn

    syn.make_rig(tmp_path / "rig.usda", frames=48)
    long = "f" * 300
    manifest = tmp_path / "m.toml"
    manifest.write_text(f'[defaults]\ninput = "rig.usda"\nshifts = ["0.2s:30:0"]\n'
                        f'[[job]]\nname = "long"\nout = "{long}/a.usdc"\n'
                        '[[job]]\nname = "fine"\nout = "out/b.usdc"\n')
    assert main(["batch", str(manifest)]) == 2
    shots = {r["name"]: r for r in json.loads((tmp_path / "m.summary.json").read_text())["shots"]}
    assert shots["long"]["status"] == "bad input" and shots["fine"]["status"] == "done"
    assert os.strerror(errno.ENAMETOOLONG) in shots["long"]["message"], shots["long"]["message"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.summary.json", "m.toml", "out", "rig.usda"]  # no temporaries
    capsys.readouterr()
    assert main(["apply", str(tmp_path / "rig.usda"), "--out", str(tmp_path / long / "a.usdc"), "--shift", "0.2s:30:0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "internal error" not in err, err


def _symlinked_input(tmp_path):
    """shots/a.usda links to assets/a.usda, whose sublayers are relative: USD finds them beside the
    link (shots/), not beside the file it links to."""
    from . import synthetic as syn

    (tmp_path / "assets").mkdir()
    (tmp_path / "shots").mkdir()
    syn.make_rig(tmp_path / "shots" / "anim.usda", frames=48)
    (tmp_path / "assets" / "a.usda").write_text('#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n'
                                                '    subLayers = [@./gaze.usda@, @./anim.usda@]\n)\n')
    (tmp_path / "shots" / "a.usda").symlink_to("../assets/a.usda")
    manifest = tmp_path / "m.toml"
    job_a = '[defaults]\nshifts = ["0.2s:30:0"]\n[[job]]\nname = "a"\ninput = "shots/a.usda"\nout = "out/a.usdc"\n'
    return manifest, job_a + '[[job]]\nname = "b"\ninput = "shots/anim.usda"\n'


def test_a_symlinked_inputs_layers_are_found_where_usd_finds_them(tmp_path):
    """The check resolved the link first and looked for the sublayers in assets/: job b writing the
    shots/gaze.usda that job a composes ran (a read it half-made on a farm), while b writing
    assets/anim.usda, which a does not compose, was refused."""
    manifest, jobs = _symlinked_input(tmp_path)
    manifest.write_text(jobs + 'out = "shots/gaze.usda"\n')
    _refused_naming(manifest, str(tmp_path / "shots" / "gaze.usda"), "job 1 'b' out", "job 0 'a'")
    manifest.write_text(jobs + 'out = "assets/anim.usda"\n')
    assert [s.name for s in load_manifest(manifest)] == ["a", "b"]


@pytest.mark.parametrize("table", ["job", "defaults"])
def test_a_value_refused_as_the_shot_runs_names_the_job_and_key(tmp_path, capsys, table):
    """A shift after the animation's end is found only once the shot reads the animation: it was said
    with the CLI's flag (``--shift 9999:30:0 lies outside the animation``), which the manifest lacks."""
    from . import synthetic as syn

    syn.make_rig(tmp_path / "rig.usda", frames=48)
    shifts = 'shifts = ["9999:30:0"]\n'
    manifest = tmp_path / "m.toml"
    manifest.write_text(('[defaults]\n' + shifts if table == "defaults" else "")
                        + '[[job]]\nname = "w"\ninput = "rig.usda"\nout = "gaze.usdc"\n'
                        + (shifts if table == "job" else ""))
    assert main(["batch", str(manifest)]) == 2
    message = json.loads((tmp_path / "m.summary.json").read_text())["shots"][0]["message"]
    key = "[defaults] shifts" if table == "defaults" else "shifts"
    assert message.startswith(f"{manifest}: job 0 'w': "), message
    assert f"{key} 9999:30:0 lies outside the animation" in message and "--" not in message, message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.summary.json", "m.toml", "rig.usda"]


def _refused_naming(manifest, *words: str) -> None:
    """Loading ``manifest`` is refused in one line that starts with its path and names ``words``."""
    with pytest.raises(UsdGazeError) as info:
        load_manifest(manifest)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{manifest}: ")
    for word in words:
        assert word in message, (word, message)


@pytest.mark.parametrize("argv", [[], ["--task-index", "0"]])
def test_a_manifest_in_a_missing_folder_is_named_not_its_summary(tmp_path, capsys, argv):
    """A mistyped manifest folder was said as its default summary's folder missing
    ('.../m.summary.json: folder ... does not exist'): the manifest is named, as for a missing file."""
    manifest = tmp_path / "no folder" / "m.toml"
    capsys.readouterr()
    assert main(["batch", str(manifest), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"usdgaze: error: {manifest}: no such file"], err
    assert list(tmp_path.iterdir()) == []


def test_a_manifest_saved_with_a_byte_order_mark_reads_as_without(tmp_path):
    """Notepad and Excel's "UTF-8" save a byte-order mark first: the manifest was refused as "not valid
    TOML (Invalid statement (at line 1, column 1))" though it read right in any editor. It is read as
    the same text without the mark (the CSV sheets already were, utf-8-sig)."""
    path = _manifest(tmp_path, 'shifts = ["1s:10:0"]\n')
    plain = load_manifest(path)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert [s.values for s in load_manifest(path)] == [s.values for s in plain]
    (tmp_path / "bad.toml").write_bytes(b"\xef\xbb\xbf[[job]]\nname = \"\xe9\"\n")  # not UTF-8 after it
    with pytest.raises(UsdGazeError, match=r"bad.toml: not valid TOML \(not UTF-8 text"):
        load_manifest(tmp_path / "bad.toml")
