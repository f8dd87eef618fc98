"""Planner speed of ``usdgaze attend``: output frames per second on one core, 1 and 4 objects.

Runs the visuomotor loop (``usdgaze.vision.loop.run``: sensing, belief updates, one DDP solve per
planner step, acting) on a standing character's gaze chain with balls flying at it from the first step, with BLAS held
to one thread. Prints planner steps per CPU second and what that is in output frames per second at
24 and 30 fps (frames/s = steps/s * h * fps; h = 0.025 s), against the paper's 1-6 frames/s
(Eom et al. 2019: full-body physics, 6-core 3.5 GHz i7) and the goal of >= 30 frames/s with 4 objects.
Also prints the same steps per wall second (other jobs on the machine inflate the wall time).

    python benchmarks/bench_attend.py [--seconds 2.0] [--window 0.8] [--runs 3] [--iterations 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from usdgaze.planning.kinbody import BaseChain  # noqa: E402
from usdgaze.vision.loop import LoopOptions, Thing, run  # noqa: E402

G = 9.81


def standing(K: int) -> BaseChain:
    one = lambda v: np.tile(np.asarray(v, float), (K, 1))  # noqa: E731
    return BaseChain(one([0, 0, 1.3]), one([0, 0, 1.5]), one([0.08, 0, 1.62]), np.tile(np.eye(3), (K, 1, 1)),
                     one([0, 1.0, 0]), np.array([0, 0, 1.0]))


def ball(start, end, t_fly, t0, h, K) -> np.ndarray:
    t = np.clip(np.arange(K) * h - t0, 0, t_fly)[:, None]
    start, end = np.asarray(start, float), np.asarray(end, float)
    v = (end - start) / t_fly + [0, 0, 0.5 * G * t_fly]
    return start + v * t - 0.5 * G * np.array([0, 0, 1.0]) * t * t


def scene(n: int, h: float, K: int) -> list[Thing]:
    out = []
    for i in range(n):
        side = (i - (n - 1) / 2) * 1.2
        out.append(Thing(f"ball{i}", ball([7.0, side, 1.4], [0.4, 0.1 * side, 1.2], 1.3 + 0.05 * i, 0.0, h, K),
                         kind="ballistic"))
    return out


def measure(n: int, seconds: float, window: float, runs: int, iterations: int = 3) -> tuple[float, float, int]:
    h = 0.025
    K = int(seconds / h)
    best_cpu = best_wall = np.inf
    for _ in range(runs):
        c0, w0 = time.process_time(), time.perf_counter()
        run(standing(K), scene(n, h, K), LoopOptions(h=h, window_s=window, iterations=iterations), K)
        best_cpu = min(best_cpu, time.process_time() - c0)
        best_wall = min(best_wall, time.perf_counter() - w0)
    return K / best_cpu, K / best_wall, K


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--window", type=float, default=0.8)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--iterations", type=int, default=3, help="DDP iterations per planner step (default as attend)")
    args = ap.parse_args()
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        print(f"planner window {args.window} s, h 0.025 s, {args.seconds} s of animation, best of {args.runs}")
        for n in (1, 4):
            cpu, wall, K = measure(n, args.seconds, args.window, args.runs, args.iterations)
            f24, f30 = cpu * 0.025 * 24, cpu * 0.025 * 30
            print(f"{n} object(s): {cpu:6.1f} steps/CPU-s ({wall:5.1f} per wall s) = {f24:5.1f} frames/s at 24 fps, "
                  f"{f30:5.1f} at 30 fps; paper 1-6 frames/s -> {f24 / 6:4.1f}-{f24 / 1:5.1f}x"
                  + ("; goal >= 30 frames/s: " + ("met" if f24 >= 30 else "NOT met") if n == 4 else ""))


if __name__ == "__main__":
    main()
