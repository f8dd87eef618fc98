"""Gaze pass against a true Sdf-level copy (the I/O floor), side by side.

    python benchmarks/bench_pass.py [--frames 20000 --joints 100 --runs 5] [--profile]

On ``sample_stages/cmu/cmu_131_02.usdc`` (31 joints x 1247 frames, real capture) and on a synthetic
walk (``--joints`` x ``--frames``, written to a temp folder by tests/synthetic.py):

* gaze: ``usdgaze.api.apply`` with four shifts, writing a .usdc override;
* floor: a true Sdf-level copy, the I/O floor: the attributes the gaze pass writes (found in its output
  layer) read from the input layer with ``Sdf.Layer.QueryTimeSample`` and written unchanged to a new
  layer with ``SetTimeSample`` in one ``Sdf.ChangeBlock``, then exported the same way. No stage, no
  composition, no model: whatever the pass spends above it is the pass's own cost.

Best of ``--runs`` each, the two interleaved. Prints both times, the ratio gaze/floor (goal <= 1.3) and
where the time goes (read, map build, model, write). ``--profile`` adds cProfile's top functions of
one gaze pass on each input.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import tempfile
import time
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from pxr import Sdf, Vt

from usdgaze import api
from usdgaze.gaze import gazemap
from usdgaze.usd import layers, skelio
from usdgaze.usd.stage import open_stage

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc"


def _synthetic():
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from tests import synthetic  # a package module (it imports its neighbours relatively)

    return synthetic


# -- timing --------------------------------------------------------------------------------------

class Stages:
    """Wall time per stage, gathered by wrapping the functions the passes call."""

    WRAP = {
        "read": [(skelio, "open_stage"), (skelio, "read_clip")],
        "map build": [(gazemap.ParametricGazeMap, "__init__")],
        "model": [(api, "apply_look"), (api, "bind")],
        "write": [(api, "build_override"), (api, "atomic_export"), (layers, "build_override"),
                  (layers, "atomic_export"), (getattr(layers, "OverrideLayer", None), "add"),
                  (getattr(layers, "OverrideLayer", None), "finish")],
    }

    def __init__(self):
        self.times: dict[str, float] = defaultdict(float)
        self._depth = 0

    @contextmanager
    def installed(self):
        saved = []
        for stage, targets in self.WRAP.items():
            for owner, name in targets:
                if not hasattr(owner, name):  # the pass this version of the API runs
                    continue
                original = getattr(owner, name)
                saved.append((owner, name, original))
                setattr(owner, name, self._wrap(stage, original))
        try:
            yield self
        finally:
            for owner, name, original in reversed(saved):
                setattr(owner, name, original)

    def _wrap(self, stage, fn):
        def timed(*args, **kwargs):
            if self._depth:  # nested wrapped call: counted by the outer one
                return fn(*args, **kwargs)
            self._depth += 1
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.times[stage] += time.perf_counter() - t0
                self._depth -= 1
        return timed


# -- the two passes ------------------------------------------------------------------------------

def gaze_pass(src: Path, shifts: list[str], out: Path, guides: bool = True) -> None:
    api.apply(src, shifts, out, guides=guides)


def written_attributes(out: Path) -> dict[str, set[str]]:
    """Prim path -> attribute names the gaze pass authored in its output layer."""
    layer = Sdf.Layer.FindOrOpen(str(out))
    layer.Reload(force=True)
    found: dict[str, set[str]] = {}

    def visit(path):
        if path.IsPropertyPath():
            found.setdefault(str(path.GetPrimPath()), set()).add(path.name)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return found


def _sdf_read(layer: Sdf.Layer, path: Sdf.Path) -> np.ndarray:
    """All time samples of one attribute spec, straight from the layer, as one numpy array."""
    times = layer.ListTimeSamplesForPath(path)
    first = np.asarray(layer.QueryTimeSample(path, times[0]))
    out = np.empty((len(times),) + first.shape, first.dtype)
    for i, t in enumerate(times):
        out[i] = layer.QueryTimeSample(path, t)
    return out


_VT = {"rotations": (Vt.QuatfArray, Sdf.ValueTypeNames.QuatfArray),
       "translations": (Vt.Vec3fArray, Sdf.ValueTypeNames.Float3Array),
       "scales": (Vt.Vec3hArray, Sdf.ValueTypeNames.Half3Array)}


def sdf_copy(src: Path, out: Path, attrs: dict[str, set[str]], rest_from: Path | None = None) -> None:
    """The I/O floor: read the attributes the gaze pass writes from the layer that holds them and write
    them unchanged to a new layer, with Sdf only (no stage, no composition, no model).

    The animation arrays come from the input (through numpy, as any numpy tool reads them). With
    ``rest_from`` (the pass's own output), every other attribute the pass writes (the review guides'
    time-sampled points, extents and point of sight, the added eyes' skeleton arrays) is copied from
    there too, value for value: the floor then writes what the pass writes."""
    source = Sdf.Layer.OpenAsAnonymous(str(src))
    rest = Sdf.Layer.OpenAsAnonymous(str(rest_from)) if rest_from else None
    layer = Sdf.Layer.CreateAnonymous("floor.usdc")
    # marked as usdgaze's, as the pass's output is: the one writer replaces only layers usdgaze wrote
    layer.customLayerData = {"usdgaze": "floor"}
    with Sdf.ChangeBlock():
        for prim_path, names in attrs.items():
            prim = Sdf.CreatePrimInLayer(layer, prim_path)
            prim.specifier = Sdf.SpecifierOver
            for name in sorted(names):
                path = Sdf.Path(prim_path).AppendProperty(name)
                if name in _VT and source.GetNumTimeSamplesForPath(path):
                    values = _sdf_read(source, path)
                    vt, type_name = _VT[name]
                    spec = Sdf.AttributeSpec(prim, name, type_name)
                    for t, row in zip(source.ListTimeSamplesForPath(path), values):
                        layer.SetTimeSample(spec.path, t, vt.FromNumpy(row))
                elif rest is not None:
                    _copy_spec(rest, layer, prim, path)
    layers.atomic_export(layer, out)


def _copy_spec(source: Sdf.Layer, layer: Sdf.Layer, prim: Sdf.PrimSpec, path: Sdf.Path) -> None:
    """One attribute spec, its default and its time samples, value for value."""
    found = source.GetAttributeAtPath(path)
    if found is None:
        return
    spec = Sdf.AttributeSpec(prim, path.name, found.typeName, found.variability)
    if found.HasDefaultValue():
        spec.default = found.default
    query, set_sample = source.QueryTimeSample, layer.SetTimeSample
    for t in source.ListTimeSamplesForPath(path):
        set_sample(path, t, query(path, t))


def shifts_for(src: Path) -> list[str]:
    """Four shifts spread over the clip, in seconds from the stage start."""
    stage = open_stage(str(src))
    length = (stage.GetEndTimeCode() - stage.GetStartTimeCode()) / stage.GetTimeCodesPerSecond()
    return [f"{length * f:.3f}s:{yaw}:{pitch}" for f, yaw, pitch in
            ((0.1, 60, 0), (0.35, -120, 10), (0.6, 0, 0), (0.85, 30, -20))]


def bench(label: str, src: Path, work: Path, runs: int, profile: bool) -> dict:
    shifts = shifts_for(src)
    gaze_out, bare_out = work / f"{label}_gaze.usdc", work / f"{label}_bare.usdc"
    plain_out, full_out = work / f"{label}_plain.usdc", work / f"{label}_full.usdc"
    gaze_pass(src, shifts, gaze_out)  # warm up (imports, caches) and learn what it writes
    gaze_pass(src, shifts, plain_out, guides=False)
    attrs, plain_attrs = written_attributes(gaze_out), written_attributes(plain_out)
    sdf_copy(src, bare_out, attrs)
    runners = {
        "gaze": lambda: gaze_pass(src, shifts, gaze_out),
        "copy all": lambda: sdf_copy(src, full_out, attrs, rest_from=gaze_out),
        "gaze, no guides": lambda: gaze_pass(src, shifts, plain_out, guides=False),
        "copy anim": lambda: sdf_copy(src, bare_out, plain_attrs, rest_from=plain_out),
    }
    best = {name: (np.inf, None) for name in runners}
    for i in range(runs):
        for name in (list(runners) if i % 2 == 0 else list(runners)[::-1]):
            stages = Stages()
            with stages.installed():
                t0 = time.perf_counter()
                runners[name]()
                total = time.perf_counter() - t0
            if total < best[name][0]:
                best[name] = (total, dict(stages.times))

    clip_info = skelio.read_clip(*_first_clip(src))
    result = dict(label=label, src=src, frames=len(clip_info.times), joints=len(clip_info.joints),
                  shifts=shifts, attrs=attrs, best=best,
                  size={name: p.stat().st_size for name, p in (("gaze", gaze_out), ("copy all", full_out),
                                                                ("gaze, no guides", plain_out), ("copy anim", bare_out))})
    if profile:
        prof = cProfile.Profile()
        prof.enable()
        gaze_pass(src, shifts, gaze_out)
        prof.disable()
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(15)
        result["profile"] = text.getvalue()
    return result


def _first_clip(src: Path):
    stage = open_stage(str(src))
    root = api.select_roots(stage, str(src), None)[0]
    return stage, skelio.skeletons_under(root)[0], root, str(src)


def report(r: dict) -> None:
    best = r["best"]
    print(f"\n{r['label']}: {r['src'].name}  {r['joints']} joints x {r['frames']} frames, shifts {' '.join(r['shifts'])}")
    written = "; ".join(f"{p} [{' '.join(sorted(a))}]" for p, a in sorted(r["attrs"].items()))
    print(f"  writes: {written}")
    for name, (t, _) in best.items():
        print(f"  {name:16s} {t * 1e3:9.1f} ms   (layer {r['size'][name] / 1e6:.1f} MB)")
    print(f"  ratio gaze / Sdf copy of every attribute it writes         {best['gaze'][0] / best['copy all'][0]:.2f}x   (goal <= 1.3x)")
    print(f"  ratio gaze --no-guides / Sdf copy of every attribute it writes {best['gaze, no guides'][0] / best['copy anim'][0]:.2f}x")
    print(f"  ratio gaze / Sdf copy of the animation alone (the old floor)   {best['gaze'][0] / best['copy anim'][0]:.2f}x")
    print("  breakdown (ms)         read  map build     model     write     other")
    for name, (total, stages) in best.items():
        parts = [stages.get(k, 0.0) for k in ("read", "map build", "model", "write")]
        print(f"    {name:<16} " + "".join(f"{v * 1e3:10.1f}" for v in parts) + f"{(total - sum(parts)) * 1e3:10.1f}")
    if "profile" in r:
        print("  cProfile, one gaze pass (top by own time):")
        print(textwrap_indent(r["profile"], "    "))


def textwrap_indent(text: str, prefix: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    start = next((i for i, line in enumerate(lines) if "ncalls" in line), 0)
    return "\n".join(prefix + line for line in lines[start:])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=20000)
    parser.add_argument("--joints", type=int, default=100)
    parser.add_argument("--runs", type=int, default=5, help="best of N, gaze and bare interleaved")
    parser.add_argument("--profile", action="store_true", help="cProfile one gaze pass per input")
    parser.add_argument("--keep", type=Path, default=None, help="write the files here instead of a temp folder")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="usdgaze_bench_") as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        rig = _synthetic().make_rig(work / "synthetic.usdc", joints=args.joints, frames=args.frames,
                                    time_codes_per_second=60, turn_deg_per_s=6, mesh=True)
        print(f"generated {rig.path.name}: {len(rig.joints)} joints x {args.frames} frames in {time.perf_counter() - t0:.1f} s")
        results = [bench("cmu", CMU, work, args.runs, args.profile),
                   bench("synthetic", rig.path, work, args.runs, args.profile)]
    for r in results:
        report(r)
    print(f"\nbest of {args.runs}, python {sys.version.split()[0]}, numpy {np.__version__}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
