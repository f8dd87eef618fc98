"""Manifest paths a shell would have expanded, and a manifest whose folder cannot take the farm tasks'
summaries: one line, exit 2, nothing written (no folder named ``~`` or ``$SHOW``, no job files)."""

from __future__ import annotations

import errno
import os
import subprocess
from pathlib import Path

import pytest

from usdgaze.console.main import main

from . import synthetic as syn
from .bad_common import can_mount, tmpfs, unmount_all


def _write(tmp_path: Path, job: str) -> Path:
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    manifest = tmp_path / "m.toml"
    manifest.write_text(f'[[job]]\nname = "a"\nshifts = ["0.2s:30:0"]\n{job}')
    return manifest


def _tree(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("job, key, written", [
    ('input = "rig.usda"\nout = "~/gaze/a.usdc"\n', "out", "~/gaze/a.usdc"),
    ('input = "rig.usda"\nout = "$SHOW/gaze/a.usdc"\n', "out", "$SHOW/gaze/a.usdc"),
    ('input = "rig.usda"\nout = "shots/${SEQ}/a.usdc"\n', "out", "shots/${SEQ}/a.usdc"),
    ('input = "rig.usda"\nout = "a.usdc"\npreview = "~shots/p.usda"\n', "preview", "~shots/p.usda"),
    ('input = "~/rig.usda"\nout = "a.usdc"\n', "input", "~/rig.usda"),
    ('input = "rig.usda"\nout = "a.usdc"\nmap = "$MAPS/studio.usda:/GazeMap"\n', "map", "$MAPS/studio.usda"),
])
def test_a_path_a_shell_would_expand_is_refused_not_made_a_folder(tmp_path, capsys, job, key, written):
    """TOML has no ``~`` or ``$VAR``, and usdgaze expands neither: ``out = "~/gaze/a.usdc"`` made a folder
    named ``~`` beside the manifest (and ``$SHOW`` one named ``$SHOW``), exit 0, the override nowhere the
    author looked for it. Refused up front, naming the job and the key."""
    manifest = _write(tmp_path, job)
    before = _tree(tmp_path)
    assert main(["batch", str(manifest)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"usdgaze: error: {manifest}: job 0 'a': {key} = '{written}'"), err
    assert "expand" in err[0], err
    assert _tree(tmp_path) == before  # no '~' or '$SHOW' folder, no summary, no override


def test_a_literal_dollar_or_tilde_inside_a_name_is_a_name(tmp_path):
    """Only what a shell expands is refused: a ``$`` not before a name, and a ``~`` not at the start."""
    manifest = _write(tmp_path, 'input = "rig.usda"\nout = "take$1/a~b.usdc"\n')
    assert main(["batch", str(manifest)]) == 0
    assert (tmp_path / "take$1" / "a~b.usdc").is_file()


@pytest.fixture
def read_only(tmp_path, monkeypatch):
    """Make a folder read-only once written: a read-only tmpfs where this machine can mount one, else
    creating anything in it fails with EROFS (as the read-only mount does)."""
    mounted = can_mount()

    def make(folder: Path, fill) -> None:
        if mounted:
            tmpfs(folder, size="1m")
            fill(folder)
            subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)
            return
        folder.mkdir()
        fill(folder)
        real_mkdir = Path.mkdir

        def mkdir(self, *args, **kwargs):
            if self.parent == folder:
                raise OSError(errno.EROFS, os.strerror(errno.EROFS))
            return real_mkdir(self, *args, **kwargs)
        monkeypatch.setattr(Path, "mkdir", mkdir)
    yield make
    if mounted:
        unmount_all()


@pytest.mark.parametrize("farm", ["slurm", "deadline", "opencue"])
def test_emit_refuses_a_manifest_whose_folder_cannot_take_the_tasks_summaries(tmp_path, capsys, read_only, farm):
    """Each emitted task writes ``<manifest>.task-I.summary.json`` beside the manifest, and refuses to run
    its shot when it cannot (exit 2). A manifest in a read-only folder (a published, locked show folder)
    was emitted without a word, and every farm task then failed. Refused as a missing input is: one
    line, no job files."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    folder = tmp_path / "locked"
    body = f'[[job]]\nname = "a"\ninput = "{tmp_path}/rig.usda"\nout = "{tmp_path}/out/a.usdc"\nshifts = ["0.2s:30:0"]\n'
    read_only(folder, lambda f: (f / "m.toml").write_text(body))
    manifest = folder / "m.toml"
    jobs = tmp_path / "jobs"
    assert main(["batch", str(manifest), "--emit", farm, str(jobs)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"usdgaze: error: {manifest}: "), err
    assert f"{folder}/m.task-0.summary.json" in err[0] and "no job files were written" in err[0], err
    assert not jobs.exists()
    assert _tree(folder) == ["m.toml"]


def test_a_run_whose_default_summary_cannot_be_written_says_how_to_name_another(tmp_path, capsys, read_only):
    """The default summary goes beside the manifest; where that folder is read-only the run is refused
    before any shot, and the line now says the way out (--summary), which the flag's help alone said."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    folder = tmp_path / "locked"
    body = f'[[job]]\nname = "a"\ninput = "{tmp_path}/rig.usda"\nout = "{tmp_path}/out/a.usdc"\nshifts = ["0.2s:30:0"]\n'
    read_only(folder, lambda f: (f / "m.toml").write_text(body))
    assert main(["batch", str(folder / "m.toml"), "--task-index", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{folder}/m.task-0.summary.json: cannot write into {folder}" in err[0], err
    assert "--summary" in err[0], err
    assert not (tmp_path / "out").exists()
    summary = tmp_path / "s.json"
    assert main(["batch", str(folder / "m.toml"), "--task-index", "0", "--summary", str(summary)]) == 0
    assert summary.is_file() and (tmp_path / "out" / "a.usdc").is_file()
