"""The composed result of a gaze pass, as arrays: the input with the override layer as its strongest
sublayer, opened in memory (neither file is touched), posed by forward kinematics for every frame.

This is the one reader behind ``usdgaze plot``, ``usdgaze preview`` and ``apply --plot``: it turns a
stage and a layer into numpy arrays; everything downstream (:mod:`usdgaze.review.analysis`, the
plots, the renderer) works on arrays only.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.kinematics import world_matrices
from usdgaze.core.rig import Chain, CharacterFrame
from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.review import recorded
from usdgaze.review.attention import Attention, read_attention
from usdgaze.review.physics_record import PhysicsMeasures, read_physics
from usdgaze.review.recorded import Look
from usdgaze.usd.stage import open_root
from usdgaze.files.kinds import not_a_file

if TYPE_CHECKING:  # annotations only: pxr is imported where a stage is read
    from pxr import Sdf

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

    looks: list[Look] = field(default_factory=list)
    """The look-at directives the pass was given (or the SkelRoot's GazeScheduleAPI), targets sampled."""
    shifts: list[tuple[float, float, float]] = field(default_factory=list)
    """What this character was asked: (seconds from the stage start, yaw, pitch), time-ordered; a
    look's yaw and pitch are NaN (see :func:`usdgaze.review.recorded.requests`)."""
    physics: PhysicsMeasures | None = None
    """What ``attend --physics`` recorded for this skeleton (its per-step measures), if it did."""

    @property
    def eyes(self) -> tuple[int, int] | None:
        return self.chain.eyes


@dataclass
class Review:
    """What ``usdgaze plot`` and ``usdgaze preview`` draw: every character, plus the layer's record."""

    input: str
    layer: str
    characters: list[CharacterReview] = field(default_factory=list)
    eye_range: dict[str, float] = field(default_factory=dict)
    eye_range_recorded: bool = False
    """False for layers written before the limits were recorded (the defaults are shown then)."""
    fixation_m: float | None = None
    attention: list[Attention] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # a layer made from another version of the input
    playback: tuple[float, float] | None = None
    """Seconds from the stage start of the shot's playback range (startTimeCode..endTimeCode), where a
    review cut to it (``read_review(playback=True)``) has one: what ``preview`` draws, frame by frame."""

    @property
    def shifts(self) -> list[tuple[float, float, float]]:
        """The first character's requests (each character's own are ``CharacterReview.shifts``)."""
        return self.characters[0].shifts if self.characters else []


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
    recorded.check_not_preview(gaze_layer, layer_file)
    in_stack = not in_memory and _in_stack(base_layer, gaze_layer)
    if in_stack and not layer_record(gaze_layer):  # muted as a --sublayer-into override: "the skeleton has no joints"
        raise UsdGazeError(f"{layer_file}: --layer names a layer of the input's own ({source} composes it as a "
                           "sublayer), not one usdgaze wrote; pass the override layer usdgaze wrote")
    root = Sdf.Layer.CreateAnonymous("usdgaze_review.usda")
    with Sdf.ChangeBlock():
        for name in ("timeCodesPerSecond", "framesPerSecond", "startTimeCode", "endTimeCode"):
            if base_layer.pseudoRoot.HasInfo(name):
                root.pseudoRoot.SetInfo(name, base_layer.pseudoRoot.GetInfo(name))
        for name in ("upAxis", "metersPerUnit", "defaultPrim"):
            if base_layer.pseudoRoot.HasInfo(name):
                root.pseudoRoot.SetInfo(name, base_layer.pseudoRoot.GetInfo(name))
        if not in_stack:  # a shot that sublayers it has it at its offset
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
                skel_root: str | None = None, playback: bool = False) -> Review:
    """Every skeleton the layer animates, base (layer muted) and gaze (composed), posed for every frame;
    ``playback``: only the frames of the shot's playback range (:func:`playback_rows`), what ``plot``
    and ``preview`` show."""
    from usdgaze import api
    from usdgaze.core.hints import from_record
    from usdgaze.review.layer_versions import review_warnings
    from usdgaze.usd.skelio import skel_roots, skeletons_under

    stage, gaze_layer = composed_stage(input_path, layer_path)
    source, layer_file = str(input_path), gaze_layer.identifier if gaze_layer.anonymous else str(layer_path)
    record = layer_record(gaze_layer)
    review = Review(input=source, layer=layer_file)
    review.eye_range, review.eye_range_recorded = _eye_range(record, layer_file)
    review.fixation_m = recorded.recorded_number(record, "fixation", layer_file) if "fixation" in record else None
    # Every SkelRoot whose animation the layer overrides (or the one named).
    roots = api.select_roots(stage, source, skel_root) if skel_root else skel_roots(stage)
    touched = touched_paths(gaze_layer)
    animated = overridden_animations(stage, touched)
    read = _Reader(stage, gaze_layer, source, layer_file, record, from_record(record, layer_file), playback)
    for root in roots:
        for skel in skeletons_under(root):
            if not skel_root and str(skel.GetPath()) not in animated:  # another character: not this review's
                continue
            character = read.character(skel, root, touched)
            if character is not None:
                review.characters.append(character)
    review.attention = read_attention(stage, source)
    if playback and stage.HasAuthoredTimeCodeRange():  # a shot over a longer take: its attention too
        review.attention = [_attention_in(a, stage) for a in review.attention]
        review.playback = _playback_span(stage, review.characters) if review.characters else None
    review.warnings = review_warnings(stage, gaze_layer, layer_file, record, review.characters)
    if not review.characters:
        if skel_root:
            elsewhere = sorted({str(r.GetPath()) for r in skel_roots(stage)
                                for s in skeletons_under(r) if _may_touch(s, touched)})
            raise UsdGazeError(f"{layer_file}: --skel-root {skel_root}: the layer animates no skeleton of it"
                               + (f" (it animates {', '.join(elsewhere)})" if elsewhere else ""))
        raise UsdGazeError(f"{layer_file}: {not_for_input(source)}")
    return review


def playback_rows(stage, times: np.ndarray) -> tuple[int, int]:
    """Rows ``lo:hi`` of the sample ``times`` that the stage plays: those inside its root layer's
    startTimeCode..endTimeCode where it authors them (a shot cut from a longer take plays only
    those; the review had drawn the whole take), else all. A range between or beyond the samples
    keeps the nearest one: the pose USD holds there."""
    if not stage.HasAuthoredTimeCodeRange() or not len(times):
        return 0, len(times)
    start, end = float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    lo, hi = (int(i) for i in np.searchsorted(times, [start - 1e-9, end + 1e-9]))
    if hi > lo:
        return lo, hi
    nearest = min(max(lo - 1, 0), len(times) - 1)
    if lo < len(times) and abs(times[lo] - start) < abs(times[nearest] - start):
        nearest = lo
    return nearest, nearest + 1


def _playback_span(stage, characters: list[CharacterReview]) -> tuple[float, float]:
    """Seconds of the shot's range to draw: the whole range where the samples reach to within a frame
    of its ends (a 60 Hz take in a 24 fps shot has none on its first and last frames), else up to a
    frame past them: USD holds the first and last pose beyond, and a range of 1e8 time codes over a
    4 s take would be 40 million frames of it."""
    length = (stage.GetEndTimeCode() - stage.GetStartTimeCode()) / stage.GetTimeCodesPerSecond()
    frame = 1.0 / stage.GetFramesPerSecond()
    first = min(float(c.seconds[0]) for c in characters)
    last = max(float(c.seconds[-1]) for c in characters)
    lo = min(max(0.0, first - frame), length)
    return lo, max(lo, min(length, last + frame))


def _attention_in(a: Attention, stage) -> Attention:
    """An attend run's record cut to the frames the stage plays (:func:`playback_rows`)."""
    start, tcps = float(stage.GetStartTimeCode()), float(stage.GetTimeCodesPerSecond())
    return a.rows(*playback_rows(stage, start + a.seconds * tcps))


def touched_paths(layer) -> set[str]:
    """The paths of every prim spec ``layer`` holds."""
    return {str(p.path) for p in _prim_specs(layer)}


def overridden_animations(stage, touched: set[str]) -> dict[str, str]:
    """Skeleton path -> the SkelAnimation bound to it on ``stage`` that a layer holds a prim spec for
    (``touched``: its :func:`touched_paths`): the skeletons plot and preview review. Empty: a layer
    made for another input (another take's animation has another name), which they refuse and
    validate flags."""
    from usdgaze.usd.skelio import animation_of, skel_roots, skeletons_under

    out = {}
    for root in skel_roots(stage):
        for skel in skeletons_under(root):
            anim = animation_of(skel)
            if anim is not None and str(anim.GetPath()) in touched:
                out[str(skel.GetPath())] = str(anim.GetPath())
    return out


def not_for_input(source: str) -> str:
    """What plot, preview and validate say of a layer that overrides none of ``source``'s animations."""
    return f"overrides no SkelAnimation of {source}; is it a usdgaze layer for this input?"


class _Reader:
    """One character of the composed stage at a time: its base and gaze clips posed, with what the
    layer records it was asked."""

    def __init__(self, stage, gaze_layer, source: str, layer_file: str, record: dict, hints,
                 playback: bool = False) -> None:
        from pxr import UsdGeom

        self.stage, self.layer, self.source, self.layer_file = stage, gaze_layer, source, layer_file
        self.record, self.hints = record, hints  # hints: the --bind/--forward the pass was given
        self.offset = recorded.layer_offset(stage, gaze_layer)
        self.playback = playback  # cut each clip to the shot's playback range
        self.up = np.array([0.0, 0.0, 1.0]) if UsdGeom.GetStageUpAxis(stage) == "Z" else np.array([0.0, 1.0, 0.0])

    def _base_clip(self, skel, root):
        from usdgaze.usd.skelio import read_clip

        stage = self.stage
        stage.MuteLayer(self.layer.identifier)
        try:
            return read_clip(stage, stage.GetPrimAtPath(skel.GetPath()), stage.GetPrimAtPath(root.GetPath()), self.source)
        finally:
            stage.UnmuteLayer(self.layer.identifier)

    def character(self, skel, root, touched: set[str]) -> CharacterReview | None:
        """``skel`` reviewed, or None where the layer does not override its animation."""
        from usdgaze import api
        from usdgaze.characters import own_map
        from usdgaze.usd.skelio import read_clip

        gaze_clip = read_clip(self.stage, skel, root, self.source)
        if gaze_clip.animation not in touched:
            return None
        base_clip = self._base_clip(skel, root)
        _check_same_frames(base_clip, gaze_clip, self.layer_file)
        chain, frame = api.bind(gaze_clip, own_map(root, self.source), self.hints)  # bound on the take, as apply did
        if self.playback:
            lo, hi = playback_rows(self.stage, gaze_clip.times)
            base_clip, gaze_clip = base_clip.frames(lo, hi), gaze_clip.frames(lo, hi)
        parents, joints = gaze_clip.parents, gaze_clip.joints
        clock = recorded.recorded_clock(self.layer, self.offset, gaze_clip)
        path = str(root.GetPath())
        return CharacterReview(
            skel_root=gaze_clip.skel_root, skeleton=gaze_clip.skeleton, joints=list(joints),
            parents=parents, seconds=gaze_clip.seconds,
            base=_pose(base_clip, joints, gaze_clip.rest_local, parents, chain),
            gaze=_pose(gaze_clip, joints, gaze_clip.rest_local, parents, chain),
            chain=chain, frame=frame, neutral_world=gaze_clip.neutral(),
            skel_to_world=gaze_clip.skel_to_world, up=self.up, meters_per_unit=gaze_clip.meters_per_unit,
            looks=recorded.looks(self.stage, root, gaze_clip, self.source, self.record, self.layer_file, clock),
            shifts=recorded.requests(self.record, path, self.layer_file, clock),
            physics=read_physics(dict(self.layer.customLayerData or {}), [gaze_clip.skeleton], self.layer_file,
                                 recorded.recorded_seconds(self.layer, self.offset, gaze_clip)).get(gaze_clip.skeleton),
        )


def _prim_specs(layer):
    out = []
    layer.Traverse(layer.pseudoRoot.path, lambda p: out.append(layer.GetPrimAtPath(p)) if p.IsPrimPath() else None)
    return [p for p in out if p is not None]


def _eye_range(record: dict, layer_file: str) -> tuple[dict[str, float], bool]:
    from usdgaze.passes.options import EyeRange

    default = EyeRange()
    limits = record.get(EYE_RANGE_KEY)
    if isinstance(limits, dict) and {"yaw", "up", "down"} <= set(limits):
        return {k: recorded.recorded_number(record, f"{EYE_RANGE_KEY}.{k}", layer_file)
                for k in ("yaw", "up", "down")}, True
    return {"yaw": default.yaw, "up": default.up, "down": default.down}, False
