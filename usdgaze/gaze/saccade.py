"""Eye movements beyond the paper: main-sequence saccades and smooth pursuit (pure numpy).

Saccades follow the main sequence: duration ``25 ms + 2.4 ms/deg`` of amplitude, with a minimum-jerk
(quintic) profile, so the peak speed is ``1.875 A / D(A)``: about 380 deg/s at 10 deg, 580 at 30,
670 at 60, saturating at 781 deg/s for very large amplitudes, under the 800 deg/s bound of Eom et
al. (4.1). Pursuit copies the target's own angular velocity (not the viewer's self-motion, which the
vestibulo-ocular reflex cancels at once) after a latency, capped at 100 deg/s.
"""

from __future__ import annotations

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.gaze.motion import ease

BASE_S = 0.025
"""Main sequence: fixed part of a saccade's duration (s)."""
PER_DEG_S = 0.0024
"""Main sequence: duration per degree of amplitude (s/deg)."""
PEAK_RATIO = 1.875
"""Peak over mean speed of the quintic profile (its slope at the middle)."""
MAX_SACCADE_DEG_S = 800.0
MAX_PURSUIT_DEG_S = 100.0


def duration(amplitude_deg: np.ndarray | float) -> np.ndarray:
    """Saccade duration in seconds for an amplitude in degrees (main sequence)."""
    return BASE_S + PER_DEG_S * np.abs(np.asarray(amplitude_deg, dtype=float))


def peak_speed(amplitude_deg: np.ndarray | float) -> np.ndarray:
    """Peak angular speed (deg/s) of a main-sequence saccade; saturates at 1.875 / 2.4 ms = 781 deg/s."""
    a = np.abs(np.asarray(amplitude_deg, dtype=float))
    return PEAK_RATIO * a / duration(a)


def progress(elapsed_s: np.ndarray, amplitude_deg: float) -> np.ndarray:
    """Fraction of a saccade done ``elapsed_s`` after its onset: 0 before, quintic, 1 after."""
    return ease(np.asarray(elapsed_s, dtype=float) / float(duration(amplitude_deg)))


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between unit vectors ``(..., 3)``; stable for small angles."""
    return np.degrees(2.0 * np.arctan2(rot.length(a - b), rot.length(a + b)))


def slerp(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Great-circle interpolation of unit vectors ``(F, 3)`` by fractions ``s (F,)`` (any real s).

    Opposite vectors have no unique great circle: the path then runs through a perpendicular chosen
    from ``a`` alone, so it does not flicker between frames.
    """
    a = rot.normalize(a)
    b = rot.normalize(b)
    s = np.asarray(s, dtype=float)
    omega = np.radians(angle_deg(a, b))
    ortho = b - rot.dot(a, b, keepdims=True) * a
    n = rot.length(ortho, keepdims=True)
    apart = n > 1e-9
    if apart.all():  # the usual case: no frame needs the fallback
        ortho = ortho / n
    else:
        # Nearly opposite: any perpendicular is as good; take one from the smallest component of a.
        pick = np.eye(3)[np.argmin(np.abs(a), axis=-1)]
        fallback = rot.normalize(pick - rot.dot(pick, a, keepdims=True) * a)
        ortho = np.where(apart, ortho / np.where(apart, n, 1.0), fallback)
    theta = (omega * s)[..., None]
    return np.cos(theta) * a + np.sin(theta) * ortho


def target_rates(target: np.ndarray, eye: np.ndarray, seconds: np.ndarray) -> np.ndarray:
    """Angular velocity ``(F, 3)`` (rad/s) of the target's own motion seen from the eye: its world
    velocity across the line of sight (see :func:`pursue`)."""
    los = target - eye
    dist = np.maximum(rot.length(los), 1e-12)
    velocity = np.gradient(target, seconds, axis=0) if len(seconds) > 1 else np.zeros_like(target)
    return np.cross(los / dist[:, None], velocity) / dist[:, None]


def pursue(target: np.ndarray, eye: np.ndarray, seconds: np.ndarray, start: int, onset_s: float,
           latency_s: float = 0.15, max_deg_s: float = MAX_PURSUIT_DEG_S, rates: np.ndarray | None = None,
           stop: int | None = None) -> np.ndarray:
    """Tracked point ``(F', 3)`` for frames ``start..stop``: on the target at ``start``, then turning with
    the target's own angular velocity as it was ``latency_s`` earlier (none before ``onset_s +
    latency_s``: motion seen only since the target was picked), capped at ``max_deg_s``.

    The target's own motion is its world velocity across the line of sight; the viewer's motion never
    enters, because the eyes cancel it at once (VOR), so a still target is held exactly. The lag
    behind the target is a rotation about the eye that accumulates (pursuit - target) angular
    velocity; summing its rotation vectors is exact for motion about one axis (a target circling or
    crossing the viewer) and close for the small lags that catch-up saccades leave. ``rates``: the
    :func:`target_rates` of the whole path, for a caller that pursues it again and again; a frame's
    point does not depend on ``stop``.
    """
    stop = len(seconds) if stop is None else stop
    t = seconds[start:stop]
    if len(t) < 2:
        return target[start:start + 1].copy()
    # The target's rates over the whole path, so the late copy reaches back before ``start`` (a
    # catch-up saccade does not reset pursuit).
    omega_all = target_rates(target, eye, seconds) if rates is None else rates
    mid = 0.5 * (t[1:] + t[:-1])
    omega = np.column_stack([np.interp(mid, seconds, omega_all[:, k]) for k in range(3)])
    seen = mid - latency_s
    delayed = np.column_stack([np.interp(seen, seconds, omega_all[:, k]) for k in range(3)])
    delayed[seen < onset_s] = 0.0
    speed = rot.length(delayed)
    pursuit = delayed * np.minimum(1.0, np.radians(max_deg_s) / np.maximum(speed, 1e-12))[:, None]
    lag = np.concatenate([np.zeros((1, 3)), np.cumsum((pursuit - omega) * np.diff(t)[:, None], axis=0)])
    return eye[start:stop] + rot.rotate(rot.from_rotvec(lag), target[start:stop] - eye[start:stop])
