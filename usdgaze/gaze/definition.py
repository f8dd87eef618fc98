"""The data of a gaze map, independent of storage: examples, joint-role bindings, synthesis settings."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.gaze.motion import GazeMotions

ROLES = ("pelvis", "lowerSpine", "upperSpine", "neck", "head", "leftEye", "rightEye")
"""Joint roles a map can bind. ``neck`` and ``head`` together carry the P+ neck segment."""


@dataclass(frozen=True)
class SynthesisSettings:
    """Kovar & Gleicher blending-based synthesis settings (stored as ``gaze:synthesis:*``)."""

    samples: int = 5000
    """Random blends drawn to sample the (yaw, pitch) space densely."""
    blend_size: int = 6
    """How many nearby examples one random blend mixes."""
    neighbors: int = 8
    """k of the k-nearest-neighbour interpolation of blend weights at query time."""
    refine: int = 3
    """Fixed-point corrections of a query against its measured gaze change on the canonical chain."""
    seed: int = 0
    """Seed of the random blends, so that a map always builds the same way."""
    neck_share: float = 1.0
    """Outside the sampled region: share of the missing rotation taken by the neck (the eyes take the rest)."""


@dataclass(frozen=True)
class GazeMapDefinition:
    """A parametric gaze map's source data.

    ``params`` ``(E, 2)``: each example's (yaw, pitch) gaze change in degrees, yaw positive toward the
    character's left, never wrapped (-180 and +180 are a right and a left turn).
    ``motions``: the E gaze displacement motions, in the same order.
    ``bindings``: role -> skeleton joint paths; empty or missing roles are found by name.
    """

    params: np.ndarray
    motions: GazeMotions
    settings: SynthesisSettings = field(default_factory=SynthesisSettings)
    bindings: dict[str, tuple[str, ...]] = field(default_factory=dict)
    forward: tuple[float, float, float] | None = None
    """Character forward in skeleton space, or None to work it out from the rest pose."""

    def __post_init__(self) -> None:
        params = np.asarray(self.params, dtype=float).reshape(-1, 2)
        object.__setattr__(self, "params", params)
        if len(self.motions) != len(params) or self.motions.offsets.ndim != 3:
            raise ValueError(f"{len(params)} example parameters but {len(self.motions)} motions")

    def __len__(self) -> int:
        return len(self.params)


# -- storage names and value checks ----------------------------------------------------------------
# The USD attribute names live here (not in the pxr-side schema module) so that in-memory maps and
# stored maps are checked by the same code and report problems under the same names.

from usdgaze.errors import GazeMapError  # noqa: E402  (kept next to the code that uses it)
from usdgaze.gaze.motion import SEGMENTS, TIMING_FIELDS  # noqa: E402

API_NAME = "GazeMapAPI"
YAW_ATTR = "gaze:examples:yaw"
PITCH_ATTR = "gaze:examples:pitch"
OFFSET_ATTRS = tuple(f"gaze:examples:{segment}Offset" for segment in SEGMENTS)
"""One quatf[] per P+ segment, in :data:`usdgaze.gaze.motion.SEGMENTS` order."""
TIMING_ATTRS = tuple(f"gaze:examples:{name}" for name in TIMING_FIELDS)
"""One float[] per timing float, in :data:`usdgaze.gaze.motion.TIMING_FIELDS` order."""
BINDING_ATTRS = {role: f"gaze:binding:{role}" for role in ROLES}
FORWARD_ATTR = "gaze:binding:forward"
SETTING_ATTRS = {
    "samples": "gaze:synthesis:samples",
    "blend_size": "gaze:synthesis:blendSize",
    "neighbors": "gaze:synthesis:neighbors",
    "refine": "gaze:synthesis:refine",
    "seed": "gaze:synthesis:seed",
    "neck_share": "gaze:synthesis:neckShare",
}
""":class:`SynthesisSettings` field -> attribute."""
EXAMPLE_ATTRS = (YAW_ATTR, PITCH_ATTR) + OFFSET_ATTRS + TIMING_ATTRS
"""Every per-example array; all hold one entry per example."""

UNIT_TOLERANCE = 1e-3
"""How far a stored quaternion's length may be from 1."""

_TIMING_RANGES = {
    # field: (low, low inclusive, high, high inclusive, unit)
    "duration": (0.0, False, np.inf, False, " s"),  # a 0 s shift is a jump of the head in one frame
    "pelvisStart": (0.0, True, 1.0, False, ""),
    "lowerSpineStart": (0.0, True, 1.0, False, ""),
    "upperSpineStart": (0.0, True, 1.0, False, ""),
    "neckStart": (0.0, True, 1.0, False, ""),
    "overshootTime": (0.0, False, 1.0, True, ""),
    "overshoot": (0.0, True, 1.0, True, ""),
}
_SETTING_MINIMA = {"samples": 1, "blend_size": 1, "neighbors": 1, "refine": 0, "seed": 0}  # numpy seeds are >= 0
# Beyond these a map takes minutes to hours to build (samples, refine) or means nothing more (blend
# size, neighbours past any real example count); seeds are 32-bit for numpy's legacy generator.
_SETTING_MAXIMA = {"samples": 200_000, "blend_size": 64, "neighbors": 256, "refine": 50, "seed": 2**32 - 1}


def _range_text(low: float, low_in: bool, high: float, high_in: bool) -> str:
    if np.isinf(high):
        return f">= {low:g}" if low_in else f"> {low:g}"
    return f"in {'[' if low_in else '('}{low:g}, {high:g}{']' if high_in else ')'}"


def _first_bad(ok: np.ndarray) -> int | None:
    bad = np.flatnonzero(~ok)
    return int(bad[0]) if bad.size else None


def _check_range(values: np.ndarray, low: float, low_in: bool, high: float, high_in: bool) -> np.ndarray:
    """Mask of values inside the range; NaN is never inside."""
    above = values >= low if low_in else values > low
    below = values <= high if high_in else values < high
    return above & below & ~np.isnan(values)


def check_unit_quaternions(q: np.ndarray, where: str) -> None:
    """Raise unless every quaternion ``(E, 4)`` is finite and unit within :data:`UNIT_TOLERANCE`.

    ``where`` is ``SOURCE.ATTRIBUTE``. Stored maps are checked before :class:`GazeMotions`
    normalizes them, which would hide a wrong length.
    """
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    length = np.linalg.norm(q, axis=-1)
    i = _first_bad(np.isfinite(q).all(axis=-1) & (np.abs(length - 1.0) <= UNIT_TOLERANCE))
    if i is not None:
        shown = "not finite" if not np.isfinite(q[i]).all() else f"of length {length[i]:.6g}"
        raise GazeMapError(f"{where}: example {i} is {shown}, expected a unit quaternion (within {UNIT_TOLERANCE:g})")


def _validate_params(params: np.ndarray, source: str) -> None:
    """At least one example, (yaw, pitch) in range, no two examples at the same gaze change."""
    if len(params) == 0:
        raise GazeMapError(f"{source}.{YAW_ATTR}: no examples, expected at least one")
    for column, attr, limit in ((0, YAW_ATTR, 180.0), (1, PITCH_ATTR, 90.0)):
        i = _first_bad(_check_range(params[:, column], -limit, True, limit, True))
        if i is not None:
            raise GazeMapError(f"{source}.{attr}: example {i} is {params[i, column]:g} deg, expected in [-{limit:g}, {limit:g}]")

    # Duplicates: sort rows lexicographically, then equal rows are neighbours.
    order = np.lexsort((params[:, 1], params[:, 0]))
    same = np.all(params[order[1:]] == params[order[:-1]], axis=-1)
    if same.any():
        k = int(np.flatnonzero(same)[0])
        a, b = sorted((int(order[k]), int(order[k + 1])))
        raise GazeMapError(
            f"{source}.{YAW_ATTR}: examples {a} and {b} share (yaw, pitch) = "
            f"({params[a, 0]:g}, {params[a, 1]:g}); each example must be a different gaze change"
        )


def _validate_motions(motions: GazeMotions, source: str) -> None:
    """Unit quaternion offsets and every timing float inside its field's range."""
    offsets = motions.offsets
    for j, attr in enumerate(OFFSET_ATTRS):
        check_unit_quaternions(offsets[:, j, :], f"{source}.{attr}")

    timing = motions.timing
    for c, (name, attr) in enumerate(zip(TIMING_FIELDS, TIMING_ATTRS)):
        low, low_in, high, high_in, unit = _TIMING_RANGES[name]
        i = _first_bad(_check_range(timing[:, c], low, low_in, high, high_in))
        if i is not None:
            raise GazeMapError(
                f"{source}.{attr}: example {i} is {timing[i, c]:g}{unit}, expected {_range_text(low, low_in, high, high_in)}"
            )


def _validate_bindings(bindings: dict, source: str) -> None:
    """Known roles, each bound to a sequence of non-empty joint paths."""
    for role, joints in bindings.items():
        if role not in BINDING_ATTRS:
            raise GazeMapError(f"{source}: unknown joint role {role!r}, expected one of {', '.join(ROLES)}")
        attr = BINDING_ATTRS[role]
        if isinstance(joints, str):
            raise GazeMapError(f"{source}.{attr}: a single string {joints!r}, expected a sequence of joint paths")
        for k, joint in enumerate(joints):
            if not isinstance(joint, str) or not joint.strip():
                raise GazeMapError(f"{source}.{attr}: entry {k} is {joint!r}, expected a joint path")


def forward_problem(forward) -> str | None:
    """Why an authored forward is no direction (``(nan, 0.0, 0.0) is not a direction ...``), or None
    for an unset one or a finite non-zero 3-vector whose length is finite too."""
    if forward is None:
        return None
    forward = np.asarray(forward, dtype=float)
    with np.errstate(over="ignore"):  # (1e200, 1e200, 0) is finite, its length is not
        length = float(np.sqrt(np.sum(forward * forward))) if forward.shape == (3,) else np.nan
    if forward.shape != (3,) or not np.isfinite(forward).all() or not 0 < length < np.inf:
        return (f"{tuple(forward.ravel().tolist())} is not a direction "
                "(leave it unset to work forward out from the rest pose)")
    return None


def _validate_forward(forward, source: str) -> None:
    problem = forward_problem(forward)
    if problem:
        raise GazeMapError(f"{source}.{FORWARD_ATTR}: {problem}")


def setting_problem(name: str, value) -> str | None:
    """Why ``value`` cannot be the synthesis setting ``name`` (a field of :class:`SynthesisSettings`),
    or None: integers within their bounds, a neck share in [0, 1]."""
    if name == "neck_share":
        if not (isinstance(value, (int, float, np.floating)) and 0.0 <= value <= 1.0):
            return f"{value!r}, expected a number in [0, 1]"
    elif not isinstance(value, (int, np.integer)) or isinstance(value, bool):
        return f"{value!r}, expected an integer"
    elif name in _SETTING_MINIMA and value < _SETTING_MINIMA[name]:
        return f"{value}, expected >= {_SETTING_MINIMA[name]}"
    elif name in _SETTING_MAXIMA and value > _SETTING_MAXIMA[name]:
        return f"{value}, expected <= {_SETTING_MAXIMA[name]}"
    return None


def _validate_settings(settings: SynthesisSettings, source: str) -> None:
    for name, attr in SETTING_ATTRS.items():
        problem = setting_problem(name, getattr(settings, name))
        if problem:
            raise GazeMapError(f"{source}.{attr}: {problem}")


def validate(definition: GazeMapDefinition, source: str) -> None:
    """Raise :class:`GazeMapError` at the first malformed value of a gaze map.

    ``source`` names where the map comes from, ``FILE:PRIMPATH`` for a stored map; messages read
    ``SOURCE.ATTRIBUTE: problem`` so that an in-memory map and a stored one report alike.
    """
    _validate_params(definition.params, source)
    _validate_motions(definition.motions, source)
    _validate_bindings(definition.bindings, source)
    _validate_forward(definition.forward, source)
    _validate_settings(definition.settings, source)
