"""World-space line of sight: azimuth and elevation about the stage up axis, and two eyes' line of sight."""

from __future__ import annotations

import functools

import numpy as np

from usdgaze.core import rotations as rot


def _horizontal_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """e1, e2 with (e1, e2, up) right-handed, so azimuth atan2(d.e2, d.e1) is counter-clockwise from above."""
    # A pass asks a dozen times for the basis of one up axis (a stage's Y or Z): built once per axis.
    return _basis_of(np.asarray(up, dtype=float).tobytes())  # bytes: -0.0 is not 0.0 here


@functools.lru_cache(maxsize=16)
def _basis_of(up: bytes) -> tuple[np.ndarray, np.ndarray]:
    u = np.frombuffer(up)
    e1 = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = rot.normalize(e1 - (e1 @ u) * u)
    e2 = np.cross(u, e1)
    e1.setflags(write=False)  # shared by every caller
    e2.setflags(write=False)
    return e1, e2


def azimuth_elevation(direction: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(azimuth, elevation) in degrees of world directions ``(..., 3)`` about the stage up axis."""
    e1, e2 = _horizontal_basis(up)
    d = rot.normalize(direction)
    az = np.degrees(np.arctan2(d @ e2, d @ e1))
    out = np.empty(az.shape + (2,))  # np.stack's bits, without its wrapper
    out[..., 0], out[..., 1] = az, np.degrees(np.arcsin((d @ up).clip(-1.0, 1.0)))
    return out


def direction_from(az_el: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World directions from (azimuth, elevation) degrees."""
    e1, e2 = _horizontal_basis(up)
    az, el = np.radians(az_el[..., 0]), np.radians(az_el[..., 1])
    cos_el = np.cos(el)
    return (cos_el * np.cos(az))[..., None] * e1 + (cos_el * np.sin(az))[..., None] * e2 + np.sin(el)[..., None] * up


def line_of_sight(left_pos, left_dir, right_pos, right_dir) -> tuple[np.ndarray, np.ndarray]:
    """Cyclopean origin and line of sight of two eyes: from their midpoint to the point of sight,
    the midpoint of the rays' closest approach (parallel rays: the mean direction)."""
    origin = 0.5 * (left_pos + right_pos)
    w0 = left_pos - right_pos
    a = rot.dot(left_dir, left_dir)
    b = rot.dot(left_dir, right_dir)
    c = rot.dot(right_dir, right_dir)
    d = rot.dot(left_dir, w0)
    e = rot.dot(right_dir, w0)
    den = a * c - b * b
    ok = den > 1e-12
    safe = np.where(ok, den, 1.0)
    s = np.where(ok, (b * e - c * d) / safe, 0.0)
    t = np.where(ok, (a * e - b * d) / safe, 0.0)
    point = 0.5 * ((left_pos + s[..., None] * left_dir) + (right_pos + t[..., None] * right_dir))
    sight = point - origin
    converging = ok & (s > 0) & (t > 0)
    sight = np.where(converging[..., None], sight, left_dir + right_dir)
    return origin, rot.normalize(sight)


def directions_to_world(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Directions through per-frame (or one) 3x3 maps, normalized."""
    return rot.normalize(np.einsum("fij,fj->fi", np.broadcast_to(m, (len(v), 3, 3)), v))
