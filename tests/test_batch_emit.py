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


def test_emit_takes_force_into_every_task_and_refuses_the_flags_of_a_run(tmp_path, capsys):
    """--force reaches the emitted tasks' commands; --workers, --dask and --summary, which only a run
    uses, were dropped without a word and are now refused in one line (nothing written)."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[[job]]\nname = "a"\ninput = "rig.usda"\nout = "out/a.usdc"\nshifts = ["0.2s:30:0"]\n')
    assert main(["batch", str(manifest), "--emit", "slurm", str(tmp_path / "forced"), "--force"]) == 0
    line = next(l for l in (tmp_path / "forced" / "usdgaze.sbatch").read_text().splitlines() if l.startswith("exec "))
    argv = shlex.split(line)
    assert "--force" in argv[argv.index("batch"):]
    assert main(["batch", str(manifest), "--emit", "slurm", str(tmp_path / "plain")]) == 0
    plain = next(l for l in (tmp_path / "plain" / "usdgaze.sbatch").read_text().splitlines() if l.startswith("exec "))
    assert "--force" not in shlex.split(plain)
    capsys.readouterr()
    for flags in (["--workers", "2"], ["--summary", str(tmp_path / "s.json")], ["--dask", "tcp://127.0.0.1:1"]):
        folder = tmp_path / flags[0].strip("-")
        assert main(["batch", str(manifest), "--emit", "deadline", str(folder), *flags]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and flags[0] in err[0] and "--emit" in err[0], err
        assert not folder.exists() and not (tmp_path / "s.json").exists()
