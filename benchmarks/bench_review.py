"""Review tools on a 10 s shot: ``usdgaze preview`` and ``usdgaze plot`` against reading the result.

    python benchmarks/bench_review.py [--runs 3] [--fps 24]

On ``sample_stages/cmu/cmu_131_02.usdc`` (31 joints x 1247 samples at 120 per second: 10.4 s) with
three shifts. The floor is reading the composed result (``read_review``: open input + layer, read
base and gaze animation, FK of every frame for both), which every review command must do. Printed:
the floor, then the preview split into its steps (projection of all frames, drawing, GIF encoding)
and the whole GIF / contact sheet / plot commands, each as seconds and as a ratio to the floor.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _timing import best_of  # noqa: E402

import usdgaze  # noqa: E402,F401
from usdgaze import api  # noqa: E402
from usdgaze.console.main import main  # noqa: E402
from usdgaze.review import preview as pv  # noqa: E402
from usdgaze.review.composed import composed_stage, read_review  # noqa: E402

INPUT = HERE.parent / "sample_stages" / "cmu" / "cmu_131_02.usdc"


def _quiet(args: list[str]) -> None:
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()):
        assert main(args) == 0


def run(runs: int, fps: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        layer = tmp / "g.usdc"
        api.apply(INPUT, ["2s:70:0", "5s:-100:10", "8s:0:0"], layer)
        review = read_review(INPUT, layer)
        seconds = review.characters[0].seconds
        stage, _ = composed_stage(INPUT, layer)
        opts = pv.PreviewOptions(fps=fps)
        scene = pv.build_scene(review, opts, stage)
        n = len(scene.seconds)

        floor = best_of(lambda: read_review(INPUT, layer), runs)
        project = best_of(lambda: pv.build_scene(review, opts, stage), runs)
        frames = []
        draw = best_of(lambda: frames.__setitem__(slice(None), [scene.frame(i) for i in range(n)]), runs)
        encode = best_of(lambda: frames[0].save(tmp / "x.gif", format="GIF", save_all=True, append_images=frames[1:],
                                                duration=round(1000 / fps), loop=0), runs)
        gif = best_of(lambda: _quiet(["preview", str(INPUT), "--layer", str(layer), "--out", str(tmp / "p.gif")]), runs)
        sheet = best_of(lambda: _quiet(["preview", str(INPUT), "--layer", str(layer), "--out", str(tmp / "s.png")]), runs)
        plot = best_of(lambda: _quiet(["plot", str(INPUT), "--layer", str(layer), "--out", str(tmp / "plots")]), runs)

    print(f"shot: {INPUT.name}, {seconds[-1] - seconds[0]:.2f} s, {len(seconds)} samples; preview {n} frames at {fps:g} fps")
    rows = [
        ("floor: read_review (read + FK, base and gaze)", floor),
        ("preview: project all frames", project),
        (f"preview: draw {n} frames", draw),
        ("preview: GIF encode", encode),
        ("usdgaze preview --out .gif (whole command)", gif),
        ("usdgaze preview --out .png (contact sheet)", sheet),
        ("usdgaze plot (4 PNGs)", plot),
    ]
    for name, t in rows:
        print(f"  {name:48s} {t:7.3f} s   {t / floor:6.1f}x floor")
    print(f"  drawing: {1000 * draw / n:.2f} ms per frame")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--fps", type=float, default=24.0)
    args = parser.parse_args()
    run(args.runs, args.fps)
