"""Local pool workers: a worker process that dies (the OOM killer's SIGKILL, a crash in C) fails its
own shot, and the other shots run and are summarized."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from . import synthetic as syn

_KILLED = """
import os, signal, sys
from usdgaze.batch import engine
from usdgaze.console.main import main

real = engine.run_shot

def run_shot(shot, force=False, limit=False):
    if shot.name == "boom":  # what the kernel's OOM killer does to a worker
        os.kill(os.getpid(), signal.SIGKILL)
    return real(shot, force, limit)

engine.run_shot = run_shot
sys.exit(main(["batch", sys.argv[1], "--workers", "2"]))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="patches the forked workers")
def test_a_killed_worker_fails_its_shot_and_the_others_run(tmp_path):
    """A SIGKILLed worker broke the process pool: the command ended with 'internal error:
    BrokenProcessPool', exit 1, no summary, and the shots not yet run never ran."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    names = ["a", "boom", "c", "d", "e"]
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[defaults]\ninput = "rig.usda"\nshifts = ["0.2s:30:0"]\n'
                        + "".join(f'[[job]]\nname = "{n}"\nout = "out/{n}.usdc"\n' for n in names))
    proc = subprocess.run([sys.executable, "-c", _KILLED, str(manifest)], capture_output=True, text=True,
                          timeout=300, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert proc.returncode == 1, proc.stderr  # an internal error: worth a retry
    summary = json.loads((tmp_path / "jobs.summary.json").read_text())
    status = {r["name"]: r["status"] for r in summary["shots"]}
    assert status == {"a": "done", "boom": "internal error", "c": "done", "d": "done", "e": "done"}, proc.stderr
    boom = next(r for r in summary["shots"] if r["name"] == "boom")
    assert "worker process" in boom["message"] and boom["exit_code"] == 1
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [f"{n}.usdc" for n in names if n != "boom"]
    lines = [line for line in proc.stderr.splitlines() if line.startswith("[")]
    assert len(lines) == len(names) and sum("boom" in line for line in lines) == 1, proc.stderr


def test_a_dask_task_whose_worker_dies_fails_its_shot_and_the_others_run(tmp_path, monkeypatch):
    """A task whose worker died (each time: dask's KilledWorker) ended the command with that exception,
    exit 1, no summary, the other shots' results dropped."""
    import dask
    from distributed import LocalCluster

    from usdgaze.batch import engine
    from usdgaze.console.main import main

    syn.make_rig(tmp_path / "rig.usda", frames=48)
    names = ["a", "boom", "c"]
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[defaults]\ninput = "rig.usda"\nshifts = ["0.2s:30:0"]\n'
                        + "".join(f'[[job]]\nname = "{n}"\nout = "out/{n}.usdc"\n' for n in names))
    real = engine.run_shot

    def run_shot(shot, force=False, limit=False):  # sent to the workers by value (a local function)
        import os
        import signal

        if shot.name == "boom":  # what the nanny's memory limit or the OOM killer does to a worker
            os.kill(os.getpid(), signal.SIGKILL)
        return real(shot, force, limit)

    monkeypatch.setattr(engine, "run_shot", run_shot)
    # the dashboard on a free port: test processes side by side (pytest -n) would clash over 8787
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        assert main(["batch", str(manifest), "--dask", cluster.scheduler_address]) == 1
    summary = json.loads((tmp_path / "jobs.summary.json").read_text())
    assert {r["name"]: r["status"] for r in summary["shots"]} == {"a": "done", "boom": "internal error", "c": "done"}
    boom = next(r for r in summary["shots"] if r["name"] == "boom")
    assert "KilledWorker" in boom["message"] and "\n" not in boom["message"], boom["message"]
    # What the record says of itself only: "the other shots ran" was said too when a lost scheduler
    # failed every task left.
    assert boom["message"].endswith("written whole or not at all (a rerun redoes it unless all landed)"), boom["message"]
    assert not (tmp_path / "out" / "boom.usdc").exists()
