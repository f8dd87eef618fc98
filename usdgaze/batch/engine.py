"""Running shots: one shot never raises, a pool or a dask cluster runs many, results stream back.

Every shot is independent: a bad shot (exit 2) or a crash (exit 1) is reported with its one line and
the others complete. Workers use one BLAS thread each, and pool workers one USD work thread (see
``limit_threads``), so N workers on N cores do not oversubscribe them.
"""

from __future__ import annotations

import os
import signal
import socket
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Callable, Generator, Iterator

from usdgaze.batch.manifest import Shot, apply_kwargs, attend_kwargs
from usdgaze.batch.progress import step_lines
from usdgaze.files.signals import STOPS

DONE, SKIPPED, BAD, INTERNAL = "done", "skipped", "bad input", "internal error"
EXIT_CODES = {DONE: 0, SKIPPED: 0, BAD: 2, INTERNAL: 1}

_limited = False
STOP_GRACE_S = 10.0
"""How long a stopped pool worker has to clean up before it is killed."""
_STOP_SIGNALS = set(STOPS)


def limit_threads(forked: bool = False) -> None:
    """One BLAS thread for this process (once), and one USD work thread if it is a ``forked`` pool
    worker; freed memory kept for reuse.

    USD reads its plugins in parallel (``import usdgaze`` makes it), so unless its limit was 1 already
    (``PXR_WORK_THREAD_LIMIT=1``) TBB has started a worker thread by then, and lowering the limit later
    does not stop it: it spins (sched_yield) beside every crate write. Measured, a 1-worker batch of 20
    shots of 100 joints x 6,000 frames: 10.0 CPU s for 5.4 s of wall time with the limit lowered,
    4.9-5.3 for 4.6-5.0 s without. A forked process has no TBB worker (fork copies the calling thread
    only), so a forked pool worker lowers it before its first USD work; any other process keeps it.
    """
    global _limited
    if _limited:
        return
    from threadpoolctl import threadpool_limits
    from pxr import Work

    from usdgaze.process import tune_allocator

    tune_allocator()  # a dask worker runs shot after shot: see usdgaze.process

    threadpool_limits(limits=1)  # stays in force: the returned context is never exited
    if forked and Work.GetConcurrencyLimit() != 1:
        Work.SetConcurrencyLimit(1)
    _limited = True


def _outputs_complete(shot: Shot) -> bool:
    """The shot's files are all there (and its override is in its sublayer target, its preview
    composes its override and input)."""
    if not all(os.path.isfile(p) for p in shot.outputs()):
        return False
    root = shot.values.get("sublayer_into")
    if root:
        from usdgaze.usd.sublayers import sublayered

        return sublayered(root, shot.out, shot.values["input"])
    preview = shot.values.get("preview")
    return not preview or _previews(preview, shot.out, shot.values["input"])


def _previews(preview: str, out: str, source: str) -> bool:
    """``preview`` sublayers ``out`` and ``source``, as :func:`usdgaze.usd.layers.write_preview` writes
    it. The key hashes contents, not paths: an input moved elsewhere kept a preview of its old path."""
    from pxr import Sdf

    from usdgaze.files.identity import FileId

    try:
        layer = Sdf.Layer.OpenAsAnonymous(preview, metadataOnly=True)
    except Exception:  # an unreadable preview is simply written again
        return False
    if layer is None:
        return False
    folder = os.path.dirname(os.path.abspath(preview))  # where write_preview made the paths relative to
    named = [FileId.of(os.path.join(folder, p)) for p in layer.subLayerPaths]
    return named == [FileId.of(out), FileId.of(source)]


def run_shot(shot: Shot, force: bool = False, limit: bool = False) -> dict:
    """Run one shot (or skip it when its resume key matches its output's); never raises."""
    from usdgaze.batch.keys import KEY_FIELD, recorded_key, shot_key
    from usdgaze.errors import UsdGazeError

    if limit:
        limit_threads()
    start, cpu = time.perf_counter(), time.process_time()
    record = {"index": shot.index, "name": shot.name, "input": shot.values["input"], "out": shot.out,
              "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        key, opened = shot_key(shot)
        record["key"] = key
        if not force and recorded_key(shot.out) == key and _outputs_complete(shot):
            record.update(status=SKIPPED)
        else:
            record.update(status=DONE, **_run(shot, {KEY_FIELD: key}))
            del opened
    except UsdGazeError as exc:
        record.update(status=BAD, message=shot.said(str(exc)))
    except Exception as exc:  # a bug: report it and let the other shots run
        record.update(status=INTERNAL, message=f"{type(exc).__name__}: {' '.join(str(exc).split())}",
                      traceback=traceback.format_exc())
    record["exit_code"] = EXIT_CODES[record["status"]]
    record["seconds"] = round(time.perf_counter() - start, 4)
    record["cpu_seconds"] = round(time.process_time() - cpu, 4)  # this process's user + sys: load-proof
    return record


def _run(shot: Shot, key: dict) -> dict:
    """Run one shot's command; what its summary record says of the result."""
    if shot.command == "apply":
        from usdgaze.api import apply

        report = apply(**apply_kwargs(shot), record=key, make_folders=True)
        return {"characters": [c.skel_root for c in report.characters],
                "frames": sum(c.frames for c in report.characters), "warnings": report.warnings}
    kwargs = attend_kwargs(shot)
    if kwargs.pop("physics"):
        from usdgaze.passes.physics import run

        shots = run(**kwargs, record=key, make_folders=True, progress=step_lines(shot.name, "simulation"))
        # A fall or a missed task is the shot's result, written and said (discard_failed: bad input).
        return {"characters": [r.skeleton for r in shots], "frames": sum(r.frames for r in shots),
                "warnings": [f"{r.skeleton}: {p}" for r in shots for p in r.problems]
                + [f"{r.skeleton}: simulated again, {p}" for r in shots for p in r.other_attempt]
                + list(dict.fromkeys(w for r in shots for w in r.warnings))}
    from usdgaze.attend import attend

    report = attend(**kwargs, record=key, make_folders=True, progress=step_lines(shot.name, "planning"))
    return {"characters": [c["skel_root"] for c in report.characters],
            "frames": sum(c["frames"] for c in report.characters), "warnings": report.warnings}


def _pool_context():
    import multiprocessing

    # fork hands the workers the parent's imports for free; the parent has opened no stage yet
    # (no USD work threads). Elsewhere (macOS, Windows) fork is unsafe or missing.
    return multiprocessing.get_context("fork" if sys.platform.startswith("linux") else "spawn")


@contextmanager
def one_thread():
    """One BLAS thread in this process while the block runs (USD's limit is kept: see
    ``limit_threads``), as before after."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


def run_local(shots: list[Shot], workers: int, force: bool) -> Iterator[dict]:
    """Records as shots finish: in this process for one worker (one BLAS thread), else in a process
    pool of workers with one BLAS thread and, forked, one USD work thread each."""
    with one_thread():
        if workers <= 1 or len(shots) <= 1:
            for shot in shots:
                yield run_shot(shot, force)
            return
        context = _pool_context()
        forked = context.get_start_method() == "fork"
        if forked:
            # Forked workers inherit the pass's modules (UsdSkel, UsdGeom, the model: ~0.1 s of CPU
            # each) instead of importing them again.
            import usdgaze.api  # noqa: F401
        todo = list(range(len(shots)))
        while todo:
            # A worker that dies (the OOM killer's SIGKILL, a crash in C) breaks the pool: every shot
            # not finished fails with it. Those it was running run again, each in a pool of its own,
            # where a death is that shot's; those not started go on in a new pool.
            running, todo = yield from _pool_round(context, forked, shots, todo, workers, force)
            if not running:  # it broke before any shot started: no shot to blame, none to retry
                running, todo = todo, []
            for i in running:
                start = time.perf_counter()
                again, never = yield from _pool_round(context, forked, shots, [i], 1, force)
                for j in again + never:
                    yield died(shots[j], time.perf_counter() - start)


def _pool_round(context, forked: bool, shots: list[Shot], todo: list[int], workers: int,
                force: bool) -> Generator[dict, None, tuple[list[int], list[int]]]:
    """Run ``shots[i]`` for each ``i`` of ``todo`` in one pool, yielding their records; returns, if a
    worker died, the shots that were running then and those not started (both unreported)."""
    from concurrent.futures.process import BrokenProcessPool

    states = context.RawArray("b", len(shots))  # per shot: 1 started, 2 finished (set by the workers)
    broken = []
    with ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=context,
                             initializer=_pool_worker, initargs=(forked, states)) as pool:
        futures = {}
        with _signals_held():  # the workers start (fork) in submit: see _pool_worker
            for n, i in enumerate(todo):
                try:
                    futures[pool.submit(_pool_shot, shots[i], force, i)] = i
                except BrokenProcessPool:  # a worker died as the pool started: the rest never started
                    broken.extend(todo[n:])
                    break
        try:
            for future in as_completed(futures):
                try:
                    record = future.result()
                except BrokenProcessPool:
                    broken.append(futures[future])
                    continue
                yield record
        except BaseException:  # SIGTERM or SIGINT here: stop the workers' shots too (each cleans up)
            _stop_workers(pool)
            raise
    broken.sort()
    return [i for i in broken if states[i] == 1], [i for i in broken if states[i] != 1]


def died(shot: Shot, seconds: float, why: str = "its worker process ended abruptly (killed, e.g. out of "
          "memory, or crashed)") -> dict:
    """The record of a shot whose worker process died while running it alone (or its dask task failed)."""
    return {"index": shot.index, "name": shot.name, "input": shot.values["input"], "out": shot.out,
            "status": INTERNAL, "exit_code": EXIT_CODES[INTERNAL], "seconds": round(seconds, 4),
            # Each output lands whole or not at all; a dask worker can die after its shot's last one
            # landed, so "none was written" could be false: a rerun skips the shot where all did.
            "message": f"{why}; each of its outputs was written whole or not at all (a rerun redoes it "
                       "unless all landed)"}


_states = None
"""This pool worker's view of its pool's shot states (see ``_pool_round``)."""


def _pool_shot(shot: Shot, force: bool, slot: int | None = None) -> dict:
    """:func:`run_shot` in a pool worker, which ends once a stop signal has interrupted a shot (its
    writer has cleaned up by then): the pool hands a worker whose shot raised the next queued shot,
    and 2-3 more shots ran after a Ctrl-C. ``slot``: where the shot's state is kept."""
    from usdgaze.errors import Interrupted

    if _states is not None and slot is not None:
        _states[slot] = 1
    try:
        record = run_shot(shot, force)
    except Interrupted as exc:
        os._exit(128 + exc.signum)
    if _states is not None and slot is not None:
        _states[slot] = 2
    return record


def _pool_worker(forked: bool, states=None) -> None:
    """A pool worker's start: its threads (``limit_threads``), and between shots SIGTERM ends it at
    once and SIGINT, SIGHUP and SIGQUIT are the parent's to handle (it stops the workers with SIGTERM).

    The worker starts with them blocked (``_signals_held``): until this runs it has the
    parent's handlers, which would raise the parent's interruption in it."""
    global _states
    _states = states
    limit_threads(forked)
    signal.signal(signal.SIGTERM, lambda signum, frame: os._exit(128 + signum))
    for sig in _STOP_SIGNALS - {signal.SIGTERM}:  # a terminal's Ctrl-C or hangup reaches the whole group
        signal.signal(sig, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)


@contextmanager
def _signals_held() -> Iterator[None]:
    """The stopping signals blocked in this thread while the block runs, then delivered: processes
    forked (or spawned) meanwhile inherit the mask."""
    if not hasattr(signal, "pthread_sigmask"):  # Windows: no fork, no inherited handlers
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel the shots not started and SIGTERM the workers: a shot stopped mid-way removes its
    temporaries (its writer's handler), one in its final renames completes them."""
    import multiprocessing

    pool.shutdown(wait=False, cancel_futures=True)
    children = multiprocessing.active_children()
    for child in children:
        child.terminate()
    for child in children:  # one that cannot run its handler (stuck in C) is killed: its folder is swept later
        child.join(timeout=STOP_GRACE_S)
        if child.is_alive():
            child.kill()


def run_shots(shots: list[Shot], workers: int = 1, dask: str | None = None, force: bool = False,
              on_record: Callable[[dict], None] | None = None) -> list[dict]:
    """Run every shot; records in manifest order (``on_record`` sees each as it finishes)."""
    if dask:
        from usdgaze.batch.cluster import run_dask

        stream = run_dask(shots, dask, force)
    else:
        stream = run_local(shots, workers, force)
    records = []
    for record in stream:
        records.append(record)
        if on_record:
            on_record(record)
    return sorted(records, key=lambda r: r["index"])


def exit_code(records: list[dict]) -> int:
    """0 all done or skipped, 2 some bad input, 1 some internal error (bad input wins: do not retry)."""
    codes = {r["exit_code"] for r in records}
    return 2 if 2 in codes else 1 if 1 in codes else 0


def write_text(path: str | os.PathLike, text: str, flag: str = "--summary") -> None:
    """Write a text file through the one writer (staged beside it, renamed into place)."""
    from usdgaze.files.transaction import Outputs

    with Outputs() as tx:
        tx.claim(path, flag)
        tx.stage_text(path, text)


def summary(records: list[dict], manifest: str, mode: str, seconds: float, started: str,
            task_index: int | None = None) -> dict:
    """The JSON summary of one run: what ran where, counts by status, one record per shot."""
    from usdgaze import __version__

    counts = {status: sum(r["status"] == status for r in records) for status in EXIT_CODES}
    return {"usdgaze": __version__, "manifest": str(manifest), "started": started, "mode": mode,
            "task_index": task_index, "seconds": round(seconds, 3), "exit_code": exit_code(records),
            "counts": counts, "shots": records}
