"""The look pass: gaze at targets, with saccades, pursuit and the gaze map's body cascade (pure numpy).

Input: a clip, its chain and character frame, a gaze map, a list of :class:`Directive` (shift, look,
release) and, for looks, target world positions per frame. Output: a :class:`PassResult` whose eyes
aim, both of them, at a per-frame point of sight, and whose chain follows the map's cascade.

Two controllers share the work, as in people:

* The **body** (pelvis, spine, neck, head) makes gaze shifts through the map (Heck 5.2.3): a shift
  toward a target is requested from the eyes' position in the base motion at that time. While a
  target moves, a new shift starts when the eyes would need more than ``replan_fraction`` of their
  range, aimed where the target will be when the shift ends (its current angular rate carried on).
* The **eyes** move on their own: a main-sequence saccade to the target (:mod:`usdgaze.gaze.saccade`),
  then pursuit of the target's own motion (latency, 100 deg/s cap), catch-up saccades when the error
  passes ``catch_up_deg``. The point of sight is a world point, so the base motion's head bob and the
  body's cascade are cancelled at once (vestibulo-ocular reflex); the eye range clamps what is left,
  so a shift larger than the range arrives as fast as the head brings it.

A target beyond reach (more than ``reach_yaw_deg`` of body turn plus the eye range from the base line
of sight, i.e. behind the character) is let go: a gaze shift back to the base motion's gaze, and a new
shift toward the target once it is within reach again (on either side). See docs/look-at.md; the
directives become body shifts, eye epochs and weight keys in :mod:`usdgaze.passes.directives`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.rig import CharacterFrame, Chain
from usdgaze.errors import UsdGazeError
from usdgaze.gaze import saccade
from usdgaze.passes import eyes as eyes_mod
from usdgaze.passes.body import CachedMap
from usdgaze.passes.directives import KINDS, Directive, Epoch, gaze_weights, plan_directives
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.aim import OVER_THE_POLE, reach_warnings
from usdgaze.passes.assemble import finish
from usdgaze.passes.chain import move_body, prepare
from usdgaze.passes.hidden import held_world, hold_visible, restore
from usdgaze.passes.options import PassOptions, PassResult, Shift
from usdgaze.passes.schedule import Schedule, Scheduler, schedule
from usdgaze.passes.sight import azimuth_elevation, direction_from
from usdgaze.values import MAX_TARGET_DISTANCE_M

EYE_TIMINGS = ("saccade", "model")
NEAR_POINT_M = 0.1  # an adult's near point of focus, about: nothing nearer is fixated as a point


@dataclass(frozen=True)
class LookOptions:
    eye_timing: str = "saccade"
    """``saccade``: main-sequence eyes; ``model``: the eyes follow the map's gaze progress (the paper)."""
    pursuit_latency_s: float = 0.15
    pursuit_max_deg_s: float = saccade.MAX_PURSUIT_DEG_S
    catch_up_deg: float = 1.0
    """Pursuit error that fires a catch-up saccade."""
    refractory_s: float = 0.2
    """Least time from the end of one saccade to the next (Eom et al.: 200 ms)."""
    replan_fraction: float = 0.7
    """A new body shift starts when the eyes would need this fraction of their range."""
    replan_interval_s: float = 0.2
    """Least time between two body shifts toward one moving target."""
    anticipation_s: float = 0.4
    """A new body shift starts this much before the eyes would need it (the base motion is known)."""
    reach_yaw_deg: float = 150.0
    """Largest body turn (line-of-sight change before the eyes) toward a target."""
    reach_pitch_deg: float = 80.0
    comfort_fraction: float = 0.5
    body_pace_deg_s: float = 450.0
    """A body shift toward a moving target turns each segment against its parent at most this fast."""
    """When the map's own head share would leave the eyes beyond this fraction of their range, the
    body turns further, to bring them back to it."""



# -- geometry ----------------------------------------------------------------------------------------

def to_world(clip: SkelClip, p: np.ndarray) -> np.ndarray:
    m = clip.skel_to_world
    return np.einsum("fij,fj->fi", np.broadcast_to(m[:, :3, :3], (len(p), 3, 3)), p) + np.broadcast_to(
        m[:, :3, 3], p.shape)


def to_skel(clip: SkelClip, p: np.ndarray) -> np.ndarray:
    # A frame the character is scaled to nothing on maps as the pass held it (see passes.hidden).
    inv = np.linalg.inv(held_world(clip.skel_to_world))
    return np.einsum("fij,fj->fi", np.broadcast_to(inv[:, :3, :3], (len(p), 3, 3)), p) + np.broadcast_to(
        inv[:, :3, 3], p.shape)


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = rot.length(v)
    return v / np.where(d > 0, d, 1.0)[..., None], d


POLE_BAND_DEG = 15.0
"""Within this of the vertical a target's azimuth says little of its direction (at 89 deg, 10 deg of
azimuth are 0.2 deg of arc) and whirls as the eyes bob under it: it is asked for in proportion."""


def _relative(points: np.ndarray, eye: np.ndarray, base_ae: np.ndarray, up: np.ndarray, too_near: np.ndarray) -> np.ndarray:
    """Target (azimuth, elevation) from ``eye`` against the base line of sight, yaw wrapped; on the
    frames ``too_near`` (nearer than the near point) it is out of reach, as if straight behind.

    Within ``POLE_BAND_DEG`` of the vertical the azimuth counts in proportion to the distance from it
    (all of it at the band's edge, none overhead): by azimuth alone, a target straight above a standing
    character was behind it, then ahead, as the head bobbed, and let go and taken up again 16 times in
    9 s (the eyes 33 deg a frame). The eyes, aimed at the target itself, take what the body leaves.
    """
    ae = azimuth_elevation(points - eye, up)
    share = np.clip((90.0 - np.abs(ae[:, 1])) / POLE_BAND_DEG, 0.0, 1.0)  # of the azimuth asked for
    ae -= base_ae
    ae[:, 0] = (ae[:, 0] + 180.0) % 360.0 - 180.0
    ae[:, 0] *= share
    # No eye fixates nearer than its near point, and a target crossing the head swings its direction
    # through the back of it within a few frames (pursued, 55 deg in a frame): let go until it is out.
    ae[too_near, 0] = 180.0
    return ae


NEAR, INSIDE = 1, 2
"""Why a target is out of reach on a frame though not behind: nearer than the eyes' near point, or
inside the head (nearer the head joint than the eyes are)."""


def _too_near(points: np.ndarray, eye: np.ndarray, head: np.ndarray, sight: np.ndarray, near: float) -> np.ndarray:
    """Per frame, ``NEAR``, ``INSIDE`` or 0. Inside the head: behind the eyes (against the base line of
    ``sight``) and nearer the head joint than they are. A point there turns with the head, so no turn of
    the body brings it into view: one at the head joint, 11 cm behind the eyes, was taken up by 150 deg
    turns cut short every few frames as the bobbing head brought it across the near point."""
    with np.errstate(over="ignore", invalid="ignore"):  # 1e300 away is refused by _check_distance
        behind = np.einsum("fi,fi->f", points - eye, sight) < 0.0
        inside = behind & (rot.length(points - head) < rot.length(eye - head))
        return np.where(inside, INSIDE, np.where(rot.length(points - eye) < near, NEAR, 0)).astype(np.int8)


# -- the pass ----------------------------------------------------------------------------------------

def _check(clip: SkelClip, directives: list[Directive], targets: list[np.ndarray], opts: LookOptions) -> None:
    if opts.eye_timing not in EYE_TIMINGS:
        raise UsdGazeError(f"eye timing '{opts.eye_timing}': expected one of {', '.join(EYE_TIMINGS)}")
    for a, b in zip(directives, directives[1:]):
        if a.time_s == b.time_s:
            what = "shifts" if a.kind == b.kind == "shift" else "directives"
            raise UsdGazeError(f"{clip.where()}: two {what} at the same time {a.time_s:g} s")
    for d in directives:
        if d.kind not in KINDS:
            raise UsdGazeError(f"{clip.where()}: directive kind '{d.kind}': expected one of {', '.join(KINDS)}")
        if d.kind == "look" and not 0 <= d.target < len(targets):
            raise UsdGazeError(f"{clip.where()}: look at {d.time_s:g} s names target {d.target}, "
                               f"but there are {len(targets)}")
        if not (0.0 <= d.weight <= 1.0 and d.blend_s >= 0.0):
            raise UsdGazeError(f"{clip.where()}: directive at {d.time_s:g} s: weight must lie in [0, 1] "
                               f"and blend be >= 0 (got {d.weight:g}, {d.blend_s:g} s)")


def _check_distance(clip: SkelClip, directives: list[Directive], targets, eye: np.ndarray, names) -> None:
    """A target at the eyes has no direction: refuse it where it is looked at."""
    seconds = clip.seconds
    near = 0.01 / clip.meters_per_unit
    for k, d in enumerate(directives):
        if d.kind != "look":
            continue
        end = directives[k + 1].time_s if k + 1 < len(directives) else np.inf
        rows = (seconds >= d.time_s) & (seconds < end)
        with np.errstate(over="ignore", invalid="ignore"):  # 1e300 away: the distance overflows, said below
            dist = np.linalg.norm(targets[d.target][rows] - eye[rows], axis=-1)
        name = names[d.target] if names else f"target {d.target}"
        if len(dist) and not dist.max() * clip.meters_per_unit <= MAX_TARGET_DISTANCE_M:
            raise UsdGazeError(f"{clip.where()}: look target {name} lies over {MAX_TARGET_DISTANCE_M:g} m "
                               "from the eyes; aim at a point nearer than that in the same direction")
        if len(dist) and dist.min() < near:
            i = np.flatnonzero(rows)[np.argmin(dist)]
            raise UsdGazeError(f"{clip.where()}: look target {name} lies at the eyes at time code "
                               f"{clip.times[i]:g} ({dist.min() * clip.meters_per_unit * 100:.1f} cm away); "
                               "nothing to look at")


def _model_progress(gaze_map, seconds: np.ndarray, eye: np.ndarray, up: np.ndarray):
    """Gaze progress of a lone map shift of the same change, for ``eye_timing model``."""
    def progress(i0: int, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        a = azimuth_elevation(start - eye[i0], up)
        b = azimuth_elevation(goal[i0] - eye[i0], up)
        change = b - a
        change[0] = (change[0] + 180.0) % 360.0 - 180.0
        plan = schedule(gaze_map, [Shift(float(seconds[i0]), *change)], seconds)
        return np.where(plan.settled, 1.0, plan.progress)[i0:]
    return progress


def _goals(epochs: list[Epoch], targets, scene: eyes_mod.Scene, base_ae: np.ndarray, up: np.ndarray,
           fixation: float, reach_deg: float) -> list[tuple[int, eyes_mod.Goal]]:
    """The eyes' goals, one per planner event. ``reach_deg``: the furthest a line of sight turns (half a
    turn plus the eye range); a shift asking for more aims there, on its side (360 deg aimed straight
    ahead, and the eyes turned away from the head's turn: 100.7 deg reached where 300 reaches 190)."""
    events = []
    held = 0.0  # the azimuth change (deg) the eyes hold against the base's, as asked; None on a target
    # Every direction goal writes its points into this one array, on the frames it is the eyes' goal
    # (from its event to the next: all the eyes read of it); one array each, of the whole clip, had
    # made 1,000 shifts on 100,000 frames hold 3 GB.
    directions = scene.base_point.copy()
    asked: list[tuple[int, float, float]] = []
    for epoch in epochs:
        d = epoch.directive
        for frame, kind, cut in epoch.events:
            wanted = d.yaw if kind == "direction" else 0.0 if kind == "base" else None
            # Which way round a shift of over 90 deg goes is the request's (a right turn of 179 deg is no
            # left turn of 181), and a release goes back the way the shift came.
            turn = 0.0 if wanted is None else wanted - (held if held is not None else 0.0)
            held = wanted
            if kind == "target":
                points = targets[d.target]
            elif kind == "direction":
                points = directions
                asked.append((len(events), float(np.clip(d.yaw, -reach_deg, reach_deg)), d.pitch))
            else:
                points = scene.base_point
            # A shift's goal more than 90 deg round is behind the head until the head turns to it; one
            # asking less is behind it only past the head's pole.
            side = 0.0 if kind != "direction" else float(np.sign(d.yaw)) if abs(d.yaw) > 90.0 else OVER_THE_POLE
            events.append((frame, eyes_mod.Goal(kind, points, cut, turn, side)))
    # The frames the eyes read each direction goal on (see point_of_sight): from its event to the
    # next, so no two overlap; the directions of all of them at once (each frame's are its own).
    if not asked:
        return events
    asked_ae, rows = np.zeros((len(base_ae), 2)), np.zeros(len(base_ae), dtype=bool)
    for k, yaw, pitch in asked:
        i0 = events[k][0]
        i1 = events[k + 1][0] if k + 1 < len(events) else len(base_ae)
        asked_ae[i0:i1], rows[i0:i1] = (yaw, pitch), True
    rows = np.flatnonzero(rows)
    ae = base_ae[rows] + asked_ae[rows]
    ae[:, 1] = np.clip(ae[:, 1], -89.0, 89.0)
    directions[rows] = scene.eye[rows] + fixation * direction_from(ae, up)
    return events


def apply_look(clip: SkelClip, chain: Chain, frame: CharacterFrame, gaze_map: ParametricGazeMap,
               directives: list[Directive], targets: list[np.ndarray] | None = None,
               options: PassOptions = PassOptions(), look: LookOptions = LookOptions(),
               target_names: list[str] | None = None) -> PassResult:
    """Run the look pass on one clip; ``targets`` are world positions ``(F, 3)`` per look target."""
    targets = [np.asarray(t, dtype=float) for t in (targets or [])]
    directives = sorted(directives, key=lambda d: d.time_s)
    _check(clip, directives, targets, look)
    clip, hidden = hold_visible(clip, chain)
    seconds = clip.seconds
    base = prepare(clip, chain, frame, options)
    rig, up = base.rig, base.up
    # Where look targets are seen from: the base motion's eyes (shifts alone never ask).
    head_b, eye_b = (to_world(clip, p) for p in base.head_and_eyes()) if targets else (None, None)
    _check_distance(clip, directives, targets, eye_b, target_names)
    near = NEAR_POINT_M / clip.meters_per_unit
    too_near = {k: _too_near(t, eye_b, head_b, base.line_of_sight, near) for k, t in enumerate(targets)}
    rel = {d.target: _relative(targets[d.target], eye_b, base.ae, up, too_near[d.target] > 0)
           for d in directives if d.kind == "look"}

    gaze_map = CachedMap(gaze_map)  # the planner asks for the same shifts again and again
    scheduler = Scheduler(gaze_map, seconds)
    shifts, epochs, keys = plan_directives(gaze_map, directives, seconds, rel, base.ae, options.eye_range, look, scheduler)
    plan = scheduler.plan(shifts)
    weight = gaze_weights(keys, seconds, _base_shown(directives, seconds, plan))
    full = weight >= 1.0
    part = np.flatnonzero(~full)  # most shots hold full weight throughout: scale only the other frames
    disp = plan.displacement
    if len(part):
        disp[part] = rot.power(disp[part], weight[part, None])
    body = move_body(base, chain, frame, disp)
    eye_m = to_world(clip, body.eye_centre(rig))
    fixation = options.fixation_m / clip.meters_per_unit
    scene = eyes_mod.Scene(seconds, eye_m, eye_m + fixation * base.line_of_sight, up, near)

    sight = _sight(gaze_map, directives, plan, epochs, targets, base, scene, fixation, options, look)
    wanted_point = _weighted_point(sight, base, scene, weight, fixation)
    result = finish(clip, chain, frame, base, body, plan, to_skel(clip, wanted_point), options,
                    saccading=sight.saccading, side=sight.side)
    # The eyes were sent toward the request after the +-89 deg elevation cap; a shift's hold is judged
    # (hold error, reach warnings) against what was asked, so a request the cap cuts short is said.
    for d, end in _shift_spans(directives):  # frames at full gaze weight only: a partial weight asks for less
        result.requested[(seconds >= d.time_s) & (seconds < end) & result.settled & full] = [d.yaw, d.pitch]
    result.warnings = _warnings(clip, directives, epochs, result, base.ae, options, target_names or [], too_near, up)
    return restore(result, hidden, clip)


def _sight(gaze_map, directives: list[Directive], plan, epochs, targets: list[np.ndarray], base, scene,
           fixation: float, options: PassOptions, look: LookOptions):
    """The eyes' point of sight per frame (:class:`eyes_mod.Sight`), at full gaze weight."""
    up, eye_m = base.up, scene.eye
    if look.eye_timing == "model" and not any(d.kind == "look" for d in directives):
        # The paper's eyes: the wanted line of sight follows the map's gaze progress.
        ae = base.ae + plan.requested
        ae[:, 1] = np.clip(ae[:, 1], -89.0, 89.0)
        wide = np.abs(plan.requested[:, 0]) > 90.0
        return eyes_mod.Sight(eye_m + fixation * direction_from(ae, up), ~plan.settled, [],
                              np.where(wide, np.sign(plan.requested[:, 0]), 0.0))
    model = _model_progress(gaze_map, scene.seconds, eye_m, up) if look.eye_timing == "model" else None
    goals = _goals(epochs, targets, scene, base.ae, up, fixation, 180.0 + options.eye_range.yaw)
    return eyes_mod.point_of_sight(scene, goals, look, model)


def _weighted_point(sight, base, scene, weight: np.ndarray, fixation: float) -> np.ndarray:
    """The point the eyes are sent to: partial gaze turns toward the base line of sight (and the
    fixation distance) as the weight falls."""
    eye_m = scene.eye
    direction, distance = _unit(sight.point - eye_m)
    part = np.flatnonzero(weight < 1.0)
    if len(part):
        direction[part] = saccade.slerp(base.line_of_sight[part], direction[part], weight[part])
    distance = np.maximum(distance, scene.near)  # nearer, each eye would turn to its own side of the point
    inv = np.where(weight >= 1.0, 1.0 / distance, (1.0 - weight) / fixation + weight / distance)
    return eye_m + direction / inv[:, None]


def _base_shown(directives: list[Directive], seconds: np.ndarray, plan: Schedule) -> np.ndarray:
    """Frames that show the base motion's own gaze: before the first directive, and where a release
    has brought the body back and it has settled (the time-sorted ``directives``)."""
    latest = np.searchsorted([d.time_s for d in directives], seconds, side="right") - 1
    shown = latest < 0
    # Only frames after a release can be back at rest: the others are not measured.
    rows = np.flatnonzero(~shown)
    rows = rows[np.array([d.kind == "release" for d in directives], dtype=bool)[latest[rows]]]
    shown[rows] = np.all(np.abs(plan.displacement[rows] - rot.IDENTITY) < 1e-9, axis=(1, 2)) & plan.settled[rows]
    return shown


def _miss_deg(base_ae: np.ndarray, achieved: np.ndarray, requested: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Degrees between the achieved and the requested line of sight, per frame (changes against ``base_ae``)."""
    a, b = direction_from(base_ae + achieved, up), direction_from(base_ae + requested, up)
    return np.degrees(np.arccos(np.clip(rot.dot(a, b), -1.0, 1.0)))


def _shift_spans(directives: list[Directive]) -> list[tuple[Directive, float]]:
    """Each shift of the time-sorted ``directives`` and when the next directive starts (its hold's end)."""
    ends = [d.time_s for d in directives[1:]] + [np.inf]
    return [(d, end) for d, end in zip(directives, ends) if d.kind == "shift"]


def _warnings(clip: SkelClip, directives: list[Directive], epochs: list[Epoch], result: PassResult,
              base_ae: np.ndarray, options: PassOptions, names: list[str], too_near: dict, up: np.ndarray) -> list[str]:
    """Shifts that miss their request once settled; targets that went out of reach (``too_near``:
    per target and frame, ``NEAR``, ``INSIDE`` or 0)."""
    shifts = [(Shift(d.time_s, d.yaw, d.pitch), end) for d, end in _shift_spans(directives)]
    plan = Schedule(np.empty(0), result.requested, result.settled, [])
    out = reach_warnings(clip, [s for s, _ in shifts], plan, base_ae, result.achieved, result.eye_angles,
                            options, ends=[e for _, e in shifts])
    seconds = clip.seconds
    for epoch in epochs:
        d = epoch.directive
        if d.kind != "look":
            continue
        name = names[d.target] if d.target < len(names) else f"target {d.target}"
        end = next((e.start for e in epochs if e.start > epoch.start), len(seconds))
        rows = np.zeros(len(seconds), dtype=bool)
        rows[epoch.start:end] = True
        for f, kind, _ in epoch.events:  # only while the target is held, not while let go
            if kind == "base":
                rows[f:end] = False
        # The angle between the lines, not the norm of (azimuth, elevation) differences: near the
        # vertical an azimuth means little (a target overhead 'missed by 269 deg').
        miss = _miss_deg(base_ae, result.achieved, result.requested, up)
        held = rows & result.settled
        if np.any(held) and miss[held].max() > options.tolerance_deg:
            out.append(f"{clip.where()}: look at {name} from {d.time_s:g} s: the line of sight misses the target "
                       f"by up to {miss[held].max():.1f} deg on {int((miss[held] > options.tolerance_deg).sum())} "
                       f"frames (the eyes at their range: yaw +-{options.eye_range.yaw:g}, up "
                       f"{options.eye_range.up:g}, down {options.eye_range.down:g} deg, and the body turns no further)")
        back = [seconds[f] for f, kind, _ in epoch.events[1:] if kind == "target"]
        for f in (f for f, kind, _ in epoch.events if kind == "base"):
            t = seconds[f]
            again = next((b for b in back if b > t), None)
            why = {NEAR: f"nearer than the eyes' near point, {NEAR_POINT_M * 100:g} cm",
                   INSIDE: "inside the character's head"}.get(int(too_near[d.target][f]), "behind the character")
            out.append(f"{clip.where()}: look at {name} from {d.time_s:g} s: the target is out of reach "
                       f"({why}) at {t:g} s; the gaze returns to the base motion's"
                       + (f" and takes the target up again at {again:g} s" if again is not None else ""))
    return out
