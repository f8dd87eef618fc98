"""CPU time per output frame of the physics tasks, one thread, and where it goes (cProfile).

The scenes are ``bench_physics.py --speed``'s (``benchmarks/_physics_speed.py``): ``track`` (the
first ``--seconds`` of the CMU 131_01 walk), ``push``, ``catch`` (the seeded front throw, coupled
eyes, belief and body), ``stones``, ``obstacles`` (coupled) and their ``-body`` variants. Each runs
pinned to one core, one BLAS thread, one finite-difference thread, under cProfile, and prints CPU
seconds (``time.process_time``: user + sys, what a shared machine's load changes least) per output
frame at 30 fps and per planner step, split by phase:

* ``fd``: each step's transition matrices (``MujocoBody._fd``: MuJoCo's ``mjd_transitionFD``, or
  the positions' batch of steps and the closed forms of ``physics.velocity``); ``lin``: the rest of
  the window's linearization (state conversions, tangent maps, interpolation, the stack's rows);
* ``backward``: the solver's backward pass; ``rollouts``: forward passes and warm-start rollouts
  without their costs; ``costs``: cost values and expansions (tracking, tasks, attention);
* ``proposals``: the coupled loop's look-at seeds (their own rollouts and costs);
* ``other``: sensing, belief updates, the simulated step, measures, setup.

cProfile adds its own overhead to every Python call (~10-20% here); ``--plain`` runs without it for the
total alone. A digest of the simulated states says whether two versions of the code simulated the
same bits. Asserts nothing.

    python benchmarks/profile_physics.py [--tasks track,catch] [--seconds 1.0] [--stride 1] [--reuse 1] [--plain]
"""

from __future__ import annotations

import argparse
import cProfile
import hashlib
import json
import os
import pstats
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_physics as bench  # noqa: E402
import _physics_speed as speed  # noqa: E402
from usdgaze.physics import mpc, visuomotor  # noqa: E402


def _cum(st: pstats.Stats, file_end: str, name: str, caller: str | None = None) -> float:
    """Cumulative seconds of the function ``name`` in a file ending ``file_end`` (from ``caller`` only)."""
    total = 0.0
    for (file, _, func), (_, _, tt, ct, callers) in st.stats.items():
        if func != name or not file.endswith(file_end):
            continue
        if caller is None:
            total += ct
        else:
            total += sum(v[3] for (f, _, fn), v in callers.items() if fn == caller)
    return total


def _tot(st: pstats.Stats, name: str) -> float:
    return sum(v[2] for (_, _, func), v in st.stats.items() if func == name)


def phases(st: pstats.Stats, total: float) -> dict[str, float]:
    """CPU seconds per phase (see the module docstring) from a profile of one simulation."""
    fd = _cum(st, "dynamics.py", "_fd")
    lin = _cum(st, "ddp.py", "linearize_start") - fd
    backward = _cum(st, "ddp.py", "_backward")
    proposals = _cum(st, "loop.py", "seed_controls")
    # rollouts and their costs outside the proposals
    forward = _cum(st, "ddp.py", "_forward") + _cum(st, "ddp.py", "rollout", "solve")
    forward_costs = _cum(st, "ddp.py", "total_cost", "_forward")
    costs = forward_costs + _cum(st, "ddp.py", "total_cost", "solve") + _cum(st, "ddp.py", "expand_cost")
    out = {"fd": fd, "lin": lin, "backward": backward, "rollouts": forward - forward_costs, "costs": costs,
           "proposals": proposals}
    out["other"] = total - sum(out.values())
    return out


def run(task: str, seconds: float, stride: int, profile: bool, reuse: int = 1) -> dict:
    from threadpoolctl import threadpool_limits

    h = 0.03 if task.startswith(("stones", "obstacles")) else (mpc.Options.moving_h if task == "catch" else mpc.Options.h)
    opts = mpc.Options(h=h, workers=1, fd_stride=stride, fd_reuse=reuse)
    model, qpos, secs, things, tasks, pushes = speed.scene(task, h, seconds, bench)
    if task == "catch" and seconds < secs[-1]:
        keep = secs <= seconds + 1e-9
        qpos, secs = qpos[keep], secs[keep]
    if things is None:
        sim = lambda: mpc.simulate(model, qpos, secs, opts, pushes, tasks=tasks)  # noqa: E731
    else:
        sim = lambda: visuomotor.simulate(model, qpos, secs, things, visuomotor.Options(opts), pushes, tasks).body  # noqa: E731
    prof = cProfile.Profile(time.process_time) if profile else None  # CPU, as the total
    with threadpool_limits(1):
        c0 = time.process_time()
        if prof:
            prof.enable()
        r = sim()
        if prof:
            prof.disable()
        cpu = time.process_time() - c0
    frames = 30 * float(r.seconds[-1] - r.seconds[0])
    steps = len(r.seconds) - 1
    row = {"task": task, "h": h, "stride": stride, "reuse": reuse, "simulated_s": round(frames / 30, 3), "steps": steps,
           "fell_at_s": r.fell_at, "profiled": profile, "cpu_s": round(cpu, 2),
           "cpu_ms_per_frame": round(1e3 * cpu / frames, 1), "cpu_ms_per_step": round(1e3 * cpu / steps, 1),
           "frames_per_cpu_s": round(frames / cpu, 2),
           "digest": hashlib.sha1(r.qpos.tobytes()).hexdigest()[:12]}
    if prof:
        st = pstats.Stats(prof)
        row["ms_per_step"] = {k: round(1e3 * v / steps, 1) for k, v in phases(st, cpu).items()}
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tasks", default="track,catch")
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated seconds (track: of the walk; catch: "
                    "of the throw, which lasts 1.3 s)")
    ap.add_argument("--stride", type=int, default=1)
    ap.add_argument("--reuse", type=int, default=1, help="mpc.Options.fd_reuse")
    ap.add_argument("--plain", action="store_true", help="no cProfile: the total alone")
    a = ap.parse_args()
    os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:1])
    for task in a.tasks.split(","):
        row = run(task, a.seconds, a.stride, not a.plain, a.reuse)
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
