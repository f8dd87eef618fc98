"""The composed result of a gaze pass, as arrays: the input with the override layer as its strongest
sublayer, opened in memory (neither file is touched), posed by forward kinematics for every frame.

This is the one reader behind ``usdgaze plot``, ``usdgaze preview`` and ``apply --plot``: it turns a
stage and a layer into numpy arrays; everything downstream (:mod:`usdgaze.review.analysis`, the
plots, the renderer) works on arrays only.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.kinematics import world_matrices
from usdgaze.core.rig import Chain, CharacterFrame
from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.usd.stage import open_root
from usdgaze.files.kinds import not_a_file

EYE_RANGE_KEY = "eyeRange"
"""``customLayerData["usdgaze"]["eyeRange"]``: the eye-in-head limits the pass used (degrees)."""


@dataclass
class Posed:
    """One skeleton's joints over frames: local rotations, stage-space positions, and the world axes
    of the joints a review measures (head and eyes): all joints' 4x4 world matrices of a long shot
    had been most of the review's memory."""

    local_q: np.ndarray
    """Local rotations ``(F, J, 4)`` (x, y, z, w)."""
    positions: np.ndarray
    """Stage-space joint positions ``(F, J, 3)``."""
    world_axes: dict[int, np.ndarray]
    """Joint index -> the upper 3x3 of its column-vector world matrix ``(F, 3, 3)`` (rotation and scale)."""

    def axes(self, joint: int) -> np.ndarray:
        """The world axes ``(F, 3, 3)`` of ``joint`` (one of those posed with its axes)."""
        return self.world_axes[joint]


@dataclass
class CharacterReview:
    """Base and gaze poses of one skeleton on the composed stage, with what the pass recorded."""

    skel_root: str
    skeleton: str
    joints: list[str]
    parents: np.ndarray
    seconds: np.ndarray
    base: Posed
    gaze: Posed
    chain: Chain
    frame: CharacterFrame
    neutral_world: np.ndarray
    """Skeleton-space neutral (bind, else rest) pose ``(J, 4, 4)``: where head and eyes look ahead."""
    skel_to_world: np.ndarray
    """``(F, 4, 4)`` or ``(1, 4, 4)``."""
    up: np.ndarray
    meters_per_unit: float

    looks: list["Look"] = field(default_factory=list)
    """The look-at directives of the SkelRoot's GazeScheduleAPI, with their targets sampled."""

    @property
    def eyes(self) -> tuple[int, int] | None:
        return self.chain.eyes


@dataclass
class Look:
    """One look-at directive: what, from when to when (seconds), where it is on every frame."""

    label: str
    start_s: float
    end_s: float
    positions: np.ndarray
    """Target world positions ``(F, 3)`` at the clip's samples."""


@dataclass
class Attention:
    """An attend run's inspection prims for one character (``/UsdGazeAttend/<character>``)."""

    name: str
    seconds: np.ndarray
    point_of_sight: np.ndarray
    """``(F, 3)`` stage units."""
    objects: dict[str, np.ndarray]
    """Object prim path -> world position ``(F, 3)`` (the estimate where the prim cannot be sampled)."""
    uncertainty: dict[str, np.ndarray]
    """Object prim path -> the belief's position uncertainty ``(F,)`` (NaN while not tracked)."""


@dataclass
class Review:
    """What ``usdgaze plot`` and ``usdgaze preview`` draw: every character, plus the layer's record."""

    input: str
    layer: str
    characters: list[CharacterReview] = field(default_factory=list)
    shifts: list[tuple[float, float, float]] = field(default_factory=list)
    """(seconds from the stage start, yaw, pitch) as recorded in the layer."""
    eye_range: dict[str, float] = field(default_factory=dict)
    eye_range_recorded: bool = False
    """False for layers written before the limits were recorded (the defaults are shown then)."""
    fixation_m: float | None = None
    attention: list[Attention] = field(default_factory=list)


def _may_touch(skel, touched: set[str]) -> bool:
    """Whether the layer's prims include ``skel``'s bound animation or anything under it (an animation
    the layer defined for a skeleton that had none)."""
    from pxr import UsdSkel

    targets = UsdSkel.BindingAPI(skel.GetPrim()).GetAnimationSourceRel().GetForwardedTargets()
    below = str(skel.GetPath()) + "/"
    return any(str(t) in touched for t in targets) or any(p.startswith(below) for p in touched)


def _check_same_frames(base, gaze, layer_file: str) -> None:
    """The layer animates the frames the input does: one made for another take (a re-export of other
    length or rate) or placed at another time had made the review's arrays disagree (exit 1)."""
    if len(base.times) == len(gaze.times) and np.array_equal(base.times, gaze.times):
        return

    def span(c):
        return f"{len(c.times)} at time codes {c.times[0]:g}..{c.times[-1]:g}"
    raise UsdGazeError(f"{layer_file}:{gaze.animation}: the layer's frames ({span(gaze)} with the input's) are not the "
                       f"input's ({span(base)}); review it over the input it was made for")


def _in_stack(root: Sdf.Layer, layer: Sdf.Layer) -> bool:
    """Whether ``layer`` is in ``root``'s layer stack (``--sublayer-into`` put it in the shot)."""
    from usdgaze.usd.stage import layer_stack

    return any(name == layer.identifier for name, _, _ in layer_stack(root))


def composed_stage(input_path: str | os.PathLike, layer_path: str | os.PathLike):
    """A stage on an anonymous root layer that sublayers ``[layer, input]``: the result, in memory only.

    The root copies the input's timing and units, so time codes mean what they mean in the input.
    """
    from pxr import Sdf, UsdGeom

    source = str(input_path)
    in_memory = isinstance(layer_path, Sdf.Layer)  # apply --plot: staged, not yet written
    layer_file = layer_path.identifier if in_memory else str(layer_path)
    for path, what in ((source, "input"), (layer_file, "--layer"))[: 1 if in_memory else 2]:
        problem = not_a_file(path)
        if problem:
            raise UsdGazeError(f"{path}: {problem} ({what})")
    if not in_memory and os.path.abspath(source) == os.path.abspath(layer_file):
        raise UsdGazeError(f"{layer_file}: --layer names the input itself; pass the override layer usdgaze wrote")
    layers = []
    for path in (source, layer_file):
        if path is layer_file and in_memory:
            layers.append(layer_path)
            continue
        try:
            layer = Sdf.Layer.FindOrOpen(os.path.abspath(path))
        except Exception as exc:  # pxr raises Tf.ErrorException with multi-line text
            raise UsdGazeError(f"{path}: cannot open as a USD layer ({usd_failure(exc)})") from None
        if layer is None:
            raise UsdGazeError(f"{path}: cannot open as a USD layer")
        layers.append(layer)
    base_layer, gaze_layer = layers
    root = Sdf.Layer.CreateAnonymous("usdgaze_review.usda")
    with Sdf.ChangeBlock():
        for name in ("timeCodesPerSecond", "framesPerSecond", "startTimeCode", "endTimeCode"):
            if base_layer.pseudoRoot.HasInfo(name):
                root.pseudoRoot.SetInfo(name, base_layer.pseudoRoot.GetInfo(name))
        for name in ("upAxis", "metersPerUnit", "defaultPrim"):
            if base_layer.pseudoRoot.HasInfo(name):
                root.pseudoRoot.SetInfo(name, base_layer.pseudoRoot.GetInfo(name))
        if in_memory or not _in_stack(base_layer, gaze_layer):  # a shot that sublayers it has it at its offset
            root.subLayerPaths.append(gaze_layer.identifier)
        root.subLayerPaths.append(base_layer.identifier)
    stage = open_root(root, source)
    if not UsdGeom.GetStageUpAxis(stage):
        raise UsdGazeError(f"{source}: the stage has no up axis")
    return stage, gaze_layer


def layer_record(gaze_layer) -> dict:
    """``customLayerData["usdgaze"]`` of an override layer, as plain Python (empty if absent)."""
    data = dict(gaze_layer.customLayerData or {})
    record = data.get("usdgaze")
    return dict(record) if isinstance(record, dict) else {}


_POSE_FRAMES = 2048
"""Frames posed at a time: the local and skeleton-space matrices of a whole long shot at once had
tripled the review's peak memory (plot 4.1 GB at 100 joints x 50,000 frames)."""


def _pose(clip, joints: list[str], rest_local: np.ndarray, parents: np.ndarray, chain: Chain) -> Posed:
    """FK of every frame (in blocks of frames); joints the clip does not animate (or lacks) keep their
    rest. World axes are kept for the chain's head and eyes."""
    f, n = len(clip.times), len(joints)
    index = {j: i for i, j in enumerate(joints)}
    known = np.flatnonzero(clip.anim_to_skel >= 0)  # a joint the skeleton lacks poses nothing
    cols = np.array([index[clip.joints[s]] for s in clip.anim_to_skel[known]], dtype=int)
    kept = sorted({chain.head, *(chain.eyes or ())})
    positions, axes = np.empty((f, n, 3)), np.empty((f, len(kept), 3, 3))
    to_world = np.broadcast_to(clip.skel_to_world, (f, 4, 4))
    for lo in range(0, f, _POSE_FRAMES):
        rows = slice(lo, min(f, lo + _POSE_FRAMES))
        local = np.broadcast_to(rest_local, (rows.stop - lo, n, 4, 4)).copy()
        local[:, cols] = rot.compose_trs(clip.translations[rows, known].astype(float),
                                         clip.rotations[rows, known].astype(float), clip.scales[rows, known].astype(float))
        world = np.einsum("fij,fkjl->fkil", to_world[rows], world_matrices(local, parents))
        positions[rows] = world[..., :3, 3]
        axes[rows] = world[:, kept, :3, :3]
    # rotation_part, not from_matrix: a joint mirrored by a negative rest scale (an eye, a hand) is a rotation too
    q = np.broadcast_to(rot.rotation_part(rest_local[:, :3, :3])[0], (f, n, 4)).copy()
    q[:, cols] = rot.normalize(clip.rotations[:, known].astype(float))
    return Posed(q, positions, {j: axes[:, i] for i, j in enumerate(kept)})


def read_review(input_path: str | os.PathLike, layer_path: str | os.PathLike,
                skel_root: str | None = None) -> Review:
    """Every skeleton the layer animates, base (layer muted) and gaze (composed), posed for every frame."""
    from pxr import UsdGeom

    from usdgaze import api
    from usdgaze.characters import own_map
    from usdgaze.core.hints import from_record
    from usdgaze.usd.skelio import read_clip, skel_roots, skeletons_under

    stage, gaze_layer = composed_stage(input_path, layer_path)
    source, layer_file = str(input_path), gaze_layer.identifier if gaze_layer.anonymous else str(layer_path)
    record = layer_record(gaze_layer)
    review = Review(input=source, layer=layer_file)
    review.eye_range, review.eye_range_recorded = _eye_range(record)
    review.fixation_m = float(record["fixation"]) if "fixation" in record else None
    # Every SkelRoot whose animation the layer overrides (or the one named).
    roots = api.select_roots(stage, source, skel_root) if skel_root else skel_roots(stage)
    touched = {str(p.path) for p in _prim_specs(gaze_layer)}
    hints = from_record(record, layer_file)  # the --bind/--forward the pass was given
    offset = _layer_offset(stage, gaze_layer)
    for root in roots:
        own = own_map(root, source)
        for skel in skeletons_under(root):
            if not skel_root and not _may_touch(skel, touched):  # another character: its problems are not this review's
                continue
            gaze_clip = read_clip(stage, skel, root, source)
            if gaze_clip.animation not in touched:
                continue
            stage.MuteLayer(gaze_layer.identifier)
            try:
                base_clip = read_clip(stage, stage.GetPrimAtPath(skel.GetPath()), stage.GetPrimAtPath(root.GetPath()), source)
            finally:
                stage.UnmuteLayer(gaze_layer.identifier)
            _check_same_frames(base_clip, gaze_clip, layer_file)
            chain, frame = api.bind(gaze_clip, own, hints)
            parents = gaze_clip.parents
            review.characters.append(CharacterReview(
                skel_root=gaze_clip.skel_root, skeleton=gaze_clip.skeleton, joints=list(gaze_clip.joints),
                parents=parents, seconds=gaze_clip.seconds,
                base=_pose(base_clip, gaze_clip.joints, gaze_clip.rest_local, parents, chain),
                gaze=_pose(gaze_clip, gaze_clip.joints, gaze_clip.rest_local, parents, chain),
                chain=chain, frame=frame, neutral_world=gaze_clip.neutral(),
                skel_to_world=gaze_clip.skel_to_world,
                up=np.array([0.0, 0.0, 1.0]) if UsdGeom.GetStageUpAxis(stage) == "Z" else np.array([0.0, 1.0, 0.0]),
                meters_per_unit=gaze_clip.meters_per_unit,
            ))
            clock = _recorded_clock(gaze_layer, offset, gaze_clip)
            review.characters[-1].looks = _looks(stage, root, gaze_clip, source, record, layer_file, clock)
            if not review.shifts:
                review.shifts = _requests(record, str(root.GetPath()), layer_file, clock)
    review.attention = read_attention(stage, source)
    if not review.characters:
        raise UsdGazeError(f"{layer_file}: overrides no SkelAnimation of {source}; is it a usdgaze layer for this input?")
    return review


ATTEND_ROOT = "/UsdGazeAttend"
"""Where the attend pass writes its inspection prims: per character ``gaze:attend:pointOfSight``
(point3f per frame), per object child ``gaze:attend:object`` (its path), ``gaze:attend:estimate``,
``gaze:attend:uncertainty`` (float per frame, NaN while not tracked)."""


def _series(attr) -> tuple[np.ndarray, np.ndarray]:
    times = np.array(attr.GetTimeSamples(), dtype=float)
    values = np.array([attr.Get(float(t)) for t in times], dtype=float)
    return times, values


def read_attention(stage, source: str) -> list[Attention]:
    """The attend run's point of sight and per-object uncertainty, if the stage holds them."""
    from usdgaze.usd.targets import sample_target

    scope = stage.GetPrimAtPath(ATTEND_ROOT)
    if not scope:
        return []
    tcps, start = stage.GetTimeCodesPerSecond(), stage.GetStartTimeCode()
    out = []
    for character in scope.GetChildren():
        sight = character.GetAttribute("gaze:attend:pointOfSight")
        if not sight or not sight.GetNumTimeSamples():
            continue
        times, points = _series(sight)
        objects, uncertainty = {}, {}
        for child in character.GetChildren():
            obj = child.GetAttribute("gaze:attend:object")
            unc = child.GetAttribute("gaze:attend:uncertainty")
            if not obj or not unc:
                continue
            path = str(obj.Get())
            uncertainty[path] = np.interp(times, *_series(unc))
            try:
                objects[path] = sample_target(stage, path, times, source)
            except UsdGazeError:  # no such prim here: where the belief put it
                est_t, est = _series(child.GetAttribute("gaze:attend:estimate"))
                objects[path] = np.stack([np.interp(times, est_t, est[:, k]) for k in range(3)], axis=1)
        if objects:
            out.append(Attention(character.GetName(), (times - start) / tcps, points, objects, uncertainty))
    return out


def _layer_offset(stage, layer):
    """The time offset at which the stage's root layer stack brings ``layer`` in (identity if not)."""
    from pxr import Sdf

    from usdgaze.usd.stage import layer_stack

    return next((o for name, _, o in layer_stack(stage.GetRootLayer()) if name == layer.identifier), Sdf.LayerOffset())


def _recorded_clock(layer, offset, clip):
    """Seconds on ``clip`` of a directive the layer records: in the input's time codes (or seconds
    from its start; the layer carries the input's timing), brought to the stage through the layer's
    ``offset`` (a shot that sublayers it later than the input's own time)."""
    start = layer.startTimeCode if layer.HasStartTimeCode() else 0.0

    def seconds(d) -> float:
        code = offset * (start + d.time * layer.timeCodesPerSecond if d.seconds else d.time)
        return (code - clip.start_time) / clip.time_codes_per_second
    return seconds


def _looks(stage, root, clip, source: str, record: dict, layer_file: str, clock) -> list[Look]:
    """Look directives the pass was given (the layer's record, timed by ``clock``), else the SkelRoot's
    schedule; each holds until the next directive (or the clip's end)."""
    from usdgaze.usd import schedule
    from usdgaze.usd.targets import sample_target

    directives = _recorded_directives(record, str(root.GetPath()), layer_file)
    tc = clock
    if directives is None:
        if not schedule.has_schedule(root):
            return []
        directives = schedule.read_schedule(root, source)
        tc = lambda d: d.time_s(clip.start_time, clip.time_codes_per_second)  # noqa: E731
    directives = sorted(directives, key=tc)
    out = []
    for k, d in enumerate(directives):
        if d.kind != "look":
            continue
        end = tc(directives[k + 1]) if k + 1 < len(directives) else float(clip.seconds[-1])
        if d.target is not None:
            positions, label = sample_target(stage, d.target, clip.times, source), d.target
        else:
            positions = np.broadcast_to(np.asarray(d.point, dtype=float), (len(clip.times), 3)).copy()
            label = "point (" + ", ".join(f"{v:g}" for v in d.point) + ")"
        out.append(Look(f"{label} from {tc(d):.2f} s", tc(d), end, positions))
    return out


def _recorded_directives(record: dict, root: str, layer_file: str):
    """The directive flags ``apply`` recorded for ``root`` (customLayerData usdgaze.directives), parsed;
    None where the layer records none for it."""
    from usdgaze.passes.requests import parse_look, parse_release, parse_shift

    texts = (record.get("directives") or {}).get(root)
    if not texts:
        return None
    parsers = {"--shift": parse_shift, "--look-at": parse_look, "--release": parse_release}
    out = []
    for text in texts:
        flag, _, value = str(text).partition(" ")
        if flag not in parsers:
            raise UsdGazeError(f"{layer_file}: customLayerData usdgaze.directives: '{text}' is no directive")
        try:
            out.append(parsers[flag](value))
        except UsdGazeError as exc:
            raise UsdGazeError(f"{layer_file}: customLayerData usdgaze.directives: {exc}") from None
    return out


def _prim_specs(layer):
    out = []
    layer.Traverse(layer.pseudoRoot.path, lambda p: out.append(layer.GetPrimAtPath(p)) if p.IsPrimPath() else None)
    return [p for p in out if p is not None]


def _requests(record: dict, root: str, layer_file: str, clock) -> list[tuple[float, float, float]]:
    """(seconds, yaw, pitch) of what the pass was asked, in time order: a shift's change (times its
    weight, the share of the way it turns), a release's return to 0, and a look as NaN (a target,
    not a change; the target panel measures it). From the directives recorded for ``root``, else the
    layer's shifts (a layer without directives)."""
    from usdgaze.passes.requests import parse_shift

    directives = _recorded_directives(record, root, layer_file)
    if directives is None:
        directives = []
        for text in record.get("shifts") or []:
            try:
                directives.append(parse_shift(str(text)))
            except UsdGazeError as exc:
                raise UsdGazeError(f"{layer_file}: customLayerData usdgaze.shifts: {exc}") from None
    out = []
    for d in directives:
        t = clock(d)
        change = {"shift": (d.weight * d.yaw, d.weight * d.pitch), "release": (0.0, 0.0)}.get(d.kind, (np.nan, np.nan))
        out.append((t, *change))
    return sorted(out)


def _eye_range(record: dict) -> tuple[dict[str, float], bool]:
    from usdgaze.passes.options import EyeRange

    default = EyeRange()
    recorded = record.get(EYE_RANGE_KEY)
    if isinstance(recorded, dict) and {"yaw", "up", "down"} <= set(recorded):
        return {k: float(recorded[k]) for k in ("yaw", "up", "down")}, True
    return {"yaw": default.yaw, "up": default.up, "down": default.down}, False
