"""SIGTERM and SIGINT outside a writer's transaction (``console.main``): before anything is written,
one line and 128 + the signal; once the command's outputs are in place, nothing changes (exit 0).

Each signal is sent to the test process itself at a point the test chooses (a wrapped step of
``usdgaze.api``), so the timing is exact. Before, SIGTERM there killed the process without a word and
SIGINT came out as click's "aborted" (exit 2) or a traceback."""

from __future__ import annotations

import os
import signal

import pytest

from usdgaze import api
from usdgaze.console.main import main

from .bad_common import rig

SIGNALS = [signal.SIGTERM, signal.SIGINT]


def _apply(d) -> list[str]:
    return ["apply", str(rig(d).path), "--shift", "0.5s:30:0", "--out", str(d / "gaze.usdc")]


def _leftovers(d) -> list[str]:
    return sorted(p.name for p in d.iterdir() if p.name.startswith(".usdgaze-tmp"))


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_a_signal_before_the_writer_starts_is_one_line(tmp_path, monkeypatch, capsys, sig):
    argv = _apply(tmp_path)
    before = {s: signal.getsignal(s) for s in SIGNALS}

    def stop(*args, **kwargs):
        os.kill(os.getpid(), sig)

    monkeypatch.setattr(api, "check_request", stop)  # runs before the command claims its outputs
    code = main(argv)
    err = capsys.readouterr().err.splitlines()
    assert code == 128 + sig
    assert err == [f"usdgaze: error: interrupted by {signal.Signals(sig).name}; nothing was written"]
    assert not (tmp_path / "gaze.usdc").exists() and _leftovers(tmp_path) == []
    assert {s: signal.getsignal(s) for s in SIGNALS} == before  # main gives the process its handlers back


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_a_signal_once_the_outputs_are_written_changes_nothing(tmp_path, monkeypatch, capsys, sig):
    argv = _apply(tmp_path)
    written = api.apply

    def then_stop(*args, **kwargs):
        report = written(*args, **kwargs)  # its transaction has committed
        os.kill(os.getpid(), sig)
        return report

    monkeypatch.setattr(api, "apply", then_stop)
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 0
    assert "interrupted" not in captured.err and f"wrote {tmp_path / 'gaze.usdc'}" in captured.out
    assert (tmp_path / "gaze.usdc").stat().st_size > 0 and _leftovers(tmp_path) == []


def test_a_stop_landing_in_an_import_is_raised_once_the_import_is_done(tmp_path, monkeypatch):
    """Raised inside an import, USD's module loader could swallow it (the command went on and wrote its
    output) or leave a module half made: the writer's handler sends the signal again after it."""
    import sys
    import time

    from usdgaze.errors import Interrupted
    from usdgaze.files.transaction import Outputs

    (tmp_path / "stopped_midway.py").write_text(
        "import os, signal, time\nos.kill(os.getpid(), signal.SIGTERM)\nfor _ in range(20):\n    time.sleep(0.001)\n"
        "DONE = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(Interrupted):
        with Outputs():
            import stopped_midway  # noqa: F401
            time.sleep(5.0)  # the signal comes again here
    assert sys.modules["stopped_midway"].DONE  # the import ran to its end


_STOP_AT_IMPORT = '''
import os, signal, sys

class _Stop:
    """Sends this process SIGINT when the module named in STOP_AT_IMPORT is first looked for."""

    def find_spec(self, name, path=None, target=None):
        if name == os.environ["STOP_AT_IMPORT"]:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, _Stop())
'''


@pytest.mark.parametrize("module", ["pxr.Usd", "click"])
@pytest.mark.parametrize("form", ["python -m usdgaze", "console script"])
def test_ctrl_c_while_the_command_imports_is_one_line(tmp_path, module, form):
    """A Ctrl-C while the command is still importing (OpenUSD inside ``import usdgaze``, click after it,
    before the CLI sets its handlers) ends it as one arriving later does: 130 and one line, nothing
    written. It was Python's KeyboardInterrupt traceback (11-14 lines). The signal is sent from an
    import hook (a sitecustomize), so it lands inside that import on every run."""
    import subprocess
    import sys
    from pathlib import Path

    hooks = tmp_path / "hooks"
    hooks.mkdir()
    (hooks / "sitecustomize.py").write_text(_STOP_AT_IMPORT)
    (hooks / "usdgaze").write_text("import sys\nfrom usdgaze.console.main import entry\nsys.exit(entry())\n")
    repo = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ, STOP_AT_IMPORT=module,
               PYTHONPATH=os.pathsep.join([str(hooks), repo, os.environ.get("PYTHONPATH", "")]))
    work = tmp_path / "work"
    work.mkdir()
    command = ["-m", "usdgaze"] if form.startswith("python") else [str(hooks / "usdgaze")]
    # Ctrl-C as a terminal delivers it: a suite run in a background job inherits SIGINT ignored, and a
    # command that starts with it ignored keeps ignoring it (quiet_stops_while_starting).
    p = subprocess.run([sys.executable, *command, "build-map", "sheet.csv", "--out", "map.usda"], cwd=work,
                       env=env, capture_output=True, text=True, timeout=120,
                       preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert (p.returncode, p.stderr.splitlines()) == (130, ["usdgaze: error: interrupted by SIGINT; nothing was written"])
    assert list(work.iterdir()) == []



def test_nohup_keeps_sighup_ignored(tmp_path):
    """Under nohup (SIGHUP ignored) the command must outlive its terminal: neither the CLI's handlers
    nor the writer's may take SIGHUP over; where it is not ignored, the writer handles it."""
    from usdgaze.errors import UsdGazeError
    from usdgaze.files.transaction import Outputs

    seen = []

    def look(*args, **kwargs):  # the handler in place while a writer holds outputs
        with Outputs():
            handler = signal.getsignal(signal.SIGHUP)
            seen.append(handler if handler is signal.SIG_IGN else type(getattr(handler, "__self__", None)))
        raise UsdGazeError("stop here")

    saved = signal.getsignal(signal.SIGHUP)
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(api, "check_request", look)
            for disposition in (signal.SIG_IGN, signal.SIG_DFL):
                signal.signal(signal.SIGHUP, disposition)
                assert main(_apply(tmp_path)) == 2
                assert signal.getsignal(signal.SIGHUP) is disposition  # given back
    finally:
        signal.signal(signal.SIGHUP, saved)
    assert seen == [signal.SIG_IGN, Outputs]
