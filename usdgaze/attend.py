"""The Python API of ``usdgaze attend``: read stage -> clip + objects -> visuomotor loop -> layer."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from usdgaze import __version__
from usdgaze.errors import UsdGazeError
from usdgaze.vision import loop
from usdgaze.vision.costs import Weights
from usdgaze.files.kinds import require_file
from usdgaze.values import MAX_ALPHA

if TYPE_CHECKING:
    from usdgaze.core.hints import BindHints


# Options of one mode of ``usdgaze attend`` only (the CLI's parameter names, the manifest's keys): given
# in the other mode they would be ignored, so the CLI and ``usdgaze batch`` refuse them.
KINEMATIC_ONLY = ("objects", "alpha", "cost", "realize")
PHYSICS_ONLY = ("discard_failed", "threads", "fd_stride", "fd_reuse", "iterations", "retry_iterations",
                "timestep", "raw_contacts", "mass")


@dataclass
class AttendSettings:
    """What ``usdgaze attend`` takes besides its files (see docs/attend.md)."""

    alpha: float = 0.2
    alpha_per_second: bool = True  # Q = alpha h I a step; False: the literal alpha I a step (docs/attend.md)
    cost: str = "uncertainty"
    window_s: float = 0.8
    h: float = 0.025
    seed: int = 0
    eta: float = 0.3
    max_tracked: int = 4
    iterations: int = 3
    realize: str = "direct"  # "direct": the planner's eyes and chain; "map": its fixations through the gaze map
    binding: BindHints | None = None  # --bind/--forward: win over the SkelRoot's GazeMapAPI bindings, as in apply

    def check(self) -> None:
        if not np.isfinite(self.alpha) or self.alpha < 0:
            raise UsdGazeError(f"--alpha {self.alpha:g}: the process noise must be >= 0")
        if self.alpha > MAX_ALPHA:  # values.MAX_ALPHA says why; batch manifests have the same bound
            raise UsdGazeError(f"--alpha {self.alpha:g}: over {MAX_ALPHA:g} an unwatched object's position spreads by "
                               "over 1 m in a second, a belief that knows nothing (the paper uses 0.2)")
        if self.cost not in loop.MODES:
            raise UsdGazeError(f"--cost {self.cost}: expected one of {', '.join(loop.MODES)}")
        if not np.isfinite(self.h) or not 0.005 <= self.h <= 0.1:
            raise UsdGazeError(f"planner step {self.h:g} s: expected 0.005-0.1 s (the paper uses 0.02-0.03)")
        if not np.isfinite(self.window_s):  # inf was called shorter than two steps
            raise UsdGazeError(f"--window {self.window_s:g} s: expected {2 * self.h:g} to 5 s (the paper uses 0.6-1.2 s)")
        if self.window_s < 2 * self.h - 1e-9:
            raise UsdGazeError(f"--window {self.window_s:g} s: shorter than two planner steps (2 x {self.h:g} s)")
        if self.realize not in ("direct", "map"):
            raise UsdGazeError(f"--realize {self.realize}: expected direct or map")
        if self.window_s > 5.0:
            raise UsdGazeError(f"--window {self.window_s:g} s: longer than 5 s (the paper uses 0.6-1.2 s)")

    def loop_options(self) -> loop.LoopOptions:
        return loop.LoopOptions(alpha=self.alpha, alpha_per_second=self.alpha_per_second, eta=self.eta, h=self.h, window_s=self.window_s, mode=self.cost,
                                seed=self.seed, max_tracked=self.max_tracked, iterations=self.iterations,
                                weights=Weights())


@dataclass
class AttendReport:
    output: str
    characters: list[dict] = field(default_factory=list)
    objects: list[dict] = field(default_factory=list)
    planner: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    results: list = field(default_factory=list, repr=False)


def attend(input_path: str | os.PathLike, out: str | os.PathLike, objects: list[str] | None = None,
           settings: AttendSettings | None = None, skel_root: str | None = None, progress=None,
           no_clobber: bool = False, record: dict | None = None, make_folders: bool = False) -> AttendReport:
    """Synthesize attention-driven eye, head and upper-spine motion; write ``out``. Nothing on failure.

    ``record``: extra entries for the layer's ``customLayerData["usdgaze"]`` (a batch resume key);
    ``make_folders``: create ``out``'s folder (kept only if the command succeeds)."""
    from usdgaze.files.transaction import Outputs

    settings = settings or AttendSettings()
    settings.check()
    source = str(input_path)
    require_file(source)
    with Outputs(no_clobber=no_clobber) as tx:
        from usdgaze.api import _open_input
        from usdgaze.usd.layers import check_output_path

        tx.read(source)  # first, so a clash names the input as such
        if make_folders:
            tx.make_folder(Path(out).parent)
        out_path = tx.claim(check_output_path(out), "--out")
        stage = _open_input(tx, source)
        tx.check_replaceable()  # every input recorded: before the work
        report, layer = _attend(stage, source, out_path, objects, settings, skel_root, progress, record)
        tx.stage_layer(out_path, layer)
    return report


def _attend(stage, source, out_path, objects, settings, skel_root, progress, record=None):
    from usdgaze.characters import select_roots
    from usdgaze.usd.attendio import add_inspection
    from usdgaze.usd.layers import build_override, composed_override_notes, layer_info
    from usdgaze.usd.objects import object_prims, objects_of
    from usdgaze.usd.skelio import animations_elsewhere

    prims = object_prims(stage, source, objects)
    roots = select_roots(stage, source, skel_root)
    others = animations_elsewhere(stage, roots)
    # A character's own SkelRoot (or a prim holding it) moves with it: the others look at it, it does not.
    per_root = objects_of(prims, roots, source)
    report = AttendReport(output=str(out_path))
    report.warnings.extend(composed_override_notes(stage, source))
    overrides, inspections = [], []
    t_start, cpu_start = time.perf_counter(), time.process_time()
    steps = frames = 0
    for root, mine in zip(roots, per_root):
        override, inspection, result = _plan_character(stage, source, root, mine, others, settings, progress, report)
        overrides.append(override)
        inspections.append(inspection)
        steps += len(result.planner_times)
        frames += len(inspection[1])
    report.planner = _planner_summary(report.results, steps, frames, time.perf_counter() - t_start,
                                      time.process_time() - cpu_start, settings)
    info = layer_info(stage)
    info.custom = {"usdgaze": {"version": __version__, "input": os.path.basename(source), "command": "attend",
                               "characters": sorted({c["skel_root"] for c in report.characters}),
                               "objects": [str(p.GetPath()) for p in prims], "alpha": settings.alpha,
                               "cost": settings.cost, "window_s": settings.window_s, "seed": settings.seed,
                               **(record or {})}}
    layer = build_override(overrides, info, fmt=out_path.suffix.lstrip("."))
    for character, times, result, paths in inspections:
        add_inspection(layer, character, times, result.sight_world, result.eye_pose, paths,
                       result.estimates_world, result.uncertainty)
    return report, layer


def _plan_character(stage, source, root, mine, others, settings, progress, report):
    """Plan one SkelRoot's first character (its first Skeleton that binds) looking at its objects ``mine``: (its
    override, its inspection's (character, times, result, object paths), the planner's result); ``report``
    gets its warnings and summary."""
    from usdgaze.characters import bind_root, first_character
    from usdgaze.passes.attend import apply_attend, planner_times
    from usdgaze.passes.take import cut_to_range, through_take, with_ahead
    from usdgaze.usd.layers import AnimOverride
    from usdgaze.usd.objects import read_objects
    from usdgaze.usd.skelio import check_not_shared, read_clip, skeletons_under

    skels = skeletons_under(root)
    if not skels:
        raise UsdGazeError(f"{source}:{root.GetPath()}: no Skeleton under this SkelRoot")
    # A shot over a longer take (a playback range inside the animation) is planned over its range,
    # as --physics simulates it: planned from the take's first frame, objects were reported first
    # seen before the shot (-4.00 s on stepping_stones_shot.usda) and 5 times the frames were planned.
    ahead_s = settings.window_s + 2 * settings.h  # the take after it, for the planner's last windows

    def read_and_bind(skel):
        clip, ahead, take = cut_to_range(read_clip(stage, skel, root, source), stage, ahead_s, ("planned", "plan"))
        return clip, ahead, take, bind_root(clip, root, settings.binding)  # as apply: hints, GazeMapAPI, names

    skel, (clip, ahead, take, (chain, frame)), notes = first_character(root, skels, source, read_and_bind)
    report.warnings.extend(notes)  # a face's skeleton listed before the body's is no character
    check_not_shared(others, clip.animation, source)
    report.warnings.extend(clip.notes)
    if len(skels) - len(notes) > 1:  # its inspection and report are the SkelRoot's: one character, one pair of eyes
        report.warnings.append(f"{source}:{root.GetPath()}: {len(skels)} Skeletons under this SkelRoot; attend "
                               f"plans the first, {skel.GetPath()}, and leaves the others as they are")
    if frame.note:
        report.warnings.append(frame.note)
    codes = clip.start_time + planner_times(clip.seconds, settings.h) * clip.time_codes_per_second
    objs = read_objects(stage, source, mine, codes, clip.meters_per_unit, report.warnings)
    things = [loop.Thing(o.path, o.positions, o.importance, o.view_radius, o.kind, visible=o.visible) for o in objs]
    # Windows near a shot's end see the take go on, not the shot's last pose held.
    result = apply_attend(with_ahead(clip, ahead, take), chain, frame, things, settings.loop_options(), progress,
                          frames=None if ahead is None else len(clip.times))
    report.warnings.extend(result.warnings)
    written = result
    if settings.realize == "map":
        written = _realize_map(stage, source, root, clip, chain, frame, mine, result, settings.h)
    # A realized map moves the pelvis like apply does: its leg roots' translations come with it.
    override = AnimOverride.of(clip, written, move_roots=settings.realize == "map" and bool(chain.leg_roots))
    report.results.append(result)
    seen = [_object_summary(o.path, result, j) for j, o in enumerate(objs)]  # by this character's eyes
    report.characters.append({"skel_root": clip.skel_root, "animation": clip.animation, "frames": len(clip.times),
                              "added_joints": written.added_joints,
                              "changed_joints": [j.rsplit('/', 1)[-1] for j in written.changed_joints],
                              "objects": seen})
    report.objects.extend({"skel_root": clip.skel_root, **o} for o in seen)
    override = override if take is None else through_take(override, take, clip)  # the take's own outside
    return override, (clip.skel_root, clip.times, result, [o.path for o in objs]), result


def _planner_summary(results: list, steps: int, frames: int, wall: float, cpu: float, settings) -> dict:
    """The report's planner figures: steps, speed, iterations, whether every solve's cost fell."""
    solves = [c for r in results for c in r.loop.solves]
    return {
        "steps": steps, "frames": frames, "seconds": round(wall, 3), "cpu_seconds": round(cpu, 3),
        "frames_per_second": round(frames / wall, 1) if wall > 0 else None,
        "frames_per_cpu_second": round(frames / cpu, 1) if cpu > 0 else None,
        "mean_iterations": round(float(np.mean([len(c) - 1 for c in solves])), 2) if solves else 0,
        "cost_monotone": bool(all(np.all(np.diff(c) <= 0) for c in solves)),
        "window_s": settings.window_s, "h": settings.h, "alpha": settings.alpha, "cost": settings.cost,
        "seed": settings.seed, "realize": settings.realize,
    }


def _realize_map(stage, source, root, clip, chain, frame, prims, result, h):
    """The planner's fixations as look directives, realized by the look pass through the gaze map."""
    from usdgaze.characters import built_map, own_map
    from usdgaze.gaze.defaults import default_definition
    from usdgaze.passes.look import Directive, apply_look
    from usdgaze.usd.objects import read_objects

    definition = own_map(root, source) or default_definition()
    targets = [o.positions for o in read_objects(stage, source, prims, clip.times, 1.0)]  # stage units
    t0 = float(result.planner_times[0])  # fixations count from the planner's first step, directives from the stage's start
    directives = [Directive(t0 + t, "look", target=j) if j >= 0 else Directive(t0 + t, "release")
                  for t, j in loop.fixations(result.loop, h)]
    if not directives:
        directives = [Directive(t0, "release")]
    return apply_look(clip, chain, frame, built_map(definition), directives, targets,
                      target_names=[str(p.GetPath()) for p in prims])


def _object_summary(path: str, result, j: int) -> dict:
    lp = result.loop
    seen = lp.visible[:, j]
    first = float(result.planner_times[np.argmax(seen)]) if seen.any() else None
    return {"path": path, "first_seen_s": first, "tracked_share": round(float(np.mean(~np.isnan(lp.sigma_p[:, j]))), 3)}
