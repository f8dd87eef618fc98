"""``usdgaze batch --dask``: every shot a task on a real dask.distributed LocalCluster (2 worker processes)."""

from __future__ import annotations

import os

from distributed import Client, LocalCluster

from usdgaze.console.main import main

from .test_pipeline import THREE, _samples, _status, _summary, _tree


def test_shots_run_as_tasks_on_a_dask_cluster(tmp_path):
    manifest = _tree(tmp_path, THREE)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        pids = {f"{host}:{pid}" for host, pid in
                ((os.uname().nodename, p) for p in client.run(os.getpid).values())}
        assert main(["batch", str(manifest), "--dask", cluster.scheduler_address]) == 2
        summary = _summary(manifest)
        assert _status(summary) == {"shot": "done", "walk2": "done", "bad": "bad input"}
        assert summary["mode"] == f"dask {cluster.scheduler_address}"
        assert {r["worker"] for r in summary["shots"]} <= pids  # ran in the cluster's worker processes
        assert main(["batch", str(manifest), "--dask", cluster.scheduler_address]) == 2
        assert _status(_summary(manifest)) == {"shot": "skipped", "walk2": "skipped", "bad": "bad input"}

    from usdgaze.api import apply
    from usdgaze.passes.shift import PassOptions

    apply(tmp_path / "walk2.usdc", ["1.5s:-45:10"], tmp_path / "direct.usdc", options=PassOptions(fixation_m=2.0))
    assert _samples(tmp_path / "out" / "walk2.usdc") == _samples(tmp_path / "direct.usdc")


def test_unreachable_scheduler_is_one_line(tmp_path, capsys):
    import dask

    manifest = _tree(tmp_path, THREE)
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        assert main(["batch", str(manifest), "--dask", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "tcp://127.0.0.1:9" in err


def test_a_worker_running_shots_on_several_threads_writes_what_one_thread_does(tmp_path):
    # A TD's dask-worker runs tasks on threads: the shots share one process (its layer registry,
    # the map cache, file descriptor 2 while a stage opens) and must still write the same layers.
    from usdgaze.api import apply

    jobs = [(f"s{k}", f"w{k}.usdc", f"{1.0 + 0.25 * k:g}s:{20 + 10 * k}:{5 - 5 * k}") for k in range(4)]
    manifest = _tree(tmp_path, "".join(f'[[job]]\nname = "{n}"\ninput = "{i}"\nout = "out/{n}.usdc"\nshifts = ["{s}"]\n'
                                       for n, i, s in jobs))
    for k, (_, name, _) in enumerate(jobs):
        (tmp_path / name).write_bytes((tmp_path / ("walk2.usdc" if k % 2 else "walk1.usdc")).read_bytes())
    stderr = os.fstat(2)
    with LocalCluster(n_workers=1, threads_per_worker=4, processes=False, dashboard_address=None) as cluster, \
            Client(cluster):
        assert main(["batch", str(manifest), "--dask", cluster.scheduler_address]) == 0
    assert _status(_summary(manifest)) == {n: "done" for n, _, _ in jobs}
    assert (os.fstat(2).st_dev, os.fstat(2).st_ino) == (stderr.st_dev, stderr.st_ino)
    for n, i, s in jobs:
        apply(tmp_path / i, [s], tmp_path / f"{n}_direct.usdc")
        assert _samples(tmp_path / "out" / f"{n}.usdc") == _samples(tmp_path / f"{n}_direct.usdc")
