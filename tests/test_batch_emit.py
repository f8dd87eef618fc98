"""``usdgaze batch --emit``: the farm's tasks read the manifest the command was given, at its path."""

from __future__ import annotations

import shlex

from usdgaze.batch.manifest import load_manifest
from usdgaze.console.main import main

from . import synthetic as syn


def test_emitted_jobs_name_a_symlinked_manifest_where_it_was_given(tmp_path):
    """A manifest's paths are relative to its folder as given (a symlinked manifest: the link's folder,
    as a local run reads them). --emit resolved the link, so every farm task read the manifest's paths
    against the real file's folder: 'no such file' on each task (or other files of the same names),
    while --emit's own check had found them all."""
    (tmp_path / "jobs").mkdir()
    (tmp_path / "show").mkdir()
    syn.make_rig(tmp_path / "jobs" / "rig.usda", frames=48)
    (tmp_path / "show" / "seq.toml").write_text('[[job]]\nname = "a"\ninput = "rig.usda"\nout = "out/a.usdc"\n'
                                                'shifts = ["0.2s:30:0"]\n')
    given = tmp_path / "jobs" / "current.toml"
    given.symlink_to("../show/seq.toml")
    assert main(["batch", str(given), "--emit", "slurm", str(tmp_path / "slurm")]) == 0
    assert main(["batch", str(given), "--emit", "deadline", str(tmp_path / "deadline")]) == 0
    line = next(l for l in (tmp_path / "slurm" / "usdgaze.sbatch").read_text().splitlines() if l.startswith("exec "))
    argv = shlex.split(line)
    emitted = argv[argv.index("batch") + 1]
    assert [s.values["input"] for s in load_manifest(emitted)] == [s.values["input"] for s in load_manifest(given)]
    plugin = dict(l.split("=", 1) for l in (tmp_path / "deadline" / "plugin_info.job").read_text().splitlines() if l)
    assert f"<QUOTE>{emitted}<QUOTE>" in plugin["Arguments"]
