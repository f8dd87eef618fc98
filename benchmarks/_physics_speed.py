"""Output frames per second of every physics task on 1 and 2 cores (``bench_physics.py --speed``).

Each task's scene is simulated once per core count, the process pinned to that many cores and the
window's finite differences split over as many threads (``Options.workers``; ``--stride`` as given):
``track`` (the CMU 131_01 walk, ``--seconds``) and ``push`` (150 N x 0.2 s at the chest, 1.5 s
standing) on the body alone; ``catch`` (a seeded throw from the front), ``stones`` (1.0-2.5 s of the
walk, a stone at each footfall, the right swing's displaced 15 cm) and ``obstacles`` (1.0-2.2 s of
the walk, two spheres crossing it) through the coupled loop (eyes, belief and body), as the pass runs
them when the stage's objects are GazeObjectAPI prims; ``stones-body`` and ``obstacles-body`` the same
scenes on the body alone (plain prims). Only the simulation is timed (no USD reading or writing).

Printed per run, at 30 output frames per second: the wall-clock rate (what an idle machine shows),
the rate per CPU second of all threads (``cpu``: what one free core would give, whatever the load),
and ``bound``: frames over ``max(all threads' CPU / cores, the main thread's CPU)``, the most an idle
machine with that many cores could show (each thread's work is serial and the cores are shared).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from usdgaze.physics import build, mpc, retarget, visuomotor
from usdgaze.vision import loop

import _physics_tasks as scenes  # benchmarks/ is on sys.path: run through bench_physics.py

TASKS = ("track", "push", "catch", "stones", "obstacles", "stones-body", "obstacles-body")


def timed(fn):
    """(result, wall s, CPU s of the process, CPU s of this thread) of ``fn()``."""
    w0, c0, t0 = time.perf_counter(), time.process_time(), time.thread_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0, time.thread_time() - t0


def _walk(start: float, end: float, bench):
    clip = build.load_clip(bench.CMU)
    model, ref = build.body_model(clip)
    keep = (clip.seconds >= start - 1e-9) & (clip.seconds <= end + 1e-9)
    return model, retarget.to_qpos(model, ref)[keep], clip.seconds[keep] - start


def _objects(paths: np.ndarray, radius: float, kind: str = "") -> list[loop.Thing]:
    """Things from positions per planner step ``(K, J, 3)``."""
    return [loop.Thing(f"o{j}", paths[:, j], 1.0, radius, kind) for j in range(paths.shape[1])]


def _catch_scene(h: float):
    from tests import catch_stages as cs
    from usdgaze.physics.catch import CatchTask

    start, arrival, flight = cs.seeded_throw(0)
    with tempfile.TemporaryDirectory() as tmp:
        clip = build.load_clip(cs.throw_stage(Path(tmp) / "t.usda", start, arrival, flight, flight + 0.2))
    model, ref = build.body_model(clip, weld_still=False)
    secs = clip.seconds - clip.seconds[0]
    steps = int(np.ceil(secs[-1] / h - 1e-6)) + 1
    to_model = model.to_model / np.linalg.norm(model.to_model[:, 0])
    ball = cs.flight(start, arrival, flight, h * np.arange(steps)) @ to_model.T
    things = [loop.Thing("ball", ball, kind="ballistic")]
    task = lambda plan, ref_q: CatchTask(plan, 0, 0, truth=ball, reference=ref_q)  # noqa: E731
    return model, retarget.to_qpos(model, ref), secs, things, [task]


def scene(task: str, h: float, seconds: float, bench):
    """(model, reference qpos, seconds, things or None for the body alone, task factories, pushes)."""
    from usdgaze.physics import obstacles, stones

    if task in ("track", "push"):
        model, qpos, secs = _walk(0.0, seconds if task == "track" else 1.5, bench)
        pushes = ()
        if task == "push":
            chest = next(b for b, n in enumerate(model.names) if n.lower() in ("chest2", "spine2", "chest", "spine1"))
            pushes = (mpc.Push(chest, 150.0 * scenes._left(model, qpos[0]), 0.5, 0.2),)
        return model, qpos, secs, None, [], pushes
    if task == "catch":
        return (*_catch_scene(h), ())
    steps = lambda secs: h * np.arange(int(np.ceil(secs[-1] / h - 1e-6)) + 1)  # noqa: E731
    if task.startswith("stones"):
        model, qpos, secs = _walk(1.0, 2.5, bench)
        placed, _ = scenes.stone_places(model, qpos, secs, {"RightAnkle": 0.15}, 0.0)
        things = _objects(np.repeat(placed[None], len(steps(secs)), 0), 0.15)
        return model, qpos, secs, None if task.endswith("body") else things, [stones.factory(placed, (qpos, secs))], ()
    model, qpos, secs = _walk(1.0, 2.2, bench)
    at, radii = scenes.crossing(qpos, secs, 0)
    if task.endswith("body"):
        return model, qpos, secs, None, [obstacles.factory(at, radii)], ()
    things = _objects(at(steps(secs)), float(radii[0]))
    return model, qpos, secs, things, [obstacles.factory(at, radii, list(range(len(radii))))], ()


def run(task: str, cores: int, opts: mpc.Options, seconds: float, bench) -> dict:
    """One timed simulation of ``task`` on ``cores`` cores (``opts.workers`` threads)."""
    model, qpos, secs, things, tasks, pushes = scene(task, opts.h, seconds, bench)
    if things is None:
        sim = lambda: mpc.simulate(model, qpos, secs, opts, pushes, tasks=tasks)  # noqa: E731
    else:
        sim = lambda: visuomotor.simulate(model, qpos, secs, things, visuomotor.Options(opts), pushes, tasks).body  # noqa: E731
    r, wall, cpu, main = timed(sim)
    frames = 30 * float(r.seconds[-1] - r.seconds[0])
    return {"task": task, "cores": cores, "coupled": things is not None, "h": opts.h, "stride": opts.fd_stride, "reuse": opts.fd_reuse,
            "simulated_s": round(frames / 30, 3), "fell_at_s": r.fell_at, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
            "main_thread_cpu_s": round(main, 2), "fps_at_30": round(frames / wall, 2), "cpu_fps_at_30": round(frames / cpu, 2),
            "bound_fps_at_30": round(frames / max(cpu / cores, main), 2), "load": round(os.getloadavg()[0], 1)}


def table(rows: list[dict]) -> str:
    """The summary: per task, frames/s at 30 fps (wall | per CPU second | idle bound) per core count."""
    cores = sorted({r["cores"] for r in rows})
    head = "task                 h     " + "".join(f"| {c} core(s): wall  cpu  bound   " for c in cores)
    lines = [head]
    for task in dict.fromkeys(r["task"] for r in rows):
        got = {r["cores"]: r for r in rows if r["task"] == task}
        first = next(iter(got.values()))
        name = f"{task}{' (coupled)' if first['coupled'] else ''}"
        cells = "".join(f"| {got[c]['fps_at_30']:9.2f} {got[c]['cpu_fps_at_30']:5.2f} {got[c]['bound_fps_at_30']:5.2f}   "
                        if c in got else "|" + " " * 30 for c in cores)
        lines.append(f"{name:21s}{first['h']:<6g}{cells}")
    lines.append("frames/s at 30 fps output; paper: 1-6 on six cores; goal: >= 6 on two cores")
    return "\n".join(lines)
