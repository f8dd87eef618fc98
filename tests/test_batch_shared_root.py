"""Two commands inserting their overrides into one shot layer at once (two manifests' shots of one shot
on a farm, or a batch beside an ``apply --sublayer-into``): each reads the root, adds its sublayer and
renames the edit into place, so without a lock the later rename dropped the other's sublayer."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

from pxr import Sdf

from . import synthetic as syn

# Each process waits before its renames: what a slow disk (the override's fsync) or a loaded node does.
# The two started together have then both read the root before either replaced it.
_DRIVER = textwrap.dedent("""
    import sys, time
    from usdgaze.files import transaction

    commit = transaction.Outputs.commit

    def slow_commit(self):
        time.sleep(float(sys.argv[1]))
        commit(self)

    transaction.Outputs.commit = slow_commit
    from usdgaze.console.main import main
    sys.exit(main(sys.argv[2:]))
""")


def _manifest(folder: Path, name: str, yaw: int) -> Path:
    path = folder / f"{name}.toml"
    path.write_text(f'[[job]]\nname = "{name}"\ninput = "rig.usda"\nout = "gaze_{name}.usdc"\n'
                    f'sublayer_into = "shot.usda"\nshifts = ["0.2s:{yaw}:0"]\n')
    return path


def test_two_batches_inserting_into_one_shot_layer_keep_both_sublayers(tmp_path):
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths.append("./rig.usda")
    shot.Save()
    driver = tmp_path / "driver.py"
    driver.write_text(_DRIVER)
    manifests = [_manifest(tmp_path, "a", 30), _manifest(tmp_path, "b", -30)]
    procs = [subprocess.Popen([sys.executable, str(driver), "2.0", "batch", str(m)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for m in manifests]
    for p in procs:
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, err
    assert (tmp_path / "gaze_a.usdc").is_file() and (tmp_path / "gaze_b.usdc").is_file()
    edited = Sdf.Layer.OpenAsAnonymous(str(tmp_path / "shot.usda"))
    listed = sorted(edited.subLayerPaths)
    assert listed == ["./gaze_a.usdc", "./gaze_b.usdc", "./rig.usda"], listed
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".usdgaze")]


def test_a_stop_signal_while_waiting_for_the_shot_layer_leaves_nothing(tmp_path):
    """A command waiting for another's edit of the shot layer to finish is stopped like any other: exit
    143, no override, no temporaries, the shot layer's bytes as they were."""
    import fcntl
    import os
    import signal
    import time

    syn.make_rig(tmp_path / "rig.usda", frames=48)
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths.append("./rig.usda")
    shot.Save()
    before = (tmp_path / "shot.usda").read_bytes()
    manifest = _manifest(tmp_path, "a", 30)
    fd = os.open(tmp_path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # another command's edit in progress
        p = subprocess.Popen([sys.executable, "-m", "usdgaze", "batch", str(manifest)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not any(q.name.startswith(".usdgaze-tmp") for q in tmp_path.iterdir()):
            time.sleep(0.05)
        time.sleep(1.0)  # past the staging of its override: at the lock
        assert p.poll() is None, p.communicate()
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    finally:
        os.close(fd)
    assert p.returncode == 128 + signal.SIGTERM, err
    assert "interrupted by SIGTERM" in err
    assert (tmp_path / "shot.usda").read_bytes() == before
    assert not (tmp_path / "gaze_a.usdc").exists()
    assert not [q.name for q in tmp_path.iterdir() if q.name.startswith(".usdgaze")]


def _two_characters(tmp_path: Path) -> None:
    """shot.usda: two characters (/Hero, /Extra), each from its own layer, sublayered together."""
    syn.make_rig(tmp_path / "hero.usda", frames=48, root_path="/Hero")
    syn.make_rig(tmp_path / "extra.usda", frames=48, root_path="/Extra")
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths[:] = ["./hero.usda", "./extra.usda"]
    shot.Save()


def _job(tmp_path: Path, name: str, source: str, out: str) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(f'[[job]]\nname = "{name}"\ninput = "{source}"\nout = "{out}"\nsublayer_into = "shot.usda"\n'
                    'shifts = ["0.2s:30:0"]\n')
    return path


def _statuses(capsys) -> str:
    return capsys.readouterr().out.split(": ", 1)[1]


def test_two_manifests_sharing_a_shot_layer_skip_their_shots_on_a_rerun(tmp_path, capsys):
    """Each manifest's override goes first in the shot layer, so the other one's is then second. A rerun
    redid a shot whose override was not first, moving it first, and the other manifest's rerun did the
    same: neither ever skipped. Below another character's override it is what it was: skipped."""
    from usdgaze.console.main import main

    _two_characters(tmp_path)
    hero, extra = _job(tmp_path, "hero", "hero.usda", "gaze_hero.usdc"), _job(tmp_path, "extra", "extra.usda", "gaze_extra.usdc")
    assert main(["batch", str(hero)]) == 0 and main(["batch", str(extra)]) == 0
    capsys.readouterr()
    before = (tmp_path / "shot.usda").read_bytes()
    for manifest in (hero, extra, hero):
        assert main(["batch", str(manifest)]) == 0
        assert _statuses(capsys).startswith("1 skipped;"), manifest
    assert (tmp_path / "shot.usda").read_bytes() == before


def test_an_override_hidden_by_another_of_the_same_character_is_redone(tmp_path, capsys):
    """Another override of the same character above ours (an earlier take under another name, inserted
    since) hides our animation: that shot is not complete, and its rerun puts it first again."""
    from usdgaze.console.main import main

    _two_characters(tmp_path)
    ours, other = _job(tmp_path, "ours", "hero.usda", "gaze_ours.usdc"), _job(tmp_path, "take", "hero.usda", "gaze_take.usdc")
    assert main(["batch", str(ours)]) == 0 and main(["batch", str(other)]) == 0
    capsys.readouterr()
    assert main(["batch", str(ours)]) == 0
    assert _statuses(capsys).startswith("1 done;")
    edited = Sdf.Layer.OpenAsAnonymous(str(tmp_path / "shot.usda"))
    assert list(edited.subLayerPaths)[0] == "./gaze_ours.usdc"


def test_a_folder_locked_twice_by_one_command_does_not_wait_for_itself(tmp_path):
    """A lock is per descriptor: taken again on another one by the same command it would wait for ever."""
    import threading

    from usdgaze.files.transaction import Outputs

    done = threading.Event()

    def twice() -> None:
        with Outputs() as tx:
            tx.lock(tmp_path)
            tx.lock(tmp_path / ".")
        done.set()

    worker = threading.Thread(target=twice, daemon=True)
    worker.start()
    assert done.wait(10), "the second lock waited for the first"
