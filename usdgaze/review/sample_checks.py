"""The animation arrays' sample checks behind the ``AnimationArrays`` validator: every sample of an
array read from the one layer that holds them and checked as one array, and, within one validation
run, once for all the prims that share those samples (a crowd's instances of one asset)."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
from pxr import Usd

_CHECKED: dict[tuple, list] | None = None
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


Finding = tuple[str, str, int, int, int]
"""(kind, "time T" or "default" of its first sample, how many samples, of how many, entries in that
first sample): one kind of problem of one attribute."""


def bad_samples(attr: Usd.Attribute, n: int, width: int) -> list[Finding]:
    """Each kind of problem the attribute's samples have (Length, NotFinite, NotUnit, in that order),
    or []: a layer with a wrong length at one time and a NaN at another has two problems to fix, and
    reporting the first alone hid the second until the first was fixed."""
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


def _check_rows(times: list, values: list[np.ndarray], n: int, width: int) -> list[Finding]:
    """Per kind, the samples that fail it: a wrong length; NaN or infinite entries (in a sample of any
    length); a quaternion off unit length (in samples of the right length that are finite)."""
    lengths = np.fromiter(map(len, values), dtype=np.int64, count=len(values))
    right = lengths == n * width
    good = np.flatnonzero(right)
    # The right-length samples as one array (the common case is all of them): one check, not one a sample.
    a = np.asarray(values if len(good) == len(values) else [values[i] for i in good], dtype=float)
    a = a.reshape(len(good), n, width)
    finite = np.ones(len(values), dtype=bool)
    finite[good] = np.isfinite(a).all(axis=(1, 2))
    finite[~right] = [np.isfinite(values[i]).all() for i in np.flatnonzero(~right)]
    off_unit = np.zeros(len(values), dtype=bool)
    if width == 4:
        off_unit[good] = np.any(np.abs(np.linalg.norm(np.nan_to_num(a), axis=2) - 1.0) > 1e-2, axis=1) & finite[good]
    out = []
    for kind, bad in (("Length", ~right), ("NotFinite", ~finite), ("NotUnit", off_unit)):
        hits = np.flatnonzero(bad)
        if len(hits):
            i = int(hits[0])
            at = "default" if times[i] is None else f"time {times[i]:g}"
            out.append((kind, at, len(hits), len(values), len(values[i]) // width))
    return out


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
