"""Exact k nearest neighbours in a small point set, numpy only.

The gaze map queries a few thousand samples in 2-D; a brute-force pass over them costs less than
importing scipy.spatial (~0.2 s of every apply process), and gives the same answer as scipy's
``cKDTree.query``: the same Euclidean distances bit for bit, nearest first, ties broken by index.
"""

from __future__ import annotations

import numpy as np

_CHUNK = 512  # queries per distance table: bounds it to _CHUNK x len(points) floats


def squared_distances(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """``(Q, N)`` squared distances, summed over dimensions in order (as cKDTree sums them)."""
    diff = queries[:, None, 0] - points[None, :, 0]
    out = diff * diff
    for d in range(1, points.shape[1]):
        diff = queries[:, None, d] - points[None, :, d]
        out += diff * diff
    return out


def _smallest(d2: np.ndarray, k: int) -> np.ndarray:
    """Column indices of each row's ``k`` smallest entries, ascending, ties by index."""
    n = d2.shape[1]
    wide = min(n, k + 8)  # a margin: a tie straddling the partition's edge is seen and resolved below
    if wide < n:
        part = np.argpartition(d2, wide - 1, axis=1)[:, :wide]
    else:
        part = np.broadcast_to(np.arange(n), d2.shape)
    vals = np.take_along_axis(d2, part, axis=1)
    order = np.lexsort((part, vals), axis=1)
    part, vals = np.take_along_axis(part, order, axis=1), np.take_along_axis(vals, order, axis=1)
    if wide < n:
        # Rows whose k-th value equals the largest kept one may have an equal value left outside.
        unsure = vals[:, k - 1] >= vals[:, -1]
        if np.any(unsure):
            full = np.argsort(d2[unsure], axis=1, kind="stable")[:, :wide]  # stable: ties by index
            part = part.copy()
            part[unsure] = full
    return part[:, :k]


def nearest(points: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Distances and indices ``(Q, k)`` of the ``k`` points nearest each query, nearest first."""
    points = np.asarray(points, dtype=float)
    queries = np.asarray(queries, dtype=float).reshape(-1, points.shape[1])
    k = int(min(k, len(points)))
    dist = np.empty((len(queries), k))
    idx = np.empty((len(queries), k), dtype=np.intp)
    for lo in range(0, len(queries), _CHUNK):
        d2 = squared_distances(points, queries[lo:lo + _CHUNK])
        near = _smallest(d2, k)
        idx[lo:lo + _CHUNK] = near
        dist[lo:lo + _CHUNK] = np.sqrt(np.take_along_axis(d2, near, axis=1))
    return dist, idx


_FEW = 8  # queries a SortedPoints answers one by one; more go to the brute-force pass
_PROBE = 32  # points each side of a query, in the sorted coordinate, that bound its k-th distance


class SortedPoints:
    """A fixed point set sorted by its first coordinate, for exact k nearest neighbours of a few
    queries at a time: :func:`nearest`'s answer, bit for bit, measuring only the strip of points
    near each query in that coordinate. A pass asks the gaze map for a few shifts at a time, and the
    brute-force pass over its 5,000 samples cost 120-240 us a query (np.argpartition, mostly)."""

    def __init__(self, points: np.ndarray) -> None:
        self.points = np.asarray(points, dtype=float)
        self.order = np.argsort(self.points[:, 0], kind="stable")
        self.first = self.points[self.order, 0]
        self.finite = bool(np.isfinite(self.points).all())  # else the brute-force pass (NaN orders last there)

    def nearest(self, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Distances and indices ``(Q, k)`` of the ``k`` points nearest each query, nearest first."""
        queries = np.asarray(queries, dtype=float).reshape(-1, self.points.shape[1])
        k = int(min(k, len(self.points)))
        if len(queries) > _FEW or k > _PROBE or not (self.finite and np.isfinite(queries).all()):
            return nearest(self.points, queries, k)
        if not len(queries):
            return np.empty((0, k)), np.empty((0, k), dtype=np.intp)
        d2, idx = self._strips(queries, k)
        return np.sqrt(d2), idx

    def _strips(self, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Squared distances and indices ``(Q, k)`` of the k points nearest each query, ascending, ties
        by index: all queries at once, each strip padded to the longest with infinite distances (a
        pass asks for 4-8 queries at a time, and one at a time cost some 15 numpy calls each)."""
        n = len(self.first)
        q0 = queries[:, 0]
        at = np.searchsorted(self.first, q0)
        # The k-th smallest distance to the points probed about each query bounds its k-th over all
        # of them: every point as near lies within that distance of it in the first coordinate (a
        # margin covers the rounding of the difference and of the square root). Every probe holds
        # at least k points (k <= _PROBE and k <= n), so the padding never reaches the k-th.
        bound = np.partition(self._padded(queries, at - _PROBE, at + _PROBE, n)[0], k - 1, axis=1)[:, k - 1]
        reach = np.sqrt(bound) * (1.0 + 1e-9) + 1e-12
        lo = np.searchsorted(self.first, q0 - reach, side="left")
        hi = np.searchsorted(self.first, q0 + reach, side="right")
        d2, near = self._padded(queries, lo, hi, n)
        pick = np.lexsort((near, d2), axis=-1)[:, :k]  # ascending distance, ties by index, as _smallest
        return np.take_along_axis(d2, pick, axis=1), np.take_along_axis(near, pick, axis=1)

    def _padded(self, queries: np.ndarray, lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Per query, the squared distances and indices of the sorted points ``lo..hi`` (clipped to the
        set), padded with infinite distances to the longest strip; each distance summed over the
        dimensions in order, as :func:`squared_distances` sums it."""
        lo, hi = np.maximum(lo, 0), np.minimum(hi, n)
        pos = lo[:, None] + np.arange(int((hi - lo).max()))
        near = self.order[np.minimum(pos, n - 1)]
        points = self.points[near]
        diff = queries[:, None, 0] - points[..., 0]
        d2 = diff * diff
        for d in range(1, points.shape[-1]):
            diff = queries[:, None, d] - points[..., d]
            d2 += diff * diff
        d2[pos >= hi[:, None]] = np.inf
        return d2, near
