"""The look pass's cost per frame as a held moving target's shot grows: flat means linear.

    python benchmarks/bench_look_length.py [--frames 2000,10000,50000] [--runs 2]

A synthetic walk (tests/synthetic.py, 60 joints, 60 time codes a second, written to a temp folder) and a
target with one sample per frame that weaves ahead of the walker, looked at from the first second to
the end: the body re-plans as it moves, the eyes pursue it with catch-up saccades. ``usdgaze.api.apply``
in-process, best of ``--runs``; prints ms per 1,000 frames and its ratio to the shortest shot.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from pxr import Gf, Sdf, Vt

from usdgaze import api

ROOT = Path(__file__).resolve().parents[1]


def shot(folder: Path, frames: int) -> Path:
    """The walk and its moving target, as a root layer over the rig."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from tests import synthetic

    rig = synthetic.make_rig(folder / f"walk_{frames}.usdc", joints=60, frames=frames, time_codes_per_second=60,
                             mesh=False)
    layer = Sdf.Layer.CreateNew(str(folder / f"shot_{frames}.usda"))
    layer.timeCodesPerSecond = layer.framesPerSecond = 60
    layer.startTimeCode, layer.endTimeCode = rig.start_time, rig.end_time
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    layer.subLayerPaths.append(rig.path.name)
    prim = Sdf.CreatePrimInLayer(layer, "/World/Target")
    prim.specifier, prim.typeName = Sdf.SpecifierDef, "Xform"
    Sdf.CreatePrimInLayer(layer, "/World").typeName = "Xform"
    op = Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3)
    Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:translate"])
    s = (rig.times - rig.start_time) / 60.0
    with Sdf.ChangeBlock():
        for t, x, y, z in zip(rig.times, 2.0 * np.sin(0.5 * s), 1.5 + 0.3 * np.sin(0.7 * s), 1.2 * s + 3.0):
            layer.SetTimeSample(op.path, float(t), Gf.Vec3d(float(x), float(y), float(z)))
    layer.Save()
    return Path(layer.realPath)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", default="2000,10000,50000")
    parser.add_argument("--runs", type=int, default=2)
    args = parser.parse_args(argv)
    lengths = [int(v) for v in args.frames.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        rows = []
        for frames in lengths:
            src = shot(folder, frames)
            best = np.inf
            for _ in range(args.runs):
                t0 = time.perf_counter()
                api.apply(src, [], folder / f"gaze_{frames}.usdc", look_at=["/World/Target@1s"])
                best = min(best, time.perf_counter() - t0)
            rows.append((frames, best))
    first = rows[0][1] / rows[0][0]
    print(f"look-at a moving target, 60 joints, best of {args.runs}")
    for frames, t in rows:
        print(f"  {frames:7d} frames  {t:8.2f} s  {t / frames * 1e6:7.1f} ms per 1,000 frames  "
              f"{t / frames / first:5.2f}x the shortest's per frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
