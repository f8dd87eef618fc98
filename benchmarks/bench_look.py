"""The look pass against the shift pass and the I/O floor, side by side, on real capture.

    python benchmarks/bench_look.py [--runs 5]

On ``sample_stages/cmu/cmu_131_01.usdc`` (31 joints x 994 frames), best of ``--runs`` each, interleaved:

* look: ``apply`` with a look-at a target the walker passes (re-planned body shifts, saccades,
  pursuit), a shift and a release, guides on;
* look, no guides: the same without the review guides;
* shifts (model): three shifts with ``--eye-timing model`` (the paper's pass);
* floor: bench_pass's true Sdf-level copy of the attributes the look pass writes.

Prints the times and the ratios to the floor.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
from pathlib import Path

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)

from usdgaze import api
from usdgaze.passes.look import LookOptions

HERE = Path(__file__).resolve().parent
CMU = HERE.parent / "sample_stages" / "cmu" / "cmu_131_01.usdc"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"usdgaze_bench_{name}", HERE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args(argv)
    timing, bench_pass = _load("_timing"), _load("bench_pass")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cases = {
            "look": lambda: api.apply(CMU, ["5s:-60:10"], work / "look.usdc", look_at=["1,1.3,-0.5@0.5s"],
                                      release=["6.5s"]),
            "look, no guides": lambda: api.apply(CMU, ["5s:-60:10"], work / "look_ng.usdc",
                                                 look_at=["1,1.3,-0.5@0.5s"], release=["6.5s"], guides=False),
            "shifts (model)": lambda: api.apply(CMU, ["2s:70:0", "4.5s:-120:10", "6.4s:0:0"], work / "model.usdc",
                                                look=LookOptions(eye_timing="model"), guides=False),
        }
        cases["look"]()
        attrs = bench_pass.written_attributes(work / "look.usdc")
        cases["floor"] = lambda: bench_pass.sdf_copy(CMU, work / "floor.usdc", attrs)
        best = {name: float("inf") for name in cases}
        for _ in range(args.runs):
            for name, fn in cases.items():
                best[name] = min(best[name], timing.best_of(fn, 1))
    floor = best["floor"]
    print(f"{CMU.name}: best of {args.runs}")
    for name, t in best.items():
        print(f"  {name:16s} {t * 1000:8.1f} ms   {t / floor:5.2f} x floor")
    return 0


if __name__ == "__main__":
    sys.exit(main())
