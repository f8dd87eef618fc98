"""``usdgaze batch --emit``: the farm's tasks read the manifest the command was given, at its path,
and ask for the cores its shots need; what a farm task says of its one shot; the farm recipes' usage."""

from __future__ import annotations

import os
import shlex
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

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


ROOT = Path(__file__).resolve().parents[1]


def _emitted(manifest: Path, folder: Path) -> tuple[list[str], str, dict]:
    """The SLURM script's lines, the OpenCue layer's <cores> and the Deadline job info of ``manifest``."""
    for farm in ("slurm", "opencue", "deadline"):
        assert main(["batch", str(manifest), "--emit", farm, str(folder / farm)]) == 0
    slurm = (folder / "slurm" / "usdgaze.sbatch").read_text().splitlines()
    cores = ET.parse(next((folder / "opencue").glob("*.xml"))).getroot().find("job/layers/layer/cores").text
    job = dict(l.split("=", 1) for l in (folder / "deadline" / "job_info.job").read_text().splitlines() if l)
    return slurm, cores, job


def test_emitted_jobs_ask_for_the_cores_of_the_shot_with_the_most_threads(tmp_path):
    """The shipped attend manifest's catch shot sets threads = 2, yet SLURM was asked for
    --cpus-per-task=1 and OpenCue for 1 core: two MuJoCo threads on one core. An array job has one
    request for all its tasks, so it is the most threads any shot sets, and the file says why."""
    slurm, cores, job = _emitted(ROOT / "pipeline" / "manifests" / "attend_shots.toml", tmp_path / "attend")
    assert "#SBATCH --cpus-per-task=2" in slurm and "#SBATCH --cpus-per-task=1" not in slurm
    assert any(l.startswith("# --cpus-per-task:") and "most threads" in l for l in slurm), slurm
    first = next(i for i, l in enumerate(slurm) if not l.startswith("#"))  # sbatch reads directives up to here
    assert slurm.index("#SBATCH --cpus-per-task=2") < first
    assert cores == "2"
    assert job["ConcurrentTasks"] == "1" and "(3 shots), each up to 2 threads" in job["Comment"], job

    syn.make_rig(tmp_path / "rig.usda", frames=48)  # no shot sets threads: one core, one shot said so
    manifest = tmp_path / "one.toml"
    manifest.write_text('[[job]]\nname = "a"\ninput = "rig.usda"\nout = "out/a.usdc"\nshifts = ["0.2s:30:0"]\n')
    slurm, cores, job = _emitted(manifest, tmp_path / "one")
    assert "#SBATCH --cpus-per-task=1" in slurm and cores == "1"
    # ... and half an hour a task, where the attend manifest's physics shots get four hours (the whole
    # stones sample simulates 33 CPU minutes; every task was asked 30 minutes, and a farm kills it there)
    assert "#SBATCH --time=00:30:00" in slurm
    attend, _, _ = _emitted(ROOT / "pipeline" / "manifests" / "attend_shots.toml", tmp_path / "attend_again")
    assert "#SBATCH --time=04:00:00" in attend and "#SBATCH --time=00:30:00" not in attend
    assert any("(1 shot)" in l for l in slurm) and "(1 shot), each up to 1 thread" in job["Comment"], job


def test_a_run_of_one_shot_says_shot_not_shots(tmp_path, capsys):
    """'1 shots in 0.42 s': every farm task (--task-index) runs one shot and said it in the plural."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[[job]]\nname = "a"\ninput = "rig.usda"\nout = "out/a.usdc"\nshifts = ["0.2s:30:0"]\n'
                        '[[job]]\nname = "b"\ninput = "rig.usda"\nout = "out/b.usdc"\nshifts = ["0.2s:-30:0"]\n')
    capsys.readouterr()
    assert main(["batch", str(manifest), "--task-index", "1"]) == 0
    assert capsys.readouterr().out.startswith("1 shot in "), "one task, one shot"
    assert main(["batch", str(manifest)]) == 0
    assert capsys.readouterr().out.startswith("2 shots in ")


@pytest.mark.parametrize("script, args, usage", [
    ("array_task.sh", [], "usage: array_task.sh MANIFEST INDEX"),
    ("array_task.sh", ["jobs.toml"], "usage: array_task.sh MANIFEST INDEX"),
    ("slurm.sbatch", [], "usage: sbatch --array="),
])
def test_farm_recipes_without_their_arguments_say_their_usage_and_exit_2(script, args, usage):
    """array_task.sh under ``set -u`` read a missing $1 first: bash's 'unbound variable' and exit 1,
    which a farm retries as an internal error; its usage line was never reached. A missing argument is
    bad input: the usage line and exit 2 (no retry), nothing run."""
    env = {k: v for k, v in os.environ.items() if k != "SLURM_ARRAY_TASK_ID"}
    proc = subprocess.run(["bash", str(ROOT / "pipeline" / "farm" / script), *args], capture_output=True,
                          text=True, timeout=60, env={**env, "USDGAZE": "false"})  # never reached
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()] and proc.stderr.startswith(usage), proc.stderr
    assert "unbound" not in proc.stderr and proc.stdout == ""


@pytest.mark.parametrize("folder_name, farms", [
    ("m\necho INJECTED\n", ("slurm", "deadline", "opencue")),  # a line break in a folder's name
    ("take \"7\"", ("deadline",)),  # a double quote: Deadline's <QUOTE> around the manifest ends there
])
def test_a_manifest_path_the_job_files_cannot_carry_is_refused_and_nothing_written(tmp_path, capsys, folder_name,
                                                                                  farms):
    """A line break in the manifest's path ended SLURM's comment line: the rest ran as a command
    (`echo INJECTED`), and sbatch ignored every #SBATCH line after it (bash -n: syntax error); it split
    Deadline's key=value lines. A double quote broke Deadline's quoted argument. One line, exit 2."""
    folder = tmp_path / folder_name
    folder.mkdir()
    (folder / "m.toml").write_text('[[job]]\ninput = "in.usda"\nout = "o.usdc"\nshifts = ["0.2s:30:0"]\n')
    (folder / "in.usda").write_text("#usda 1.0\n")
    for farm in farms:
        capsys.readouterr()
        assert main(["batch", str(folder / "m.toml"), "--emit", farm, str(tmp_path / farm)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "m.toml" in err[0] and "no job files were written" in err[0], err
        assert not (tmp_path / farm).exists()
    if "slurm" not in farms:  # the same folder is carried by SLURM's quoting, and the script parses
        assert main(["batch", str(folder / "m.toml"), "--emit", "slurm", str(tmp_path / "slurm")]) == 0
        script = tmp_path / "slurm" / "usdgaze.sbatch"
        assert subprocess.run(["bash", "-n", str(script)]).returncode == 0
        exec_line = next(l for l in script.read_text().splitlines() if l.startswith("exec "))
        assert shlex.split(exec_line)[3] == str(folder / "m.toml")


def test_more_shots_than_one_slurm_array_holds_go_in_several_arrays(tmp_path):
    """SLURM's default MaxArraySize (1001) caps an array's indices at 1000: a 1,200-shot manifest was
    emitted as --array=0-1199, which sbatch refuses ("Invalid job array specification"). Now a
    submit.sh submits arrays of at most 1001 tasks, each telling the script the shot of its task 0;
    run here with a recording sbatch, the arrays cover every shot once, and one task of the second
    array runs the shot it names (its layer, and no other, is written)."""
    syn.make_rig(tmp_path / "rig.usda", frames=24)
    count = 1200
    (tmp_path / "many.toml").write_text("".join(
        f'[[job]]\nname = "s{i}"\ninput = "rig.usda"\nout = "out/s{i}.usda"\nshifts = ["0.2s:{10 + i % 50}:0"]\n'
        for i in range(count)))
    folder = tmp_path / "slurm"
    assert main(["batch", str(tmp_path / "many.toml"), "--emit", "slurm", str(folder)]) == 0
    script = (folder / "usdgaze.sbatch").read_text()
    assert "#SBATCH --array=0-1000\n" in script, script
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "sbatch").write_text(f'#!/usr/bin/env bash\necho "$@" >> {tmp_path}/calls.txt\n')
    (bin_dir / "sbatch").chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}"}
    subprocess.run(["bash", str(folder / "submit.sh")], check=True, env=env, cwd=tmp_path)
    covered = []
    for call in (tmp_path / "calls.txt").read_text().splitlines():
        array, path, first = call.split()
        assert array.startswith("--array=0-") and Path(path) == folder / "usdgaze.sbatch", call
        size = int(array.rpartition("-")[2]) + 1
        assert size <= 1001, call
        covered += range(int(first), int(first) + size)
    assert covered == list(range(count))
    env["SLURM_ARRAY_TASK_ID"] = "3"
    done = subprocess.run(["bash", str(folder / "usdgaze.sbatch"), "1001"], env=env, cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in (tmp_path / "out").glob("*.usda")) == ["s1004.usda"]


def test_a_re_emit_with_fewer_shots_leaves_no_stale_submit_script(tmp_path):
    """Over 1,001 shots --emit slurm writes submit.sh; emitted again into the same folder for a manifest
    cut to 3 shots it wrote usdgaze.sbatch alone, and the old submit.sh still submitted 1,200 tasks: 197
    'out of range' failures and a second array re-running shots 0-198. submit.sh is now written every
    time, and submits what the manifest holds."""
    syn.make_rig(tmp_path / "rig.usda", frames=24)
    manifest = tmp_path / "many.toml"
    folder = tmp_path / "slurm"
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "sbatch").write_text(f'#!/usr/bin/env bash\necho "$@" >> {tmp_path}/calls.txt\n')
    (bin_dir / "sbatch").chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}"}
    for count in (1200, 3):
        manifest.write_text("".join(f'[[job]]\nname = "s{i}"\ninput = "rig.usda"\nout = "out/s{i}.usda"\n'
                                    f'shifts = ["0.2s:{10 + i % 50}:0"]\n' for i in range(count)))
        assert main(["batch", str(manifest), "--emit", "slurm", str(folder)]) == 0
    (tmp_path / "calls.txt").unlink(missing_ok=True)
    subprocess.run(["bash", str(folder / "submit.sh")], check=True, env=env, cwd=tmp_path)
    calls = (tmp_path / "calls.txt").read_text().splitlines()
    arrays = [c for c in calls if "--array" in c]
    submitted = [c.split() for c in calls]
    assert len(submitted) == 1 and Path(submitted[0][-1]) == folder / "usdgaze.sbatch", calls
    assert not arrays or arrays == [f"--array=0-2 {folder / 'usdgaze.sbatch'}"], calls
    assert "#SBATCH --array=0-2\n" in (folder / "usdgaze.sbatch").read_text()


def _task_command(folder: Path, index: int) -> list[str]:
    """What SLURM's array task ``index`` runs: the emitted script's exec line, its index filled in."""
    line = next(l for l in (folder / "usdgaze.sbatch").read_text().splitlines() if l.startswith("exec "))
    return shlex.split(line.removeprefix("exec ").replace('"$SLURM_ARRAY_TASK_ID"', str(index)))


def test_a_farm_task_of_a_manifest_edited_since_it_was_emitted_runs_nothing(tmp_path):
    """Job files run shot I by its index. A job inserted into the manifest after --emit (or two swapped)
    moved every later shot: task 2 ran what was shot 1, the last shot ran in no task, and every task
    exited 0. Now a task whose manifest lists other jobs than it was emitted for refuses in one line
    (exit 2, nothing written); a job's values edited in place still run (the resume key sees them)."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    manifest = tmp_path / "jobs.toml"

    def job(name: str, yaw: int) -> str:
        return f'[[job]]\nname = "{name}"\ninput = "rig.usda"\nout = "out/{name}.usdc"\nshifts = ["0.2s:{yaw}:0"]\n'

    manifest.write_text(job("a", 10) + job("b", 20) + job("c", 30))
    assert main(["batch", str(manifest), "--emit", "slurm", str(tmp_path / "slurm")]) == 0
    manifest.write_text(job("a", 10) + job("b", 25) + job("c", 30))  # a value edited in place: runs
    done = subprocess.run(_task_command(tmp_path / "slurm", 1), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["b.usdc"]
    manifest.write_text(job("a", 10) + job("x", 40) + job("b", 25) + job("c", 30))  # a job inserted
    for index in (1, 2):
        moved = subprocess.run(_task_command(tmp_path / "slurm", index), capture_output=True, text=True)
        err = moved.stderr.strip().splitlines()
        assert moved.returncode == 2 and len(err) == 1, moved.stderr
        assert err[0].startswith(f"usdgaze: error: {manifest}: ") and "re-emit" in err[0], err
        assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["b.usdc"]
    assert not (tmp_path / "jobs.task-2.summary.json").exists()
