"""The gaze displacement motion G = {P+, l, T, t_beta, beta} (Heck, section 5.1) and its blending.

A :class:`GazeMotions` holds a batch of motions as arrays:

* ``offsets`` ``(..., 5, 4)``: P+, one quaternion per :data:`SEGMENTS` entry, each a rotation of that
  segment relative to its parent, expressed in the canonical character frame (X left, Y up,
  Z forward; see :mod:`usdgaze.core.rotations`).
* ``timing`` ``(..., 7)``: the seven floats, in :data:`TIMING_FIELDS` order.

Evaluation follows the piecewise formula of section 5.2.3 with the linear terms replaced by a
quintic ease-in/ease-out (C1 and C2 at every junction; the paper asks for C1 and later reports C2).
"(1 + beta) * q" scales the rotation angle of q.

Cases the formula leaves open, and what we do:

* A segment starting at or after the overshoot peak (``t_j >= t_beta``) has no overshoot phase: it
  eases from identity at ``t_j`` straight to P+ at ``t = 1``.
* ``beta = 0``: the segment reaches P+ at ``t_beta`` and holds it (the formula's own answer).
* ``t_beta = 1`` leaves no time to settle, so the overshoot is dropped (the segment reaches P+ at 1).
* ``l = 0`` is a cut: the displacement is P+ from the shift's first frame on (see :func:`normalized_time`).
* Before ``t = 0`` the displacement is identity, after ``t = 1`` it is P+.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot

SEGMENTS = ("pelvis", "lowerSpine", "upperSpine", "neck", "eyes")
"""The five segments of P+, root to tip. ``neck`` moves the head relative to the upper spine."""

TIMING_FIELDS = (
    "duration",
    "pelvisStart",
    "lowerSpineStart",
    "upperSpineStart",
    "neckStart",
    "overshootTime",
    "overshoot",
)
"""The seven floats: l (s), T (normalized start times; the eyes start at 0), t_beta, beta."""

DURATION, START_SLICE, PEAK, BETA = 0, slice(1, 5), 5, 6


def ease(u: np.ndarray) -> np.ndarray:
    """Quintic ease-in/ease-out on [0, 1]: zero velocity and acceleration at both ends."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


def normalized_time(elapsed_s: np.ndarray, duration_s: np.ndarray) -> np.ndarray:
    """Seconds since the shift began -> normalized time; a zero duration is a cut at elapsed 0."""
    elapsed_s = np.asarray(elapsed_s, dtype=float)
    duration_s = np.asarray(duration_s, dtype=float)
    safe = np.where(duration_s > 0.0, duration_s, 1.0)
    return np.where(duration_s > 0.0, elapsed_s / safe, np.where(elapsed_s >= 0.0, 1.0, -1.0))


def profile(t: np.ndarray, start: np.ndarray, peak: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Angle multiplier s(t) of one segment: 0 before ``start``, ``1 + beta`` at ``peak``, 1 at t >= 1."""
    # No broadcast copies: each step broadcasts as it goes, the per-segment ones on a row of 5.
    t, start, peak, beta = (np.asarray(a, dtype=float) for a in (t, start, peak, beta))
    start = np.clip(start, 0.0, 1.0)
    peak = np.clip(peak, 0.0, 1.0)
    beta = np.where(peak >= 1.0, 0.0, beta)
    overshooting = start < peak

    rise_len = np.where(overshooting, peak - start, 1.0)
    rise = ease((t - start) / rise_len) * (1.0 + beta)
    settle_len = np.where(peak < 1.0, 1.0 - peak, 1.0)
    settle = 1.0 + (1.0 - ease((t - peak) / settle_len)) * beta
    with_overshoot = np.where(t <= peak, rise, settle)

    late_len = np.where(start < 1.0, 1.0 - start, 1.0)
    late = np.where(start < 1.0, ease((t - start) / late_len), (t >= 1.0).astype(float))

    s = np.where(overshooting, with_overshoot, late)
    s = np.where(t < start, 0.0, s)
    return np.where(t >= 1.0, 1.0, s)


@dataclass(frozen=True)
class GazeMotions:
    """A batch of gaze displacement motions (see the module docstring for the layout)."""

    offsets: np.ndarray
    timing: np.ndarray

    def __post_init__(self) -> None:
        offsets = np.asarray(self.offsets, dtype=float)
        timing = np.asarray(self.timing, dtype=float)
        if offsets.shape[-2:] != (len(SEGMENTS), 4):
            raise ValueError(f"offsets must have shape (..., 5, 4), got {offsets.shape}")
        if timing.shape[-1] != len(TIMING_FIELDS) or timing.shape[:-1] != offsets.shape[:-2]:
            raise ValueError(f"timing must have shape {offsets.shape[:-2] + (7,)}, got {timing.shape}")
        # Renormalize only what is visibly off unit length: values read from float32 storage stay
        # bit for bit, so a map read and written back is unchanged.
        # Values too large to normalize come out non-finite or zero, and the map's checks refuse them
        # with their own one-line error: no numpy warning on the way.
        with np.errstate(over="ignore", invalid="ignore"):
            norm = rot.length(offsets, keepdims=True)
            offsets = np.where(np.abs(norm - 1.0) > 1e-6, rot.normalize(offsets), offsets)
        object.__setattr__(self, "offsets", rot.positive_w(offsets))
        object.__setattr__(self, "timing", timing)

    @classmethod
    def of_checked(cls, offsets: np.ndarray, timing: np.ndarray) -> "GazeMotions":
        """Motions of offsets taken from checked motions (rows, slices or stacks of them: unit, w >= 0),
        without checking them again: :meth:`__post_init__` would leave them as they are."""
        out = object.__new__(cls)
        object.__setattr__(out, "offsets", offsets)
        object.__setattr__(out, "timing", np.asarray(timing, dtype=float))
        return out

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return self.timing.shape[:-1]

    def __len__(self) -> int:
        return self.batch_shape[0] if self.batch_shape else 1

    def __getitem__(self, index) -> "GazeMotions":
        return GazeMotions.of_checked(self.offsets[index], self.timing[index])

    @property
    def duration(self) -> np.ndarray:
        return self.timing[..., DURATION]

    @property
    def starts(self) -> np.ndarray:
        """Normalized start times of all five segments (eyes = 0), shape ``(..., 5)``."""
        t = self.timing[..., START_SLICE]
        return np.concatenate([t, np.zeros(t.shape[:-1] + (1,))], axis=-1)

    @property
    def peak_time(self) -> np.ndarray:
        return self.timing[..., PEAK]

    @property
    def overshoot(self) -> np.ndarray:
        return self.timing[..., BETA]

    def profiles(self, t: np.ndarray) -> np.ndarray:
        """Angle multipliers for normalized times ``t (..., F)`` -> ``(..., F, 5)``.

        ``t`` broadcasts against the batch shape: pass ``t[..., None]``-shaped arrays per motion.
        """
        t = np.asarray(t, dtype=float)[..., None]
        starts = self.starts[..., None, :]
        peak = self.peak_time[..., None, None]
        beta = self.overshoot[..., None, None]
        return profile(t, starts, peak, beta)

    def displacement(self, t: np.ndarray) -> np.ndarray:
        """Per-segment displacement quaternions at normalized times ``t`` -> ``(..., F, 5, 4)``."""
        s = self.profiles(t)
        return rot.power(self.offsets[..., None, :, :], s)


def transition(start: np.ndarray, target: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Per-segment path from state ``start`` to ``target`` with angle multipliers ``s``.

    ``start * (start^-1 * target) ** s``: identity start gives the paper's ``target ** s``; a later
    shift starts from wherever the previous one left each segment.
    """
    return rot.multiply(start, rot.power(rot.relative(start, target), s))


def blend(motions: GazeMotions, weights: np.ndarray, table: np.ndarray | None = None) -> GazeMotions:
    """Lerp blend of ``E`` motions with non-negative weights ``(..., E)`` (rows are normalized).

    Quaternions are stored with w >= 0, so all offsets of one segment share a hemisphere and the
    normalized weighted sum is the lerp of section 5.2.2.2; the seven floats are lerped as well.
    ``table`` is :func:`blend_table` of ``motions``, for a caller that blends the same motions often.
    """
    mixed = _mix(blend_table(motions) if table is None else table, weights)
    return GazeMotions(mixed_offsets(mixed), mixed[..., 20:])


def blend_table(motions: GazeMotions) -> np.ndarray:
    """The ``(E, 5*4 + 7)`` rows :func:`blend` mixes: each motion's offsets, then its timing."""
    return np.concatenate([motions.offsets.reshape(len(motions.offsets), -1), motions.timing], axis=1)


def blend_timing(table: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The timing floats ``(..., 7)`` of :func:`blend` (bit for bit), without building its motions."""
    return _mix(table, weights)[..., 20:]


def blended_offsets(table: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The unit offsets ``(..., 5, 4)`` of :func:`blend` (bit for bit, up to each quaternion's sign,
    which no rotation of a vector sees), without building its motions."""
    return mixed_offsets(_mix(table, weights))


def blend_shares(weights: np.ndarray) -> np.ndarray:
    """Blend weights ``(..., E)`` checked and normalized per blend, as :func:`blend` mixes with them."""
    w = np.asarray(weights, dtype=float)
    if (w < 0).any():  # array methods: np.any's, less a wrapper (the map measures often)
        raise ValueError("blend weights must be non-negative")
    total = w.sum(axis=-1, keepdims=True)
    if (total <= 0).any():
        raise ValueError("each blend needs at least one positive weight")
    return w / total


def _mix(table: np.ndarray, weights: np.ndarray) -> np.ndarray:
    return blend_shares(weights) @ table  # one matrix product (BLAS) for all blends


def mixed_offsets(mixed: np.ndarray) -> np.ndarray:
    """The unit offsets ``(..., 5, 4)`` of mixed :func:`blend_table` rows (``blend_shares(w) @ table``)."""
    return rot.normalize(mixed[..., :20].reshape(mixed.shape[:-1] + (5, 4)))



def chain_rotation(offsets: np.ndarray) -> np.ndarray:
    """Composite canonical-frame rotation of consecutive segments ``(..., n, 4)``, root first."""
    q = offsets[..., 0, :]
    for j in range(1, offsets.shape[-2]):
        q = rot.multiply(q, offsets[..., j, :])
    return q


def achieved_gaze(offsets: np.ndarray, yaw_hint_deg: np.ndarray | float = 0.0) -> np.ndarray:
    """Gaze change (yaw, pitch) in degrees that offsets ``(..., 5, 4)`` achieve on the canonical chain.

    The canonical chain is the five segments composed hierarchically with the eyes looking along +Z
    at rest; with the point of sight at infinity only the composite rotation matters.
    """
    direction = rot.rotate(chain_rotation(offsets), rot.FORWARD)
    yaw, pitch = rot.direction_to_yaw_pitch(direction, yaw_hint_deg)
    out = np.empty(np.shape(yaw) + (2,))  # np.stack's bits, without its wrapper (the map measures often)
    out[..., 0], out[..., 1] = yaw, pitch
    return out


def aim_eyes(body_offsets: np.ndarray, yaw_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """Eye offset (Listing's law: no torsion) that makes the chain look at (yaw, pitch).

    ``body_offsets`` are the four non-eye segments ``(..., 4, 4)``.
    """
    body = chain_rotation(body_offsets)
    target = rot.yaw_pitch_to_direction(yaw_deg, pitch_deg)
    return rot.shortest_arc(rot.FORWARD, rot.rotate(rot.conjugate(body), target))
