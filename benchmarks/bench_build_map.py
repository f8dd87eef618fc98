"""build-map benchmark: a gaze map from 33 captured trials of 6 s at 60 Hz (C3D).

Run from the repository root: ``python benchmarks/bench_build_map.py``. The session (Heck's 33-target
protocol, 20 markers, 0.5 mm noise, occlusions; tests/ingest_synth.py) is generated into a temporary
folder first and is not timed. Prints, best of N repeats (``time.perf_counter``):

* build: sheet -> C3D reading -> gap fill, stabilization, rest cropping -> extraction -> definition;
* of which reading the 33 C3D files (ezc3d);
* writing the map layer (``usdgaze.usd.schema.dump_map``);
* the whole ``usdgaze build-map`` command in-process (build + report table + map file).

Nothing is asserted.
"""

from __future__ import annotations

import contextlib
import io
import os
import platform
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from tests import ingest_synth as syn  # noqa: E402
from usdgaze.console.main import main  # noqa: E402
from usdgaze.ingest import build, load_sheet, write_map  # noqa: E402
from usdgaze.ingest.c3dio import read_c3d  # noqa: E402

from _timing import best_of  # noqa: E402  (benchmarks/ is on sys.path when run as a script)


def main_bench() -> None:
    print(f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs, {platform.machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        session = syn.write_c3d_session(tmp / "session", seed=0, total_s=6.0)
        frames = [read_c3d(t.file).frames for t in session.trials]
        print(f"session: {len(session.trials)} trials, {min(frames)}-{max(frames)} frames at {syn.RATE:g} Hz, "
              f"{len(syn.LABELS)} markers, C3D in {tmp / 'session'} (not timed)")

        sheet = load_sheet(session.sheet)
        result = build(sheet, session.markerset)
        assert len(result.good) == len(session.trials), [r.error for r in result.reports if r.error]

        t_build = best_of(lambda: build(sheet, session.markerset), 5)
        t_read = best_of(lambda: [read_c3d(t.file) for t in session.trials], 5)
        t_write = best_of(lambda: write_map(result, sheet, tmp / "map.usda"), 5)

        def command() -> None:
            with contextlib.redirect_stdout(io.StringIO()):
                code = main(["build-map", str(session.sheet), "--markers", str(session.markerset),
                             "--out", str(tmp / "cli_map.usda")])
            assert code == 0

        t_cli = best_of(command, 3)
        n = len(session.trials)
        print("\n[build-map] best of 5 (command: best of 3)")
        print(f"  build (read + clean + crop + extract)  {t_build * 1e3:8.1f} ms   ({t_build / n * 1e3:.2f} ms per trial)")
        print(f"    of which reading C3D                 {t_read * 1e3:8.1f} ms")
        print(f"  write map layer (.usda)                {t_write * 1e3:8.1f} ms")
        print(f"  usdgaze build-map, whole command       {t_cli * 1e3:8.1f} ms")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()  # --help, no options
    main_bench()
