"""``usdgaze batch``: run the shots of a TOML manifest locally, on a dask cluster, or one per farm task."""

from __future__ import annotations

import json
import time
from datetime import datetime, timezone
from pathlib import Path

import click

from usdgaze.errors import UsdGazeError


@click.command()
@click.argument("manifest", type=click.Path(dir_okay=False))
@click.option("--workers", default=1, show_default=True, type=click.IntRange(min=1),
              help="Shots run in parallel in this many local processes (one BLAS thread each).")
@click.option("--dask", "dask_address", default=None, metavar="ADDRESS",
              help="Run every shot as a task on the running dask.distributed scheduler at ADDRESS.")
@click.option("--task-index", default=None, type=int, metavar="I",
              help="Run only shot I (0-based): one farm array task.")
@click.option("--force", is_flag=True, help="Redo shots whose outputs are up to date.")
@click.option("--summary", "summary_path", default=None, type=click.Path(dir_okay=False), metavar="FILE.json",
              help="Where to write the run's JSON summary [default: MANIFEST.summary.json, or "
                   "MANIFEST.task-I.summary.json with --task-index].")
@click.option("--emit", nargs=2, default=None, metavar="FARM DIR",
              help="Instead of running: write job files for FARM (deadline, opencue, slurm) into DIR, one task per shot.")
@click.pass_context
def batch(ctx, manifest, workers, dask_address, task_index, force, summary_path, emit) -> None:
    """Run the gaze shots of MANIFEST; skip those whose inputs and parameters are unchanged."""
    from usdgaze.batch import engine
    from usdgaze.batch.manifest import load_manifest, manifest_files
    from usdgaze.batch.progress import Progress
    from usdgaze.files.transaction import Outputs

    if dask_address and workers > 1:
        raise UsdGazeError("--dask and --workers are alternatives: the cluster's workers run the shots")
    shots = all_shots = load_manifest(manifest)
    if emit:
        from usdgaze.batch.emit import emit as write_jobs

        for path in write_jobs(emit[0], manifest, len(shots), emit[1]):
            click.echo(f"wrote {path}")
        return
    if task_index is not None:
        if not 0 <= task_index < len(shots):
            raise UsdGazeError(f"{manifest}: --task-index {task_index} out of range (0..{len(shots) - 1})")
        shots = [shots[task_index]]
    mode = f"dask {dask_address}" if dask_address else f"{workers} worker{'s' * (workers > 1)}"
    path = Path(summary_path) if summary_path else _default_summary(Path(manifest), task_index)
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    t0 = time.perf_counter()
    # The summary is claimed before any shot runs: it may be none of the files the shots read or write.
    with Outputs(ids=manifest_files(manifest, all_shots)) as tx:
        tx.claim(path, "--summary")
        progress = Progress(len(shots))
        try:
            records = engine.run_shots(shots, workers=workers, dask=dask_address, force=force, on_record=progress)
        finally:
            progress.close()
        report = engine.summary(records, manifest, mode, time.perf_counter() - t0, started, task_index)
        tx.stage_text(path, json.dumps(report, indent=2) + "\n")
    counts = ", ".join(f"{n} {status}" for status, n in report["counts"].items() if n)
    click.echo(f"{len(records)} shots in {report['seconds']:.2f} s ({mode}): {counts}; summary {path}")
    ctx.exit(report["exit_code"])


def _default_summary(manifest: Path, task_index: int | None) -> Path:
    tag = f".task-{task_index}" if task_index is not None else ""
    return manifest.with_name(f"{manifest.stem}{tag}.summary.json")
