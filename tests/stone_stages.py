"""Stepping-stone stages for the coupled physics loop, and the gaze-before-lift measure on a written layer.

``walk_stage`` writes a .usda over ``sample_stages/attend/stepping_stones.usda`` (the CMU walk, a
GazeObjectAPI stone at each footfall, each stone's importance 1 from the previous swing start to its
landing, 0.05 otherwise, each also a physics stone) with the animation cropped to a span of seconds
at 30 fps. ``gaze_before_lift`` measures, by UsdSkel FK on the composed layer only, for each stone a
foot steps on: when the written foot that steps on it lifts (the end of that foot's previous
contact in the WRITTEN motion) and whether the line of sight reached the stone before then. Used by
the tests and by benchmarks/bench_physics.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Sdf

from . import measure
from .attend_support import ATTEND, angle_to, compose, gaze, positions

SKEL, ANIM = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_01"
CMU = ATTEND.parent / "cmu" / "cmu_131_01.usdc"
TOES = ("LeftToe", "RightToe")
ON_DEG, ON_M = 5.0, 0.3  # reached: line of sight within 5 deg, or point of sight within 0.3 m (as attend's test)


def walk_body(h: float, first: int = 120, last: int = 300):
    """The CMU walk's MuJoCo body at step ``h`` and its reference over frames ``first:last`` (1.0-2.5 s
    at 120 fps): ``(dyn, ref_q at steps of h, (qpos at the frames, their seconds from the first))``."""
    from usdgaze.physics import build, retarget
    from usdgaze.physics.dynamics import MujocoBody
    from usdgaze.physics.tracking import resample

    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    dyn = MujocoBody(model, h=h)
    frames = clip.seconds[first:last] - clip.seconds[first]
    qpos = retarget.to_qpos(model, ref)[first:last]
    return dyn, resample(qpos, frames, h, dyn), (qpos, frames)


def copy_animation(layer: Sdf.Layer, src: Sdf.Layer, anim: str, codes) -> None:
    """An over of ``anim`` in ``layer`` holding ``src``'s skinning arrays at ``codes`` only (a crop)."""
    prim = Sdf.CreatePrimInLayer(layer, anim)
    prim.specifier = Sdf.SpecifierOver
    for name in ("rotations", "translations", "scales"):
        attr = src.GetPrimAtPath(anim).attributes[name]
        spec = Sdf.AttributeSpec(prim, name, attr.typeName)
        for c in codes:
            value = src.QueryTimeSample(attr.path, c) if src.GetNumTimeSamplesForPath(attr.path) else attr.default
            layer.SetTimeSample(spec.path, float(c), value)


def walk_stage(path: Path, start_s: float, end_s: float, until_lift: bool = False, task: bool = True,
               shift: dict[str, np.ndarray] | None = None, after_s: float = 0.0) -> Path:
    """stepping_stones.usda with the walk cropped to ``[start_s, end_s]`` (30 fps samples; ``after_s``:
    the take's samples go on that much past the playback range's end, as a shot's over its take).

    ``until_lift``: each stone's importance is 1 from the previous swing start until its own foot
    lifts (its ``swingStart``), 0.05 otherwise: the paper's "looked at the selected stone before
    moving the stepping foot to the stone and then looked at the next target stone once the foot
    began to move" (the sample stage keeps a stone important until its landing). ``task=False``
    blocks the stones' ``usdgaze:physics:task`` (they stay objects to look at). ``shift``: stone name ->
    offset (stage units) added to that stone's translation (a stone displaced from the footfall)."""
    src = Sdf.Layer.FindOrOpen(str(CMU))
    tcps = src.timeCodesPerSecond
    a = src.startTimeCode + 4.0 * round(start_s * tcps / 4.0)
    codes = np.arange(a, a + (end_s - start_s) * tcps + 1e-6, 4.0)
    take = np.arange(a, a + (end_s + after_s - start_s) * tcps + 1e-6, 4.0)
    layer = Sdf.Layer.CreateNew(str(path))
    layer.subLayerPaths[:] = [str(ATTEND / "stepping_stones.usda")]
    layer.startTimeCode, layer.endTimeCode = float(codes[0]), float(codes[-1])
    layer.timeCodesPerSecond = layer.framesPerSecond = tcps
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    copy_animation(layer, src, ANIM, take)
    _stone_overs(layer, codes, until_lift, task, shift or {})
    layer.Save()
    return path


def _stone_overs(layer: Sdf.Layer, codes: np.ndarray, until_lift: bool, task: bool, shift: dict) -> None:
    """Overs on stepping_stones.usda's stones: the physics task blocked, the importance until the lift,
    stones displaced."""
    sample = Sdf.Layer.FindOrOpen(str(ATTEND / "stepping_stones.usda"))  # held: its specs live with it
    stones = list(sample.GetPrimAtPath("/Stones").nameChildren)
    swings = [c.attributes["userProperties:swingStart"].default for c in stones]
    for spec, swing in zip(stones, swings):
        over = Sdf.CreatePrimInLayer(layer, spec.path)
        over.specifier = Sdf.SpecifierOver
        if not task:
            Sdf.AttributeSpec(over, "usdgaze:physics:task", Sdf.ValueTypeNames.Token).default = Sdf.ValueBlock()
        if spec.name in shift:
            at = spec.attributes["xformOp:translate"].default
            moved = Sdf.AttributeSpec(over, "xformOp:translate", Sdf.ValueTypeNames.Double3)
            moved.default = tuple(float(a + d) for a, d in zip(at, shift[spec.name]))
        if until_lift:
            rise = max([w for w in swings if w < swing], default=codes[0] - 1)  # the previous swing start
            imp = Sdf.AttributeSpec(over, "gaze:object:importance", Sdf.ValueTypeNames.Float)
            for c in codes:
                layer.SetTimeSample(imp.path, float(c), 1.0 if rise <= c < swing else 0.05)


def contacts(posed: measure.Posed, toe: str, seconds: np.ndarray, floor: float | None = None) -> list[tuple[int, int]]:
    """Frame spans with the toe within 6 cm of its lowest (or of ``floor``) and slower than 0.6 m/s,
    >= 50 ms."""
    p = posed.position(toe)
    h = p @ posed.up
    speed = np.linalg.norm(np.gradient(p - np.outer(h, posed.up), seconds, axis=0), axis=1)
    low = (h < (h.min() if floor is None else floor) + 0.06) & (speed < 0.6)
    edges = np.flatnonzero(np.diff(np.r_[0, low.astype(int), 0]))
    return [(a, b) for a, b in zip(edges[::2], edges[1::2]) if seconds[b - 1] - seconds[a] >= 0.05 - 1e-9]


@dataclass
class StoneGaze:
    stone: str
    toe: str
    lift_s: float  # the written foot leaves its previous contact
    land_s: float  # the written foot's contact on this stone starts
    miss_m: float  # the written toe's mean ground-plane distance to the stone over that contact
    ref_miss_m: float  # the same over the reference's contact on it (the stones test's measure)
    nearest_deg: float  # the line of sight's smallest angle to the stone up to the lift
    first_on_s: float | None  # first time it was reached (up to the lift), None if never
    reached: bool


def _flat(posed: measure.Posed, v: np.ndarray) -> np.ndarray:
    return v - np.outer(v @ posed.up, posed.up)


def _shot_times(src: Path) -> np.ndarray:
    """The walk's sample times inside the stage's playback range (the take may go on past it)."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(src))
    codes = np.array(stage.GetPrimAtPath(ANIM).GetAttribute("rotations").GetTimeSamples())
    return codes[(codes >= stage.GetStartTimeCode() - 1e-9) & (codes <= stage.GetEndTimeCode() + 1e-9)]


def stood_on(tmp: Path, src: Path, out: Path) -> list[tuple[str, str, float, float]]:
    """Per stone stepped on in the reference within the shot (a reference contact within 5 cm of it),
    ``(stone, toe, miss_m, rise_m)``: the written toe's mean ground-plane distance to the stone over the
    reference's contact, and how much higher than the reference's toe it is on average there. Every
    contact, the one from the first frame included, whatever the written foot did before it (unlike
    :func:`gaze_before_lift`, which needs the written foot's lift)."""
    composed = compose(tmp, src, out, "stood_composed.usda")
    times = _shot_times(src)
    ref, sim = measure.posed(str(src), SKEL, times=times), measure.posed(str(composed), SKEL, times=times)
    from pxr import Usd

    stage = Usd.Stage.Open(str(composed))
    seconds = (times - times[0]) / stage.GetTimeCodesPerSecond()
    rows = []
    for prim in stage.Traverse():
        if not prim.GetAttribute("userProperties:landing"):
            continue
        stone = positions(stage, str(prim.GetPath()), times)
        for toe in TOES:
            for a, b in contacts(ref, toe, seconds):
                if np.linalg.norm(_flat(ref, ref.position(toe)[a:b].mean(0) - stone[a])) >= 0.05:
                    continue
                miss = np.linalg.norm(_flat(sim, sim.position(toe)[a:b] - stone[a:b]), axis=1).mean()
                rise = ((sim.position(toe) - ref.position(toe))[a:b] @ sim.up).mean()
                rows.append((prim.GetName(), toe, float(miss), float(rise)))
    return rows


def gaze_before_lift(tmp: Path, src: Path, out: Path, shift: dict[str, np.ndarray] | None = None) -> list[StoneGaze]:
    """Per stone stepped on in the reference (a reference contact within 5 cm of it, less its
    ``shift``), the written contact of the same foot nearest in time and the lift before it; stones
    whose foot is on them from the first frame are left out. The written contacts are low against
    the reference toe's lowest (a written toe that dips into the ground on one frame does not make
    every stance of that foot too high to count)."""
    composed = compose(tmp, src, out, "stones_composed.usda")
    g = gaze(composed, times=_shot_times(src))
    ref, sim = measure.posed(str(src), SKEL, times=g.times), measure.posed(str(composed), SKEL, times=g.times)
    rows = []
    for prim in g.stage.Traverse():
        if not prim.GetAttribute("userProperties:landing"):
            continue
        stone = positions(g.stage, str(prim.GetPath()), g.times)
        footfall = stone[0] - np.asarray((shift or {}).get(prim.GetName(), np.zeros(3)))
        found = [(toe, a, b) for toe in TOES for a, b in contacts(ref, toe, g.seconds)
                 if np.linalg.norm(_flat(ref, ref.position(toe)[a:b].mean(0) - footfall)) < 0.05]
        if not found:
            continue
        toe, ref_land, ref_end = found[0]
        spans = contacts(sim, toe, g.seconds, float((ref.position(toe) @ ref.up).min()))
        i = int(np.argmin([abs(a - ref_land) for a, _ in spans])) if spans else 0
        if i == 0 or abs(g.seconds[spans[i][0]] - g.seconds[ref_land]) > 0.3:
            continue  # on it from the start (or never lifted): no lift to look before
        a, b = spans[i]
        lift = spans[i - 1][1] - 1
        miss = float(np.linalg.norm(_flat(sim, sim.position(toe)[a:b] - stone[a:b]), axis=1).mean())
        ref_miss = float(np.linalg.norm(_flat(sim, sim.position(toe)[ref_land:ref_end] - stone[ref_land:ref_end]),
                                        axis=1).mean())
        ang = angle_to(g, stone)[: lift + 1]
        on = (ang < ON_DEG) | (np.linalg.norm(g.sight - stone, axis=1)[: lift + 1] < ON_M)
        rows.append(StoneGaze(prim.GetName(), toe, float(g.seconds[lift]), float(g.seconds[a]), miss, ref_miss,
                              float(ang.min()), float(g.seconds[int(np.argmax(on))]) if on.any() else None,
                              bool(on.any())))
    return rows
