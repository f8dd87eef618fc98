"""The animation arrays' sample checks behind the ``AnimationArrays`` validator: every sample of an
array read from the one layer that holds them and checked as one array, and, within one validation
run, once for all the prims that share those samples (a crowd's instances of one asset)."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
from pxr import Usd

_CHECKED: dict[tuple, tuple[str, str, int] | None] | None = None
"""While :func:`shared_samples` is on: (layer, spec path, joints, width) -> :func:`_check_rows`'
answer for samples read from that layer spec. A crowd's instances of one asset share them, and each
instance is validated (checked once each, a 100-character crowd's validate took 3.1 s)."""


@contextmanager
def shared_samples():
    """Check samples shared by several prims once, for one validation run (layers do not change
    during it; across runs they may, so other callers of these validators check every prim)."""
    global _CHECKED
    _CHECKED = {}
    try:
        yield
    finally:
        _CHECKED = None


def first_bad(attr: Usd.Attribute, n: int, width: int) -> tuple[str, str, int] | None:
    """(kind, "time T" or "default", entries) of the first sample that fails, or None."""
    from usdgaze.usd.samples import Samples

    samples = Samples(attr)
    shared = samples.found is not None and samples.found[2].IsIdentity()
    memo = _CHECKED
    key = (samples.found[0].identifier, str(samples.found[1]), n, width) if shared and memo is not None else None
    if key is not None and key in memo:
        return memo[key]
    answer = _check_rows(*_all_samples(samples), n, width)
    if key is not None:
        memo[key] = answer
    return answer


def _check_rows(times: list, values: list[np.ndarray], n: int, width: int) -> tuple[str, str, int] | None:
    """The first sample at which any check fails, in the order length, finite, unit."""
    wrong = next((i for i, v in enumerate(values) if len(v) != n * width), len(values))
    a = np.asarray(values[:wrong], dtype=float).reshape(wrong, n, width)
    bad_finite = ~np.isfinite(a).all(axis=(1, 2))
    bad_unit = np.zeros(wrong, dtype=bool) if width != 4 else \
        np.any(np.abs(np.linalg.norm(np.nan_to_num(a), axis=2) - 1.0) > 1e-2, axis=1) & ~bad_finite
    first = np.flatnonzero(bad_finite | bad_unit)
    i = int(first[0]) if len(first) else wrong
    if i >= len(values):
        return None
    at = "default" if times[i] is None else f"time {times[i]:g}"
    kind = "Length" if i == wrong else "NotFinite" if bad_finite[i] else "NotUnit"
    return kind, at, len(values[i]) // width


def _all_samples(samples) -> tuple[list, list[np.ndarray]]:
    """(times, flat values) of an array attribute, its default as time None where it has no samples;
    from the one layer that holds the samples where that is where they resolve (a ``Get`` per sample
    composed each anew: a 200-character crowd's took 12 s)."""
    def flat(value) -> np.ndarray:
        return np.asarray(value if value is not None else [], dtype=float).ravel()

    attr = samples.attr
    if samples.found is not None and samples.found[2].IsIdentity():
        layer, path, _ = samples.found
        times = list(samples.own)
        return times, [flat(layer.QueryTimeSample(path, t)) for t in times]
    times = attr.GetTimeSamples()
    if not times:
        return [None], [flat(attr.Get())]
    return list(times), [flat(attr.Get(t)) for t in times]
