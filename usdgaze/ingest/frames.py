"""Orientations of marker landmarks (Heck 5.2.2.2: the coordinate system of a triangle or a square).

Only displacements of these frames are used (last frame relative to first, one frame relative to
another), so any frame rigidly attached to the markers gives the same P+; what matters is that it
is built the same way on every frame.

The axes come from the markers' geometry (a triangle's first edge and normal, a square's sides);
:func:`fit_frames` then refits every frame by least squares (Kabsch) to the landmark's mean shape, so
that all its markers (the head top too) weigh in equally instead of the one edge that fixes an axis:
the same coordinate system, with less of the markers' jitter in it.
"""

from __future__ import annotations

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError


class FrameError(UsdGazeError):
    """Markers do not span a frame."""


def _unit(v: np.ndarray, what: str) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    bad = np.flatnonzero(n.reshape(-1) < 1e-9)
    if bad.size:
        at = f" at frame {bad[0]}" if n.ndim > 1 else ""
        raise FrameError(f"{what}: degenerate{at} (markers coincide or are collinear)")
    return v / n


def _from_axes(left: np.ndarray, forward: np.ndarray, what: str) -> np.ndarray:
    """Orthonormal frame (X left, Y up, Z forward) keeping ``forward`` and the plane of ``left``."""
    forward = _unit(forward, what)
    up = _unit(np.cross(forward, left), what)
    left = np.cross(up, forward)
    return rot.frame_rotation(left, up, forward)


def triangle_frames(p: np.ndarray, what: str = "triangle") -> np.ndarray:
    """Frames ``(F, 4)`` of marker triangles ``(F, 3, 3)``: X along the first edge, Z along the normal."""
    e1 = p[:, 1] - p[:, 0]
    e2 = p[:, 2] - p[:, 0]
    normal = np.cross(e1, e2)
    return _from_axes(e1, normal, what)


def square_axes(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Left and forward vectors of squares ``(F, 4, 3)`` listed left-front, left-back, right-back, right-front."""
    left = (p[:, 0] + p[:, 1]) - (p[:, 2] + p[:, 3])
    forward = (p[:, 0] + p[:, 3]) - (p[:, 1] + p[:, 2])
    return left, forward


def square_frames(p: np.ndarray, what: str = "square") -> np.ndarray:
    """Frames ``(F, 4)`` of marker squares: X left, Y up, Z forward of the landmark."""
    left, forward = square_axes(p)
    return _from_axes(left, forward, what)


def landmark_frames(p: np.ndarray, what: str) -> np.ndarray:
    """Frames of a triangle (3 markers) or a square (4 markers)."""
    if p.shape[1] == 3:
        return triangle_frames(p, what)
    if p.shape[1] == 4:
        return square_frames(p, what)
    raise FrameError(f"{what}: {p.shape[1]} markers; a landmark needs 3 (triangle) or 4 (square)")


def square_is_mirrored(p: np.ndarray, top: np.ndarray) -> bool:
    """True when a head top marker lies below the square's plane as its listed order orients it."""
    left, forward = square_axes(p)
    up = np.cross(forward, left)
    above = np.einsum("fi,fi->f", top - p.mean(axis=1), up)
    return bool(np.median(above) < 0)


def character_frame(forward: np.ndarray, up: np.ndarray, what: str = "character frame") -> np.ndarray:
    """Canonical character frame in the lab: up = lab up, forward = ``forward`` made horizontal.

    Returns the quaternion taking canonical vectors (X left, Y up, Z forward) to lab vectors.
    """
    up = _unit(np.asarray(up, dtype=float), what)
    forward = np.asarray(forward, dtype=float)
    horizontal = forward - np.dot(forward, up) * up
    if np.linalg.norm(horizontal) < 1e-6 * max(np.linalg.norm(forward), 1e-12):
        raise FrameError(f"{what}: the forward direction is vertical, so the subject's heading is unknown")
    horizontal = horizontal / np.linalg.norm(horizontal)
    return rot.frame_rotation(np.cross(up, horizontal), up, horizontal)


UPRIGHT_DEG = 45.0
"""At rest the head lies within this of straight above the base of the spine: the subject stands or sits."""


def off_upright(head: np.ndarray, up: np.ndarray) -> tuple[float, str]:
    """Angle (deg) of the mean direction of ``head`` positions ``(F, 3)`` (from the base of the spine)
    from ``up``, and the signed axis nearest that direction (``"+Y"``)."""
    direction = head / np.linalg.norm(head, axis=-1, keepdims=True)
    mean = np.nanmean(direction, axis=0)
    mean = mean / np.linalg.norm(mean)
    angle = float(np.degrees(np.arccos(np.clip(np.dot(mean, up), -1.0, 1.0))))
    i = int(np.argmax(np.abs(mean)))
    return angle, ("+" if mean[i] > 0 else "-") + "XYZ"[i]


def fit_frames(points: np.ndarray, initial: np.ndarray) -> np.ndarray:
    """Least-squares orientations ``(F, 4)`` of rigid marker groups ``(F, n, 3)``.

    The group's shape is its mean over frames in the ``initial`` frames; each frame's orientation is
    the rotation that best maps that shape onto the frame's centred markers (Kabsch, via SVD).
    """
    centred = points - points.mean(axis=1, keepdims=True)
    basis = rot.to_matrix(initial)
    shape = np.einsum("fji,fnj->fni", basis, centred).mean(axis=0)
    h = np.einsum("ni,fnj->fij", shape, centred)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("fij,fjk->fik", u, vt)))
    fix = np.ones((len(points), 3))
    fix[:, 2] = d
    r = np.einsum("fji,fj,fkj->fik", vt, fix, u)
    return rot.from_matrix(r)
