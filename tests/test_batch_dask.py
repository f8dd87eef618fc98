"""``usdgaze batch --dask``: every shot a task on a real dask.distributed LocalCluster (2 worker processes)."""

from __future__ import annotations

import os

import pytest
from distributed import Client, LocalCluster

from usdgaze.console.main import main

from .test_pipeline import THREE, _samples, _status, _summary, _tree


def test_shots_run_as_tasks_on_a_dask_cluster(tmp_path):
    manifest = _tree(tmp_path, THREE)
    # the dashboard on a free port: test processes side by side (pytest -n) would clash over 8787
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
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


def _server(answer: bytes | None):
    """A TCP server on a free port that answers every connection with ``answer`` and closes it, or
    (None) reads and never answers, as an HTTP port does a dask handshake."""
    import socket
    import threading

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(8)

    def serve() -> None:
        while True:
            try:
                conn, _ = sock.accept()
            except OSError:
                return
            if answer is not None:
                conn.sendall(answer)
                conn.close()

    threading.Thread(target=serve, daemon=True).start()
    return sock, f"tcp://127.0.0.1:{sock.getsockname()[1]}"


@pytest.mark.parametrize("answer", [None, b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4, "closed"])
def test_a_port_that_is_no_scheduler_is_one_line(tmp_path, capsys, monkeypatch, answer):
    """A closed port (it took distributed's default 30 s), bytes that are no dask protocol (exit 1, "MemoryError:
    Unable to allocate 3.07 EiB"), a port that never answers the handshake (the dashboard's HTTP: it hung)."""
    from usdgaze.batch import cluster

    monkeypatch.setattr(cluster, "DASK_CONNECT_S", 1)
    manifest = _tree(tmp_path, THREE)
    sock, address = _server(None if answer == "closed" else answer)
    if answer == "closed":
        sock.close()
    try:
        assert main(["batch", str(manifest), "--dask", address]) == 2
    finally:
        sock.close()
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"--dask {address}: cannot connect to a dask scheduler there" in err, err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


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
    with LocalCluster(n_workers=1, threads_per_worker=4, processes=False, dashboard_address=":0") as cluster, \
            Client(cluster):
        assert main(["batch", str(manifest), "--dask", cluster.scheduler_address]) == 0
    assert _status(_summary(manifest)) == {n: "done" for n, _, _ in jobs}
    assert (os.fstat(2).st_dev, os.fstat(2).st_ino) == (stderr.st_dev, stderr.st_ino)
    for n, i, s in jobs:
        apply(tmp_path / i, [s], tmp_path / f"{n}_direct.usdc")
        assert _samples(tmp_path / "out" / f"{n}.usdc") == _samples(tmp_path / f"{n}_direct.usdc")
