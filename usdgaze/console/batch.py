"""``usdgaze batch``: run the shots of a TOML manifest locally, on a dask cluster, or one per farm task."""

from __future__ import annotations

import json
import time
from datetime import datetime, timezone
from pathlib import Path

import click

from usdgaze.errors import Interrupted, UsdGazeError


@click.command()
@click.argument("manifest", type=click.Path())
@click.option("--workers", default=1, show_default=True, type=click.IntRange(min=1),
              help="Shots run in parallel in this many local processes (one BLAS thread each).")
@click.option("--dask", "dask_address", default=None, metavar="ADDRESS",
              help="Run every shot as a task on the running dask.distributed scheduler at ADDRESS.")
@click.option("--task-index", default=None, type=int, metavar="I",
              help="Run only shot I (0-based): one farm array task.")
@click.option("--force", is_flag=True, help="Redo shots whose outputs are up to date (with --emit: every task does).")
@click.option("--summary", "summary_path", default=None, type=click.Path(), metavar="FILE.json",
              help="Where to write the run's JSON summary [default: beside MANIFEST, its name with "
                   ".summary.json for its extension (jobs.toml: jobs.summary.json), or "
                   ".task-I.summary.json with --task-index].")
@click.option("--report", "report_path", default=None, type=click.Path(), hidden=True,
              help="Old name of --summary.")
@click.option("--manifest-jobs", default=None, hidden=True, metavar="DIGEST",
              help="Emitted tasks: the manifest's jobs they were emitted for (refused when they changed).")
@click.option("--emit", nargs=2, default=None, metavar="FARM DIR",
              help="Instead of running: write job files for FARM (deadline, opencue, slurm) into DIR, one task per shot.")
@click.pass_context
def batch(ctx, manifest, workers, dask_address, task_index, force, summary_path, report_path, manifest_jobs,
          emit) -> None:
    """Run the gaze shots of MANIFEST; skip those whose inputs and parameters are unchanged."""
    from usdgaze.batch.manifest import load_manifest, register
    from usdgaze.files.transaction import Outputs

    if dask_address is not None and not dask_address.strip():
        raise UsdGazeError("--dask '': expected the scheduler's address, such as tcp://host:8786")
    if dask_address and workers > 1:
        raise UsdGazeError("--dask and --workers are alternatives: the cluster's workers run the shots")
    if emit and task_index is not None:  # the emitted jobs give each farm task its own index
        raise UsdGazeError("--emit and --task-index are alternatives: the emitted jobs run one task per shot")
    if emit:  # a flag of the run, not of the job files, was dropped without a word
        ran = [f for f, on in (("--workers", workers > 1), ("--dask", dask_address), ("--summary", summary_path),
                               ("--report", report_path), ("--manifest-jobs", manifest_jobs)) if on]
        if ran:
            raise UsdGazeError(f"--emit writes job files and runs nothing: {ran[0]} is for a run (each emitted "
                               "task runs one shot and writes its own summary)")
    flag, given = ("--report", report_path) if report_path else ("--summary", summary_path)
    with Outputs() as tx:
        # The manifest first: a missing one in a missing folder was said as its summary's folder missing.
        shots = load_manifest(manifest)
        if manifest_jobs is not None:
            _check_emitted_jobs(manifest, shots, manifest_jobs, task_index)
        # The summary is checked before any shot runs: it may not be the manifest or any shot's file.
        summary = Path(given) if given else _default_summary(Path(manifest), task_index)
        if summary.suffix.lower() != ".json":
            raise UsdGazeError(f"{summary}: {flag} is written as JSON; name it FILE.json")
        if not emit:
            _claim_summary(tx, summary, flag, given)
        register(tx.ids, Path(manifest), shots)
        if emit:
            from usdgaze.batch.emit import check_inputs, check_summaries, emit as write_jobs, jobs_digest, task_request

            check_inputs(manifest, shots)
            check_summaries(manifest, _default_summary(Path(manifest), 0))
            for path in write_jobs(emit[0], manifest, len(shots), emit[1], force=force, ask=task_request(shots),
                                   jobs=jobs_digest(shots)):
                click.echo(f"wrote {path}")
            return
        if task_index is not None:
            if not 0 <= task_index < len(shots):
                raise UsdGazeError(f"{manifest}: --task-index {task_index} out of range (0..{len(shots) - 1})")
            shots = [shots[task_index]]
        report = _run(shots, manifest, workers, dask_address, force, task_index, summary)
        tx.stage_text(summary, json.dumps(report, indent=2) + "\n")
    counts = ", ".join(f"{n} {status}" for status, n in report["counts"].items() if n)
    click.echo(f"{_shots(len(shots))} in {report['seconds']:.2f} s ({report['mode']}): {counts}; summary {summary}")
    ctx.exit(report["exit_code"])


def _check_emitted_jobs(manifest: str, shots: list, digest: str, task_index: int | None) -> None:
    """An emitted task runs shot I by its index: a job added, removed, renamed or moved in the manifest
    since its job files were written moved the later shots (a task ran another shot, the last ran in
    none, and every task exited 0). Refused before anything is written."""
    from usdgaze.batch.emit import jobs_digest

    if jobs_digest(shots) == digest:
        return
    task = f", so task {task_index} would run another shot than it was given" if task_index is not None else ""
    raise UsdGazeError(f"{manifest}: its jobs are not those its farm job files were emitted for (a job added, removed, "
                       f"renamed or moved since; {len(shots)} now){task}; re-emit them with --emit")


def _claim_summary(tx, summary: Path, flag: str, given: str | None) -> None:
    """Claim the run's summary; where the default one (beside the manifest) cannot be written, the
    line says the way out, which only the flag's help said (a manifest in a locked show folder)."""
    try:
        tx.claim(summary, flag)
    except UsdGazeError as exc:
        if given:
            raise
        raise UsdGazeError(f"{exc}; write it elsewhere with --summary FILE.json") from None


def _run(shots, manifest, workers, dask_address, force, task_index, summary: Path) -> dict:
    from usdgaze.batch import engine
    from usdgaze.batch.progress import Progress

    mode = f"dask {dask_address}" if dask_address else f"{workers} worker{'s' * (workers > 1)}"
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    t0 = time.perf_counter()
    progress = Progress(len(shots))
    try:
        records = engine.run_shots(shots, workers=workers, dask=dask_address, force=force, on_record=progress)
    except Interrupted as exc:
        # A shot may finish between its last rename and its report: the count is of the reported ones.
        were = "was" if len(shots) == 1 else "were"
        exc.detail = (f"{progress.done} of {_shots(len(shots))} {were} reported finished; finished shots keep their "
                      f"outputs (a rerun skips them), no shot is half-written, no summary was written{_earlier(summary)}")
        raise
    finally:
        progress.close()
    return engine.summary(records, manifest, mode, time.perf_counter() - t0, started, task_index)


def _earlier(summary: Path) -> str:
    """Where an earlier run's summary is left at ``summary``: said, since a dashboard reading it would
    take that run's "exit_code": 0 for this one's."""
    try:
        started = json.loads(summary.read_text()).get("started")
    except (OSError, ValueError, AttributeError):
        return ""
    return f" ({summary} is an earlier run's, started {started})" if started else ""


def _shots(n: int) -> str:
    """``1 shot``, ``3 shots``: a --task-index run is always one."""
    return f"{n} shot{'s' * (n != 1)}"


def _default_summary(manifest: Path, task_index: int | None) -> Path:
    tag = f".task-{task_index}" if task_index is not None else ""
    return manifest.with_name(f"{manifest.stem}{tag}.summary.json")
