"""Quaternion and rotation helpers: the one module that knows conventions.

Conventions used everywhere in usdgaze:

* Quaternions are numpy arrays of shape ``(..., 4)`` in **(x, y, z, w)** order, the order of
  ``Vt.QuatfArray`` buffers and of ``scipy.spatial.transform.Rotation`` (which this module does not
  import: its matrix conversions are numpy, matching scipy's bit for bit).
* Rotation matrices act on **column vectors** (``v' = R @ v``). USD's ``GfMatrix4d`` acts on row
  vectors; :func:`matrices_from_usd` / :func:`matrices_to_usd` convert at the boundary.
* The *canonical character frame* is right-handed with +X = the character's left, +Y = up,
  +Z = forward. Gaze-map offsets are expressed in it.
* Angles in the public interface are degrees; everything in here is radians unless the name says
  ``_deg``.

The products and norms everything here builds on (``dot``, ``length``, ``normalize``, ``cross``,
``multiply``, ``normalized_product``) are written in :mod:`._rotation_products`, a private sibling:
they are imported from here, this module being the one to import.
"""

from __future__ import annotations

import numpy as np

from usdgaze.core._rotation_products import (  # noqa: F401  (this module's names; the private ones too)
    _FEW, _SIGNS, _TERMS, _product, _shape, cross, dot, length, multiply, normalize, normalized_product)

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
LEFT = np.array([1.0, 0.0, 0.0])
UP = np.array([0.0, 1.0, 0.0])
FORWARD = np.array([0.0, 0.0, 1.0])


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions of the given batch shape."""
    out = np.zeros(shape + (4,))
    out[..., 3] = 1.0
    return out


def positive_w(q: np.ndarray) -> np.ndarray:
    """The representative with w >= 0 (the same rotation), so lerp blends stay on one hemisphere."""
    q = np.asarray(q, dtype=float)
    return np.where(q[..., 3:4] < 0.0, -q, q)


def mirror_left_right(q: np.ndarray) -> np.ndarray:
    """The rotations a left-right mirror image makes of ``q`` in the canonical frame (x = left): a
    turn toward the left becomes one toward the right, pitch stays, roll flips."""
    return np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, 1.0])


def conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion."""
    q = np.asarray(q, dtype=float)
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)``: ``v + w t + u x t`` with
    ``t = 2 u x v``, ``u`` the vector part. Component by component: the same products and sums
    as the two cross products and the sums of whole vectors, without storing and reading back
    ``t`` and the cross products (rotations are the pass's commonest step)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    ux, uy, uz, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    tx, ty, tz = 2.0 * (uy * vz - uz * vy), 2.0 * (uz * vx - ux * vz), 2.0 * (ux * vy - uy * vx)
    out = np.empty(_shape(q[..., :3], v))
    out[..., 0] = vx + w * tx + (uy * tz - uz * ty)
    out[..., 1] = vy + w * ty + (uz * tx - ux * tz)
    out[..., 2] = vz + w * tz + (ux * ty - uy * tx)
    return out


def to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis * angle, angle in [0, pi]) of quaternions ``(..., 4)``."""
    q = positive_w(normalize(q))
    v = q[..., :3]
    s = length(v, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:4])
    # angle / sin(angle/2) -> 2 as the angle goes to zero
    small = s <= 1e-12
    scale = angle / np.where(small, 1.0, s)
    scale[small] = 2.0
    return v * scale


def from_rotvec(r: np.ndarray) -> np.ndarray:
    """Quaternions from rotation vectors ``(..., 3)`` (any angle, including beyond pi)."""
    r = np.asarray(r, dtype=float)
    angle = length(r, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle -> 1/2 as the angle goes to zero
    k = np.divide(np.sin(half), angle, out=np.full_like(angle, 0.5), where=angle > 1e-12)
    return np.concatenate([r * k, np.cos(half)], axis=-1)


_ROWS = 1 << 16  # quaternions per step where a whole-array computation would make large temporaries


def angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle in radians, in [0, pi]; computed in steps of rows, so a long clip's temporaries
    stay small (each row's value is the same either way)."""
    q = np.asarray(q, dtype=float)
    flat = q.reshape(-1, 4)
    out = np.empty(len(flat))
    for lo in range(0, len(flat), _ROWS):
        out[lo:lo + _ROWS] = length(to_rotvec(flat[lo:lo + _ROWS]))
    return out.reshape(q.shape[:-1])


def power(q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Scale the rotation angle of ``q`` by ``s`` (``q ** s``); ``s`` broadcasts against ``q[..., 0]``."""
    return from_rotvec(to_rotvec(q) * np.asarray(s, dtype=float)[..., None])


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 * b``: the rotation that takes ``a`` to ``b`` in ``a``'s frame."""
    return multiply(conjugate(a), b)


def from_axis_angle(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Quaternions rotating by ``angle_rad`` about ``axis`` (broadcasting)."""
    axis = normalize(np.asarray(axis, dtype=float))
    return from_rotvec(axis * np.asarray(angle_rad, dtype=float)[..., None])


def shortest_arc(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The minimal rotation taking direction ``u`` to direction ``v`` (Listing's law for eyes)."""
    u = normalize(u)
    v = normalize(v)
    d = dot(u, v, keepdims=True)  # both broadcast as they go: u is often one direction per batch
    axis = cross(u, v)
    q = np.concatenate([axis, 1.0 + d], axis=-1)
    # Antiparallel: rotate 180 deg about any axis perpendicular to u.
    anti = (1.0 + d[..., 0]) < 1e-12
    if anti.any():
        ua = np.broadcast_to(u, axis.shape)[anti]
        helper = np.where(np.abs(ua[:, :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
        perp = normalize(np.cross(ua, helper))
        q[anti] = np.concatenate([perp, np.zeros((len(ua), 1))], axis=-1)
    return normalize(q)


def _norm4(q: np.ndarray) -> np.ndarray:
    """Quaternion lengths summed in component order (as scipy's Rotation does, so results match it bit for bit)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.sqrt(x * x + y * y + z * z + w * w)


def _orthogonal_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternions of orthogonal matrices ``(N, 3, 3)``: Shepperd's method, largest-pivot case per matrix.

    All four cases are formed for every matrix and each matrix takes its own (a few whole-array
    operations, where selecting each case's matrices first cost some thirty small ones)."""
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    choice = np.argmax(np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 2, 2], trace], axis=-1), axis=-1)
    cases = np.empty((len(m), 4, 4))
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        cases[:, i, i] = 1 - trace + 2 * m[:, i, i]
        cases[:, i, j] = m[:, j, i] + m[:, i, j]
        cases[:, i, k] = m[:, k, i] + m[:, i, k]
        cases[:, i, 3] = m[:, k, j] - m[:, j, k]
    cases[:, 3, 0] = m[:, 2, 1] - m[:, 1, 2]
    cases[:, 3, 1] = m[:, 0, 2] - m[:, 2, 0]
    cases[:, 3, 2] = m[:, 1, 0] - m[:, 0, 1]
    cases[:, 3, 3] = 1 + trace
    q = cases[np.arange(len(m)), choice]
    return q / _norm4(q)[:, None]


_EYE3 = np.eye(3)
_EYE3_CLOSE = 1e-12 + 1e-05 * np.abs(_EYE3)  # np.isclose's atol + rtol * |b|, its default rtol


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Quaternions from (column-vector) rotation matrices ``(..., 3, 3)``; scale is removed first.

    A matrix that is not orthogonal to 1e-12 is replaced by its nearest rotation (SVD). numpy only,
    the same operations as ``scipy.spatial.transform.Rotation.from_matrix`` (tests compare the two
    bit for bit), without importing scipy.spatial (~0.2 s) on the apply path.
    """
    m = np.asarray(m, dtype=float)
    shape = m.shape[:-2]
    cols = (m / np.linalg.norm(m, axis=-2, keepdims=True)).reshape(-1, 3, 3)
    if np.any(np.linalg.det(cols) <= 0):
        raise ValueError("non-positive determinant (left-handed or null coordinate frame) in a rotation matrix")
    gram = cols @ np.swapaxes(cols, -1, -2)
    # np.isclose(gram, I, atol=1e-12) for a finite identity, without its wrapper's two dozen calls
    skewed = ~(np.abs(gram - _EYE3) <= _EYE3_CLOSE).all(axis=(-2, -1))
    if skewed.any():
        u, _, vt = np.linalg.svd(cols[skewed], full_matrices=False)
        cols[skewed] = u @ vt
    return positive_w(_orthogonal_to_quat(cols)).reshape(shape + (4,))


def to_matrix(q: np.ndarray) -> np.ndarray:
    """(Column-vector) rotation matrices ``(..., 3, 3)`` of quaternions (normalized first)."""
    q = np.asarray(q, dtype=float)
    n = _norm4(q)
    if np.any(n == 0):
        raise ValueError("zero-length quaternion")
    q = q / n[..., None]
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = x2 - y2 - z2 + w2
    m[..., 0, 1] = 2 * (xy - zw)
    m[..., 0, 2] = 2 * (xz + yw)
    m[..., 1, 0] = 2 * (xy + zw)
    m[..., 1, 1] = -x2 + y2 - z2 + w2
    m[..., 1, 2] = 2 * (yz - xw)
    m[..., 2, 0] = 2 * (xz - yw)
    m[..., 2, 1] = 2 * (yz + xw)
    m[..., 2, 2] = -x2 - y2 + z2 + w2
    return m


def frame_rotation(left: np.ndarray, up: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """Quaternion mapping the canonical frame (X left, Y up, Z forward) onto the given axes."""
    m = np.stack([left, up, forward], axis=-1)
    return from_matrix(m)


def yaw_pitch_to_direction(yaw_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """Unit direction in the canonical frame for azimuth ``yaw`` (toward +X) and elevation ``pitch``."""
    y = np.radians(yaw_deg)
    p = np.radians(pitch_deg)
    cos_p = np.cos(p)
    return np.stack([np.sin(y) * cos_p, np.sin(p), np.cos(y) * cos_p], axis=-1)


def direction_to_yaw_pitch(d: np.ndarray, yaw_hint_deg: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and elevation (degrees) of canonical-frame directions.

    The azimuth is unwrapped to the branch nearest ``yaw_hint_deg`` so that a left turn of 180 deg
    reads +180 and a right turn -180.
    """
    d = normalize(d)
    yaw = np.degrees(np.arctan2(d[..., 0], d[..., 2]))
    yaw = unwrap_near(yaw, yaw_hint_deg)
    pitch = np.degrees(np.arcsin(d[..., 1].clip(-1.0, 1.0)))  # the array's own clip: np.clip's, less a wrapper
    return yaw, pitch


def unwrap_near(angle_deg: np.ndarray, hint_deg: np.ndarray | float) -> np.ndarray:
    """The representative of ``angle_deg`` (mod 360) nearest to ``hint_deg``."""
    hint = np.asarray(hint_deg, dtype=float)
    return hint + (np.asarray(angle_deg) - hint + 180.0) % 360.0 - 180.0


def unwrap_from_kept(angle_deg: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Angles ``(..., F)`` over frames: where ``keep`` as they are, elsewhere unwrapped (mod 360)
    continuously from the last kept frame before (the first frame, where none is)."""
    if keep.all():
        return angle_deg
    unwrapped = np.unwrap(angle_deg, period=360.0, axis=-1)
    frames = np.arange(angle_deg.shape[-1])
    anchor = np.maximum.accumulate(np.where(keep, frames, 0), axis=-1)
    return unwrapped - np.take_along_axis(unwrapped - angle_deg, np.broadcast_to(anchor, angle_deg.shape), axis=-1)


def yaw_pitch_rotation(yaw_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """Canonical-frame rotation: yaw about +Y (toward the left) after pitch up about the left axis."""
    yaw = from_axis_angle(UP, np.radians(yaw_deg))
    pitch = from_axis_angle(-LEFT, np.radians(pitch_deg))
    return multiply(yaw, pitch)


def conjugate_into(frame: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Express the rotation ``q`` given in a frame whose axes are ``frame`` (a quaternion) in the outer frame."""
    return multiply(multiply(frame, q), conjugate(frame))


def matrices_from_usd(m: np.ndarray) -> np.ndarray:
    """Column-vector 4x4 matrices from USD row-vector matrices ``(..., 4, 4)``."""
    return np.swapaxes(np.asarray(m, dtype=float), -1, -2)


def matrices_to_usd(m: np.ndarray) -> np.ndarray:
    """USD row-vector 4x4 matrices from column-vector ones."""
    return np.swapaxes(np.asarray(m, dtype=float), -1, -2)


def compose_trs(translation: np.ndarray, rotation: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Column-vector 4x4 matrices ``T * R * S`` (UsdSkel's local transform order)."""
    translation = np.asarray(translation, dtype=float)
    shape = translation.shape[:-1]
    m = np.zeros(shape + (4, 4))
    m[..., :3, :3] = to_matrix(rotation) * np.asarray(scale, dtype=float)[..., None, :]
    m[..., :3, 3] = translation
    m[..., 3, 3] = 1.0
    return m


def rotation_part(lin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and per-axis scale of column-vector linear parts ``(..., 3, 3)`` without shear: ``lin =
    R diag(scale)``. A mirrored part (negative determinant: a negative scale, as some rigs mirror a
    joint) takes the mirror on its x scale, as UsdSkel's own decomposition does."""
    lin = np.asarray(lin, dtype=float)
    scale = np.linalg.norm(lin, axis=-2)
    mirrored = np.linalg.det(lin) < 0.0
    if np.any(mirrored):
        flip = np.where(mirrored[..., None], [-1.0, 1.0, 1.0], 1.0)
        scale, lin = scale * flip, lin * flip[..., None, :]
    return from_matrix(lin), scale


def decompose_tr(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translation, rotation and per-axis scale of column-vector 4x4 matrices without shear (see
    :func:`rotation_part`)."""
    m = np.asarray(m, dtype=float)
    q, scale = rotation_part(m[..., :3, :3])
    return m[..., :3, 3].copy(), q, scale


def align_hemisphere(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``q`` with its sign flipped where that brings it onto ``ref``'s hemisphere (same rotations).

    Keeps consecutive samples of a joint on one hemisphere, as the input had them, so that
    interpolation between time samples never takes the long way round.
    """
    q = np.asarray(q, dtype=float)
    return np.where(dot(q, np.asarray(ref), keepdims=True) < 0.0, -q, q)  # float32 refs widen exactly
