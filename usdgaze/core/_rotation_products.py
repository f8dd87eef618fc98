"""The products and norms the rest of :mod:`usdgaze.core.rotations` builds on: dot and cross
products, lengths and normalization, and the Hamilton product of quaternions (plain and normalized),
written for speed and giving the plain numpy forms' bits.

Private: import these from :mod:`usdgaze.core.rotations`, the one rotation module, whose docstring
states the conventions (quaternions (x, y, z, w); ``multiply(a, b)`` applies ``b`` first).
"""

from __future__ import annotations

import numpy as np


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (or unit vectors); zero-length inputs stay zero."""
    q = np.asarray(q, dtype=float)
    n = np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]
    if (n > 0).all():  # the usual case: a plain division, the same values, without the masked one's cost
        return q / n
    return np.divide(q, n, out=np.zeros_like(q), where=n > 0)


def dot(a: np.ndarray, b: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Dot products of float vectors over the last axis, broadcasting: ``np.sum(a * b, axis=-1)`` bit
    for bit.

    numpy reduces a short last axis (2 to 4 components) one row at a time, several times slower than
    these few whole-array products; summed in component order, as its reduction does for fewer than 8
    components (from 8 on it sums pairwise, so longer axes go to it).
    """
    n = max(a.shape[-1], b.shape[-1])
    if n >= 8 or a.shape[-1] != b.shape[-1]:
        return np.sum(a * b, axis=-1, keepdims=keepdims)
    out = a[..., 0] * b[..., 0]
    for i in range(1, n):
        out += a[..., i] * b[..., i]
    return out[..., None] if keepdims else out


def length(v: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean lengths of float vectors over the last axis: ``np.linalg.norm(v, axis=-1)`` bit for
    bit (see :func:`dot`)."""
    return np.sqrt(dot(v, v, keepdims))


# The Hamilton product's terms by ``a``'s component (x, y, z, w rows): which of ``b``'s components each
# output takes, and its sign; an output sums its w, x, y and z terms in that order, as below.
_TERMS = np.array([3, 2, 1, 0, 2, 3, 0, 1, 1, 0, 3, 2, 0, 1, 2, 3])
_SIGNS = np.array([1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0, -1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0, 1.0, 1.0])
_FEW = 256  # floats: up to 64 quaternions, where numpy's per-call cost outweighs the arithmetic


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (apply ``b`` first, then ``a``), broadcasting over batches."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.size <= _FEW and b.size <= _FEW:
        # The same products, summed in the same order (a sign flip is exact), in 6 numpy calls
        # instead of some 40: the gaze map's measures multiply a few rows at a time.
        terms = a[..., :, None] * (np.take(b, _TERMS, axis=-1) * _SIGNS).reshape(b.shape[:-1] + (4, 4))
        out = terms[..., 3, :] + terms[..., 0, :]
        out += terms[..., 1, :]
        out += terms[..., 2, :]
        return out
    out = np.empty(_shape(a, b))
    for i, component in enumerate(_product(a, b)):  # one at a time: a long clip's temporaries stay few
        out[..., i] = component
    return out


def _product(a: np.ndarray, b: np.ndarray):
    """The x, y, z and w components of the Hamilton product ``a * b``, one after the other."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    yield aw * bx + ax * bw + ay * bz - az * by
    yield aw * by - ax * bz + ay * bw + az * bx
    yield aw * bz + ax * by - ay * bx + az * bw
    yield aw * bw - ax * bx - ay * by - az * bz


def normalized_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``normalize(multiply(a, b))`` bit for bit, without storing the product and reading it back.

    The norm is summed as :func:`normalize`'s einsum sums a fresh product's contiguous axis of four:
    pairwise, (x^2 + z^2) + (y^2 + w^2) (tests hold the two to the same bits)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.size <= _FEW and b.size <= _FEW:
        return normalize(multiply(a, b))
    x, y, z, w = _product(a, b)
    n = np.sqrt((x * x + z * z) + (y * y + w * w))
    out = np.empty(_shape(a, b))
    if (n > 0).all():
        out[..., 0], out[..., 1], out[..., 2], out[..., 3] = x / n, y / n, z / n, w / n
        return out
    out[..., 0], out[..., 1], out[..., 2], out[..., 3] = x, y, z, w
    return normalize(out)  # zero-length rows stay zero, as there


def _shape(a: np.ndarray, b: np.ndarray) -> tuple[int, ...]:
    # np.broadcast_shapes is Python code, and these products are called by the thousand: the same
    # shapes, or one vector against a batch of them (a constant axis), are told without it.
    if a.shape == b.shape or (b.ndim == 1 and a.shape[-1:] == b.shape):
        return a.shape
    if a.ndim == 1 and b.shape[-1:] == a.shape:
        return b.shape
    return np.broadcast_shapes(a.shape, b.shape)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of 3-vectors, broadcasting (np.cross copies its inputs; this is hot)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(_shape(a, b))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out
