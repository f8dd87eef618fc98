"""Gaze map benchmark: build time, query throughput (batched vs one at a time), model evaluation cost.

Run from the repository root: ``python benchmarks/bench_map.py``. Prints measured numbers and ratios
only (best of N repeats, ``time.perf_counter``); nothing is asserted.
"""

from __future__ import annotations

import os
import platform

import numpy as np

from usdgaze.gaze import defaults
from usdgaze.gaze.definition import GazeMapDefinition
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.gaze.motion import GazeMotions

from _timing import best_of  # noqa: E402  (benchmarks/ is on sys.path when run as a script)


def paper_grid(full: GazeMapDefinition) -> GazeMapDefinition:
    """Heck 5.2.1's 33 targets: the default examples with pitch in {-12, 0, 12}."""
    keep = np.isin(full.params[:, 1], [-12.0, 0.0, 12.0])
    return GazeMapDefinition(full.params[keep], full.motions[keep], full.settings)


def main() -> None:
    print(f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs, {platform.machine()}")
    full = defaults.default_definition()
    grid33 = paper_grid(full)
    print(f"synthesis settings: {full.settings}")

    # -- build ---------------------------------------------------------------------------------------
    print("\n[build] ParametricGazeMap(definition), best of 5")
    built = {}
    for name, definition in (("33 examples (paper grid)", grid33), ("55 examples (default map)", full)):
        t = best_of(lambda d=definition: built.__setitem__(len(d), ParametricGazeMap(d)), 5)
        print(f"  {name:28s} {t * 1e3:8.1f} ms   ({len(built[len(definition)].sample_params)} samples)")

    # -- queries -------------------------------------------------------------------------------------
    gaze_map = built[len(full)]
    rng = np.random.default_rng(0)
    n_batch, n_single = 10_000, 300
    yaw = rng.uniform(-180.0, 180.0, n_batch)
    pitch = rng.uniform(-30.0, 30.0, n_batch)
    gaze_map.query(yaw[:10], pitch[:10])  # warm up

    t_batch = best_of(lambda: gaze_map.query(yaw, pitch), 3)

    def singles() -> None:
        for i in range(n_single):
            gaze_map.query(yaw[i], pitch[i])

    t_single = best_of(singles, 3) / n_single
    batch_qps = n_batch / t_batch
    single_qps = 1.0 / t_single
    print("\n[query] default map, random (yaw, pitch) in [-180, 180] x [-30, 30]")
    print(f"  vectorized, batch of {n_batch}: {t_batch * 1e3:8.1f} ms  -> {batch_qps:10.0f} queries/s  (best of 3)")
    print(f"  one at a time ({n_single} calls):  {t_single * 1e3:8.3f} ms each -> {single_qps:10.0f} queries/s  (best of 3)")
    print(f"  ratio vectorized / one-at-a-time: {batch_qps / single_qps:.1f}x")

    # -- model evaluation ----------------------------------------------------------------------------
    frames = 20_000
    motions = gaze_map.query(70.0, 10.0)
    one = GazeMotions(motions.offsets, motions.timing)
    t = np.linspace(-0.1, 1.1, frames)
    one.displacement(t[:100])  # warm up
    t_eval = best_of(lambda: one.displacement(t), 7)
    per = t_eval / (frames * 5)
    print(f"\n[model] GazeMotions.displacement, {frames} frames x 5 segments (best of 7)")
    print(f"  {t_eval * 1e3:8.2f} ms total -> {per * 1e9:6.1f} ns per frame-joint")

    # batched: 100 motions x 200 frames each (same frame-joint count)
    many = gaze_map.query(rng.uniform(-180, 180, 100), rng.uniform(-30, 30, 100))
    t_many = np.tile(np.linspace(-0.1, 1.1, frames // 100), (100, 1))
    t_eval_many = best_of(lambda: many.displacement(t_many), 7)
    print(f"  100 motions x {frames // 100} frames x 5 segments: {t_eval_many * 1e3:8.2f} ms -> "
          f"{t_eval_many / (frames * 5) * 1e9:6.1f} ns per frame-joint")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()  # --help, no options
    main()
