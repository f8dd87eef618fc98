"""``attend --physics`` writes through the one writer: its output may not be the input or any layer
the input composes (compared by file identity, so a hard link or a second spelling is caught), and
the refusal is one line before any simulation, with every input's bytes and mode unchanged. An
interrupted simulation (SIGINT, one or two planner threads) exits 130 with one line and leaves the
folder as it was."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest
from pxr import Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import synthetic as syn
from .bad_common import CLI, snapshot
from .measure import sha256


def _shot(tmp_path):
    """A shot layer that sublayers the animation file, as studio shots do."""
    rig = syn.make_rig(tmp_path / "anim.usdc", frames=6, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths[:] = ["./anim.usdc"]
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(shot, key, getattr(src, key))
    shot.Save()
    return tmp_path / "shot.usda", tmp_path / "anim.usdc"


@pytest.mark.parametrize("target", ["sublayer", "hard link of the sublayer", "sublayer spelled otherwise"])
def test_physics_output_may_not_be_a_layer_the_input_reads(tmp_path, capsys, target):
    shot, anim = _shot(tmp_path)
    if target == "sublayer":
        out = anim
    elif target == "hard link of the sublayer":
        os.link(anim, tmp_path / "linked.usdc")
        out = tmp_path / "linked.usdc"
    else:
        (tmp_path / "sub").mkdir()
        out = tmp_path / "sub" / ".." / "anim.usdc"
    before = {p: (sha256(p), os.stat(p).st_mode) for p in (shot, anim)}
    assert main(["attend", str(shot), "--physics", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("usdgaze: error: "), err
    assert "composed by the input" in err[0], err
    assert {p: (sha256(p), os.stat(p).st_mode) for p in (shot, anim)} == before
    assert not [p for p in tmp_path.rglob("*") if ".usdgaze-tmp" in p.name]


@pytest.mark.parametrize("args, words", [
    (["--physics", "--alpha", "0.4"], "--alpha is not taken with --physics"),
    (["--physics", "--objects", "/Objects/Ball"], "--objects is not taken with --physics"),
    (["--threads", "2"], "--threads is an option of --physics"),
    (["--discard-failed"], "--discard-failed is an option of --physics"),
    (["--fd-reuse", "3"], "--fd-reuse is an option of --physics"),
    (["--mass", "60"], "--mass is an option of --physics"),
])
def test_an_option_of_the_other_mode_is_refused_not_ignored(tmp_path, capsys, args, words):
    shot, anim = _shot(tmp_path)
    out = tmp_path / "out.usdc"
    assert main(["attend", str(shot), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_physics_without_mujoco_installed_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch):
    import sys

    shot, _ = _shot(tmp_path)
    out = tmp_path / "out.usdc"
    monkeypatch.setitem(sys.modules, "mujoco", None)  # what `import mujoco` meets where it is not installed
    assert main(["attend", str(shot), "--physics", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["usdgaze: error: --physics needs MuJoCo: pip install 'usdgaze[physics]'"], err
    assert not out.exists()


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a running process, from /proc (Linux)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.parametrize("threads", [1, 2])
def test_sigint_while_simulating_leaves_nothing(tmp_path, threads):
    from .test_physics_pass import excerpt

    src = excerpt(tmp_path / "walk.usda", 1.0)
    before = snapshot(tmp_path)
    proc = subprocess.Popen([*CLI, "attend", str(src), "--physics", "--threads",
                             str(threads), "--out", str(tmp_path / "body.usdc")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Past the imports and the model build (about 1.5 CPU s): the planner is simulating.
    deadline = time.monotonic() + 120
    while proc.poll() is None and _cpu_seconds(proc.pid) < 3.0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "finished before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGINT, err
    assert err.splitlines() == ["usdgaze: error: interrupted by SIGINT; nothing was written"]
    assert snapshot(tmp_path) == before
