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
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1)))


def slerp(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Great-circle interpolation of unit vectors ``(F, 3)`` by fractions ``s (F,)`` (any real s).

    Opposite vectors have no unique great circle: the path then runs through a perpendicular chosen
    from ``a`` alone, so it does not flicker between frames.
    """
    a = rot.normalize(a)
    b = rot.normalize(b)
    s = np.asarray(s, dtype=float)
    omega = np.radians(angle_deg(a, b))
    ortho = b - np.sum(a * b, -1, keepdims=True) * a
    n = np.linalg.norm(ortho, axis=-1, keepdims=True)
    # Nearly opposite: any perpendicular is as good; take one from the smallest component of a.
    pick = np.eye(3)[np.argmin(np.abs(a), axis=-1)]
    fallback = rot.normalize(pick - np.sum(pick * a, -1, keepdims=True) * a)
    ortho = np.where(n > 1e-9, ortho / np.where(n > 1e-9, n, 1.0), fallback)
    theta = (omega * s)[..., None]
    return np.cos(theta) * a + np.sin(theta) * ortho


def pursue(target: np.ndarray, eye: np.ndarray, seconds: np.ndarray, start: int, onset_s: float,
           latency_s: float = 0.15, max_deg_s: float = MAX_PURSUIT_DEG_S) -> np.ndarray:
    """Tracked point ``(F', 3)`` for frames ``start..``: the target's own motion, late and speed-capped.

    From ``target[start]`` the point moves with the target's world velocity as it was ``latency_s``
    earlier (zero before ``onset_s + latency_s``: motion seen only since the target was picked), its
    component across the line of sight capped at ``max_deg_s`` as seen from ``eye``. The viewer's own
    motion never enters: the eyes cancel it at once (VOR), so a still target is held exactly.
    """
    t = seconds[start:]
    if len(t) < 2:
        return target[start:start + 1].copy()
    # Target velocity per frame interval, sampled at the delayed times (piecewise linear path).
    delayed = np.column_stack([np.interp(t - latency_s, seconds, target[:, k]) for k in range(3)])
    seen = (t - latency_s) >= onset_s
    step = np.diff(delayed, axis=0) * (seen[1:] & seen[:-1])[:, None]
    dt = np.diff(t)
    los = target[start + 1:] - eye[start + 1:]
    dist = np.linalg.norm(los, axis=-1, keepdims=True)
    u = los / np.where(dist > 0, dist, 1.0)
    along = np.sum(step * u, -1, keepdims=True) * u
    across = step - along
    speed = np.degrees(np.linalg.norm(across, axis=-1) / np.maximum(dist[:, 0], 1e-12)) / np.maximum(dt, 1e-12)
    scale = np.minimum(1.0, max_deg_s / np.maximum(speed, 1e-12))
    moved = along + across * scale[:, None]
    return target[start] + np.concatenate([np.zeros((1, 3)), np.cumsum(moved, axis=0)])
