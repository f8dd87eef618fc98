"""The parametric gaze map: blending-based synthesis over (yaw, pitch) (Kovar & Gleicher 2004).

Build: the (yaw, pitch) space is sampled densely with random convex blends of nearby examples; each
blend's *real* parameter is measured as the gaze change its blended pose achieves on the canonical
chain (:func:`usdgaze.gaze.motion.achieved_gaze`). The examples themselves are samples too.

Query: the k nearest samples (in measured parameter space) are interpolated with the non-negative
weights of Kovar & Gleicher (``1/d_i - 1/d_k``, normalized), giving non-negative example weights.
That interpolation is only as smooth as the sampling (about 1 deg of error here), so a few
Gauss-Newton steps then adjust the weights of the examples it already blends until the blend's
measured gaze change meets the request (weights stay non-negative).

Outside the sampled region (e.g. pitch beyond the examples' rows, |yaw| beyond 180) the query is
clamped into the sampled box, and the rotation still missing is added to the neck (its share set by
``SynthesisSettings.neck_share``) with the eyes re-aimed to take the rest, so the map still returns a
motion that reaches the request on the canonical chain. Its timing is the nearest region's, with the
duration stretched by the ratio of gaze amplitudes so the extra rotation is not done faster.
Yaw is never wrapped: -180 and +180 are a right and a left turn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.gaze import motion
from usdgaze.gaze.neighbors import SortedPoints, squared_distances
from usdgaze.gaze.triangulation import example_geometry
from usdgaze.core import rotations as rot
from usdgaze.gaze.definition import GazeMapDefinition
from usdgaze.gaze.motion import GazeMotions


@dataclass(frozen=True)
class QueryResult:
    """Motions answered for a batch of queries, with their example weights and measured gaze change."""

    motions: GazeMotions
    weights: np.ndarray
    achieved: np.ndarray
    extrapolated: np.ndarray


def _random_blends(params: np.ndarray, count: int, blend_size: int, rng: np.random.Generator) -> np.ndarray:
    """Blend weights ``(count, E)`` of random blends of nearby examples.

    Two thirds are uniform points in the Delaunay triangles of the examples' nominal parameters
    (area-weighted, so the samples cover the space evenly instead of piling up at blend centroids);
    the rest mix an example with one of its ``blend_size`` nearest neighbours, which reaches the
    edges of the region and serves maps whose examples lie on one line.
    """
    n = len(params)
    weights = np.zeros((max(count, 0), n))
    if count <= 0 or n < 2:
        weights[:, 0] = 1.0  # one example: every blend is that example
        return weights
    k = int(min(max(blend_size, 2), n))
    triangles, near = example_geometry(params, k)
    a, b, c = (params[triangles[:, i]] for i in range(3))
    area = 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    n_tri = (2 * count) // 3 if len(triangles) and area.sum() > 0 else 0
    if n_tri:
        pick = rng.choice(len(triangles), size=n_tri, p=area / area.sum())
        r1, r2 = np.sqrt(rng.uniform(size=n_tri)), rng.uniform(size=n_tri)
        bary = np.column_stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2])
        rows = np.repeat(np.arange(n_tri), 3)
        np.add.at(weights, (rows, triangles[pick].ravel()), bary.ravel())
    n_pair = count - n_tri
    first = rng.integers(0, n, size=n_pair)
    second = near[first, rng.integers(1, k, size=n_pair)]
    frac = rng.uniform(size=n_pair)
    rows = np.arange(n_tri, count)
    np.add.at(weights, (rows, first), 1.0 - frac)
    np.add.at(weights, (rows, second), frac)
    return weights


_CHUNK = 1024  # queries corrected together: bounds the (Q, C, E) probe arrays
_CANDIDATES = 8  # examples a correction may reweight
_BACKTRACK = np.array([1.0, 0.5, 0.25])  # step scales a correction tries, largest first
_RIDGE = 1e-9 * np.eye(2)  # keeps a correction's 2x2 normal equations solvable
_LEAST_AMPLITUDE_DEG = 10.0
"""A clamped request's duration grows with its amplitude over the clamped one's, this at the least: a map
whose examples lie on a line clamps (0, 10) to (0, 0), and the ratio was 1e10 (a 2.5e9 s shift)."""


class ParametricGazeMap:
    """A queryable gaze map built from a :class:`GazeMapDefinition`."""

    def __init__(self, definition: GazeMapDefinition) -> None:
        self.definition = definition
        self.examples = definition.motions
        self._table = motion.blend_table(self.examples)
        self.params = definition.params
        s = definition.settings
        rng = np.random.default_rng(s.seed)

        weights = _random_blends(self.params, s.samples, s.blend_size, rng)
        weights = np.concatenate([np.eye(len(self.params)), weights])
        self.sample_weights = weights
        self.sample_params = self._measure(weights)
        self._samples = SortedPoints(self.sample_params)  # the k-NN search of each query
        self.k = int(min(max(s.neighbors, 1), len(weights)))
        self.low = self.sample_params.min(axis=0)
        self.high = self.sample_params.max(axis=0)

    # -- measuring -------------------------------------------------------------------------
    def _measure(self, weights: np.ndarray, checked: bool = False) -> np.ndarray:
        """Measured (yaw, pitch) of blends; yaw unwrapped near the blend's mean example yaw.
        ``checked``: float weights known non-negative with a positive sum per blend (a correction's)."""
        # The blend's and its hint's normalized weights (blend_shares' division, less its checks).
        share = weights / weights.sum(axis=-1, keepdims=True) if checked else motion.blend_shares(weights)
        offsets = motion.mixed_offsets(share @ self._table)
        hint = share @ self.params[:, 0]
        return motion.achieved_gaze(offsets, hint)

    # -- querying --------------------------------------------------------------------------
    def _interpolate(self, points: np.ndarray) -> np.ndarray:
        """Kovar & Gleicher k-NN interpolation of sample blend weights at ``points (Q, 2)``."""
        k = self.k
        dist, idx = self._samples.nearest(points, k + 1)
        if dist.shape[1] > k:
            cutoff = dist[:, k:k + 1]
            dist, idx = dist[:, :k], idx[:, :k]
        else:
            cutoff = dist[:, -1:] * (1.0 + 1e-9) + 1e-12
        with np.errstate(divide="ignore"):
            w = np.maximum(1.0 / np.maximum(dist, 1e-12) - 1.0 / np.maximum(cutoff, 1e-12), 0.0)
        exact = dist[:, 0] < 1e-9
        w[exact] = 0.0
        w[exact, 0] = 1.0
        # All k at the same distance as the cutoff: fall back to equal weights.
        empty = w.sum(axis=1) <= 0
        w[empty] = 1.0
        w /= w.sum(axis=1, keepdims=True)
        return np.einsum("qk,qke->qe", w, self.sample_weights[idx])

    def _correct(self, weights: np.ndarray, target: np.ndarray, iterations: int) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Newton steps on the blend weights toward ``target``; the weights and their measured change.

        The examples that may change are those the k-NN answer blends plus the examples nearest the
        target (so an answer stuck on one meridian can lean on the next), weights stay
        non-negative, and a step is kept only where it brings the measured change closer.
        """
        q, n = weights.shape
        c = min(n, _CANDIDATES)
        eps = 1e-4
        dist_by_example = np.sqrt(squared_distances(self.params, target))  # (Q, E), example order
        score = np.where(weights > 1e-9, -1.0, dist_by_example)
        cand = np.argsort(score, axis=1, kind="stable")[:, :c]  # (Q, C) example indices
        rows, probed = np.arange(q)[:, None], (np.arange(q)[:, None], np.arange(c)[None, :], cand)
        achieved = self._measure(weights, checked=True)
        for _ in range(iterations):
            err = target - achieved
            probe = np.repeat(weights[:, None, :], c, axis=1)
            probe[probed] += eps
            moved = self._measure(probe.reshape(-1, n), checked=True).reshape(q, c, 2)
            jac = np.swapaxes(moved - achieved[:, None, :], 1, 2) / eps  # (Q, 2, C)
            # Projected step: a candidate at zero weight that the step would push negative is
            # held at zero and the step recomputed without it, instead of clipping the step
            # afterwards (which spoils it and stalls the correction at ~0.5 deg).
            w_cand = weights[rows, cand]
            at_zero = w_cand <= 1e-12
            free = np.ones((q, c), dtype=bool)
            for _ in range(c):
                jac_free = jac * free[:, None, :]
                normal = jac_free @ np.swapaxes(jac_free, 1, 2) + _RIDGE
                step = np.einsum("qcm,qc->qm", jac_free, np.linalg.solve(normal, err[..., None])[..., 0])
                blocked = free & at_zero & (step < 0.0)
                if not blocked.any():
                    break
                free &= ~blocked
            # Backtracking from the same start (the non-negativity clip can spoil a full step): the
            # candidates are measured in one batch, then taken in order wherever each is closer.
            candidates = np.repeat(weights[None], len(_BACKTRACK), axis=0)  # (S, Q, E)
            candidates[:, rows, cand] = np.maximum(w_cand + _BACKTRACK[:, None, None] * step, 0.0)
            total = candidates.sum(axis=2, keepdims=True)
            candidates = np.where(total > 0, candidates / np.where(total > 0, total, 1.0), weights)
            measured = self._measure(candidates.reshape(-1, n), checked=True).reshape(len(_BACKTRACK), q, 2)
            best_err = rot.length(err)
            for candidate, cand_achieved in zip(candidates, measured):
                cand_err = rot.length(target - cand_achieved)
                better = cand_err < best_err
                weights = np.where(better[:, None], candidate, weights)
                achieved = np.where(better[:, None], cand_achieved, achieved)
                best_err = np.minimum(cand_err, best_err)
        return weights, achieved

    def _clamped(self, yaw_deg, pitch_deg):
        """Requests ``(Q, 2)`` broadcast to one shape, clamped into the sampled box, and which were clamped."""
        yaw, pitch = np.broadcast_arrays(np.asarray(yaw_deg, float), np.asarray(pitch_deg, float))
        request = np.stack([yaw.ravel(), pitch.ravel()], axis=-1)
        inside = np.clip(request, self.low, self.high)
        return yaw.shape, request, inside, (np.abs(inside - request) > 1e-9).any(axis=1)

    @staticmethod
    def _stretched(timing: np.ndarray, request: np.ndarray, inside: np.ndarray) -> np.ndarray:
        """Timing of clamped requests: the extra rotation must not make the shift faster than the
        region it borrows its timing from, so the duration grows by the ratio of gaze amplitudes."""
        ratio = np.linalg.norm(request, axis=1) / np.maximum(np.linalg.norm(inside, axis=1), _LEAST_AMPLITUDE_DEG)
        timing[:, motion.DURATION] *= np.maximum(ratio, 1.0)
        return timing

    def query_full(self, yaw_deg, pitch_deg, correct: bool = True) -> QueryResult:
        """Answer a batch of gaze changes; broadcasting ``yaw_deg`` and ``pitch_deg`` to one shape.

        ``correct=False`` skips the Gauss-Newton correction: the plain Kovar & Gleicher answer.
        """
        clamped = self._clamped(yaw_deg, pitch_deg)
        return self._answer(clamped, self._interpolate(clamped[2]), correct)

    def query_with_timing(self, yaw_deg, pitch_deg, timing_yaw, timing_pitch) -> tuple[QueryResult, np.ndarray]:
        """``query_full(yaw_deg, pitch_deg)`` and ``timing(timing_yaw, timing_pitch)``, bit for bit, with
        one k-NN interpolation of both sets (each row's weights are its own either way): a scheduler
        asks for its new shifts and their changes' timing together."""
        asked, timed = self._clamped(yaw_deg, pitch_deg), self._clamped(timing_yaw, timing_pitch)
        weights = self._interpolate(np.concatenate([asked[2], timed[2]]))
        n = len(asked[2])
        return self._answer(asked, weights[:n]), self._timing_of(timed, weights[n:])

    def _answer(self, clamped: tuple, weights: np.ndarray, correct: bool = True) -> QueryResult:
        """:meth:`query_full`'s answer from the clamped requests and their k-NN blend weights."""
        shape, request, inside, extrapolated = clamped
        achieved = np.empty_like(inside) if correct else self._measure(weights)
        for lo in range(0, len(inside) if correct else 0, _CHUNK):
            part = slice(lo, lo + _CHUNK)
            weights[part], achieved[part] = self._correct(weights[part], inside[part], self.definition.settings.refine)

        blended = motion.blend(self.examples, weights, self._table)
        offsets, timing = blended.offsets, blended.timing
        if extrapolated.any():
            offsets, timing = offsets.copy(), timing.copy()
            offsets[extrapolated] = self._extend(offsets[extrapolated], request[extrapolated])
            achieved[extrapolated] = motion.achieved_gaze(offsets[extrapolated], request[extrapolated, 0])
            timing[extrapolated] = self._stretched(timing[extrapolated], request[extrapolated], inside[extrapolated])
        motions = GazeMotions(offsets.reshape(shape + (5, 4)), timing.reshape(shape + (7,)))
        return QueryResult(
            motions,
            weights.reshape(shape + (-1,)),
            achieved.reshape(shape + (2,)),
            extrapolated.reshape(shape),
        )

    def timing(self, yaw_deg, pitch_deg) -> np.ndarray:
        """The timing floats ``(..., 7)`` of the uncorrected answer (``query_full(correct=False)``'s,
        bit for bit), for callers that need only when a shift's segments move: no offsets are built."""
        clamped = self._clamped(yaw_deg, pitch_deg)
        return self._timing_of(clamped, self._interpolate(clamped[2]))

    def _timing_of(self, clamped: tuple, weights: np.ndarray) -> np.ndarray:
        """:meth:`timing`'s answer from the clamped changes and their k-NN blend weights."""
        shape, request, inside, extrapolated = clamped
        timing = motion.blend_timing(self._table, weights)
        if extrapolated.any():
            timing[extrapolated] = self._stretched(timing[extrapolated], request[extrapolated], inside[extrapolated])
        return timing.reshape(shape + (7,))

    def query(self, yaw_deg, pitch_deg) -> GazeMotions:
        """Gaze displacement motions for requested gaze changes (degrees)."""
        return self.query_full(yaw_deg, pitch_deg).motions

    def _extend(self, offsets: np.ndarray, request: np.ndarray) -> np.ndarray:
        """Add the rotation the clamped answer lacks: part to the neck, the rest by re-aiming the eyes."""
        yaw = np.clip(request[:, 0], -180.0, 180.0)
        pitch = np.clip(request[:, 1], -89.0, 89.0)
        below_neck = motion.chain_rotation(offsets[:, :3])
        current = rot.rotate(motion.chain_rotation(offsets), rot.FORWARD)
        wanted = rot.yaw_pitch_to_direction(yaw, pitch)
        missing = rot.power(rot.shortest_arc(current, wanted), self.definition.settings.neck_share)
        # Express the missing world rotation in the neck's parent frame, then apply it there.
        neck_extra = rot.multiply(rot.multiply(rot.conjugate(below_neck), missing), below_neck)
        out = offsets.copy()
        out[:, 3] = rot.multiply(neck_extra, offsets[:, 3])
        out[:, 4] = motion.aim_eyes(out[:, :4], yaw, pitch)
        return rot.positive_w(out)
