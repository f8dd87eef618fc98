"""Catalogue builders for what an outside-in audit of ``usdgaze batch`` found (2026-12-08): manifest paths
a shell would have expanded (a folder named ``~`` was made), and a manifest whose folder cannot take the
summaries (every emitted farm task failed on it)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from .bad_common import JOB, manifest, rig, tmpfs
from .bad_cases_files import MOUNTABLE


def _locked(d: Path, body: str) -> Path:
    """``d/ro/manifest.toml`` in a read-only folder (a read-only tmpfs where mounting works; else mode
    0555, or as root the runner's injected EROFS), its jobs reading ``d/in.usda``."""
    rig(d)
    folder = d / "ro"
    if MOUNTABLE:
        tmpfs(folder, size="64k")
    else:
        folder.mkdir()
    (folder / "manifest.toml").write_text(body)
    if MOUNTABLE:
        subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)
    elif os.geteuid() == 0:
        (folder / ".inject-erofs").write_text("")
    else:
        os.chmod(folder, 0o555)
    return folder / "manifest.toml"


_LOCKED_JOB = '[[job]]\ninput = "../in.usda"\nout = "../gaze.usdc"\nshifts = ["0.5s:30:0"]\n'


def b_batch_out_with_a_tilde(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "~/gaze/gaze.usdc"\nshifts = ["0.5s:30:0"]\n')


def b_batch_path_with_an_environment_variable(d):
    return manifest(d, f'[defaults]\nmap = "$MAPS/studio.usda:/GazeMap"\n[[job]]\n{JOB}')


def b_batch_emit_manifest_in_a_read_only_folder(d):
    return ["batch", str(_locked(d, _LOCKED_JOB)), "--emit", "slurm", str(d / "jobs")]


def b_batch_default_summary_in_a_read_only_folder(d):
    return ["batch", str(_locked(d, _LOCKED_JOB))]


def b_batch_map_composes_a_later_out(d):
    (d / "map.usda").write_text('#usda 1.0\n(\n    subLayers = [@./out/a.usda@]\n)\n')
    (d / "out").mkdir()
    return manifest(d, '[defaults]\nshifts = ["0.5s:30:0"]\n[[job]]\nname = "a"\ninput = "in.usda"\nout = "out/a.usda"\n'
                       '[[job]]\nname = "b"\ninput = "in.usda"\nout = "out/b.usdc"\nmap = "map.usda:/GazeMap"\n')


def b_batch_task_of_an_edited_manifest(d):
    """An emitted task (its ``--manifest-jobs`` digest) of a manifest a job was inserted into since."""
    jobs = "".join(f'[[job]]\nname = "{n}"\ninput = "in.usda"\nout = "{n}.usdc"\nshifts = ["0.5s:30:0"]\n' for n in "axb")
    return manifest(d, jobs, "--manifest-jobs", "0000000000000000", "--task-index", "1")
