"""Batch entry for farms: run the gaze jobs of a TOML manifest.

    python pipeline/batch.py MANIFEST.toml [--task-index I] [--workers N] [--report report.json]

A manifest lists jobs (paths relative to the manifest)::

    [defaults]            # optional; any job key
    fixation = 2.0

    [[job]]
    name = "walk_01"
    input = "../../sample_stages/cmu/cmu_131_01.usdc"
    out = "out/walk_01_gaze.usdc"
    preview = "out/walk_01_preview.usda"     # or sublayer_into = "shot.usda"
    shifts = ["2s:60:0", "5s:-120:10", "7.5s:0:0"]
    # map = "maps/studio.usda:/GazeMap"; skel_root = "/Char/Body"
    # bind = ["pelvis=j1", "head=j5"]  (or a table: bind = { neck = ["j3", "j4"] }); forward = [0, 0, 1]

Each job runs on its own and is reported on its own: a bad job (exit 2) or a crash (exit 1) does not
stop the others. ``--task-index`` runs just one job, for farm array tasks (see pipeline/farm/). The
exit code is the worst of the jobs run: 0 all done, 2 some bad input, 1 some internal error.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

KEYS = {"name", "input", "out", "preview", "sublayer_into", "shifts", "map", "skel_root", "fixation", "bind", "forward"}
_TEXT = ("name", "input", "out", "preview", "sublayer_into", "map", "skel_root")
_PATHS = ("input", "out", "preview", "sublayer_into")


def load_manifest(path: Path) -> list[dict]:
    """Jobs of a manifest with defaults applied and paths resolved against the manifest's folder.

    Every problem is one line naming the manifest, the job and the key; values go through the same
    check as the CLI's (:func:`usdgaze.api.check_request`); no two jobs may write one file, and no
    job may write a file another job reads.
    """
    from usdgaze.errors import UsdGazeError
    from usdgaze.ingest.tomlio import load_toml

    data = load_toml(path)
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise UsdGazeError(f"{path}: [defaults] must be a table of job keys")
    jobs = data.get("job", [])
    if not isinstance(jobs, list):
        raise UsdGazeError(f"{path}: job = {jobs!r}: expected [[job]] tables")
    if not jobs:
        raise UsdGazeError(f"{path}: no [[job]] entries")
    out = [_job(path, i, raw, defaults) for i, raw in enumerate(jobs)]
    _check_identities(path, out)
    return out


def _job(path: Path, i: int, raw, defaults: dict) -> dict:
    from usdgaze.api import ApplyRequest, check_request
    from usdgaze.core.hints import parse_hints
    from usdgaze.errors import UsdGazeError
    from usdgaze.passes.shift import PassOptions

    if not isinstance(raw, dict):
        raise UsdGazeError(f"{path}: job {i}: {raw!r} is not a table; expected [[job]] tables")
    job = {**defaults, **raw}
    where = f"{path}: job {i}" + (f" '{job['name']}'" if isinstance(job.get("name"), str) else "")
    unknown = set(job) - KEYS
    if unknown:
        raise UsdGazeError(f"{where}: unknown key '{sorted(unknown)[0]}' (keys: {', '.join(sorted(KEYS))})")
    for key in ("input", "out", "shifts"):
        if key not in job:
            raise UsdGazeError(f"{where}: missing '{key}'")
    for key in _TEXT:
        if key in job and not (isinstance(job[key], str) and job[key].strip()):
            raise UsdGazeError(f"{where}: {key} = {job[key]!r}: expected a non-empty string")
    label = lambda key, value: f"{where}: {key} = {value}"  # noqa: E731
    fixation = job.get("fixation", 2.0)
    if isinstance(fixation, bool) or not isinstance(fixation, (int, float)):
        raise UsdGazeError(f"{label('fixation', repr(fixation))}: expected a distance in metres")
    for key in _PATHS:
        if job.get(key):
            job[key] = str((path.parent / job[key]).resolve())
    if job.get("map"):
        file, sep, prim = job["map"].partition(":/")
        job["map"] = str((path.parent / file).resolve()) + (f":/{prim}" if sep else "")
    check_request(ApplyRequest(job["input"], job["shifts"], job["out"], sublayer_into=job.get("sublayer_into"),
                               preview=job.get("preview"), options=PassOptions(fixation_m=float(fixation))), label)
    job["fixation"] = float(fixation)
    job.setdefault("name", Path(job["input"]).stem)
    # Checked here, so a bad hint fails the manifest as a whole, naming the job, before any job runs.
    job["hints"] = parse_hints(job.get("bind"), job.get("forward"), bind_label=f"{where}: bind",
                               forward_label=f"{where}: forward")
    return job


def _check_identities(path: Path, jobs: list[dict]) -> None:
    """No job writes the manifest, another job's input or map, or a file another job writes."""
    from usdgaze.files.identity import Identities

    ids = Identities()
    ids.read(path, "manifest")
    for i, job in enumerate(jobs):
        ids.read(job["input"], f"input of job {i} '{job['name']}'")
        if job.get("map"):
            ids.read(job["map"].partition(":/")[0], f"map of job {i} '{job['name']}'")
    for i, job in enumerate(jobs):
        for key in ("out", "preview", "sublayer_into"):
            if job.get(key) and not (key == "sublayer_into" and any(
                    j.get("sublayer_into") == job[key] for j in jobs[:i])):
                ids.write(job[key], f"job {i} '{job['name']}' {key}")


def run_job(job: dict) -> dict:
    """Run one job; never raises. Returns its status record."""
    from usdgaze.api import apply
    from usdgaze.errors import UsdGazeError
    from usdgaze.passes.shift import PassOptions

    start = time.perf_counter()
    record = {"name": job["name"], "input": job["input"], "out": job["out"]}
    try:
        report = apply(
            job["input"], job["shifts"], job["out"], skel_root=job.get("skel_root"), map_spec=job.get("map"),
            sublayer_into=job.get("sublayer_into"), preview=job.get("preview"), make_folders=True,
            options=PassOptions(fixation_m=float(job.get("fixation", 2.0)), binding=job["hints"]),
        )
        record.update(exit_code=0, status="done", characters=[c.skel_root for c in report.characters],
                      warnings=report.warnings)
    except UsdGazeError as exc:
        record.update(exit_code=2, status="bad input", message=str(exc))
    except Exception as exc:  # a bug: report it and let the other jobs run
        record.update(exit_code=1, status="internal error", message=f"{type(exc).__name__}: {exc}",
                      traceback=traceback.format_exc())
    record["seconds"] = round(time.perf_counter() - start, 3)
    return record


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("manifest", type=Path)
    parser.add_argument("--task-index", type=int, default=None, help="run only job I (0-based), for farm array tasks")
    parser.add_argument("--workers", type=int, default=1, help="jobs run in parallel processes")
    parser.add_argument("--report", type=Path, default=None, help="write the job records as JSON here")
    args = parser.parse_args(argv)

    import usdgaze  # noqa: F401  (registers the schema before any stage is opened)
    from usdgaze.errors import UsdGazeError
    from usdgaze.files.transaction import Interrupted, Outputs

    try:
        with Outputs() as tx:
            records = _run(args, tx)
    except UsdGazeError as exc:
        print(f"usdgaze-batch: error: {exc}", file=sys.stderr)
        return 2
    except (Interrupted, KeyboardInterrupt) as exc:
        print(f"usdgaze-batch: error: interrupted ({exc or 'SIGINT'}); the job running was not written", file=sys.stderr)
        return 128 + getattr(exc, "signum", 2)

    for r in records:
        line = f"{r['status']:<14} {r['name']}  {r['seconds']:.2f}s"
        if r.get("message"):
            line += f"  {r['message']}"
        print(line, file=sys.stderr if r["exit_code"] else sys.stdout)
        for w in r.get("warnings", []):
            print(f"warning        {r['name']}  {w}", file=sys.stderr)
    codes = [r["exit_code"] for r in records]
    return 2 if 2 in codes else 1 if 1 in codes else 0


def _run(args, tx) -> list[dict]:
    """Check the manifest and the report path, run the jobs (each commits on its own), stage the report."""
    from usdgaze.errors import UsdGazeError

    if args.report:
        tx.claim(args.report, "--report")
    jobs = load_manifest(args.manifest)
    tx.read(args.manifest, "manifest")
    written: set[str] = set()
    for i, job in enumerate(jobs):  # the report is no job's file either
        tx.read(job["input"], f"input of job {i} '{job['name']}'")
        for key in ("out", "preview", "sublayer_into"):
            if job.get(key) and job[key] not in written:
                written.add(job[key])
                tx.ids.write(job[key], f"job {i} '{job['name']}' {key}")
    if args.task_index is not None:
        if not 0 <= args.task_index < len(jobs):
            raise UsdGazeError(f"{args.manifest}: --task-index {args.task_index} out of range (0..{len(jobs) - 1})")
        jobs = [jobs[args.task_index]]
    if args.workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            records = list(pool.map(run_job, jobs))
    else:
        records = [run_job(j) for j in jobs]
    if args.report:
        tx.stage_text(args.report, json.dumps(records, indent=2))
    return records


if __name__ == "__main__":
    sys.exit(main())
