"""Array attributes' time samples as numpy arrays, read at the Sdf level where USD's value
resolution allows it: each authored sample once from the layer that holds it, USD's own
interpolation only for the times that fall strictly between two samples."""

from __future__ import annotations

from itertools import islice, repeat

import numpy as np
from pxr import Sdf, Usd

from usdgaze.errors import UsdGazeError


def authored_samples(attr: Usd.Attribute) -> tuple[Sdf.Layer, Sdf.Path, Sdf.LayerOffset] | None:
    """The layer spec whose time samples are the attribute's value, with its offset to stage time.

    None when value resolution is anything else (value clips, splines, a stronger default), in which
    case the caller reads through Usd.
    """
    if attr.GetResolveInfo().GetSource() != Usd.ResolveInfoSourceTimeSamples:
        return None
    return samples_spec(attr)


def samples_spec(attr: Usd.Attribute, skip: Sdf.Layer | None = None
                 ) -> tuple[Sdf.Layer, Sdf.Path, Sdf.LayerOffset] | None:
    """The strongest spec of ``attr``'s property stack that holds time samples, with its offset to stage
    time, the specs of ``skip`` left out (the value as resolved without that layer); None where a
    stronger default comes first or no spec holds samples."""
    for spec, offset in attr.GetPropertyStackWithLayerOffsets(Usd.TimeCode.Default()):
        layer, path = spec.layer, spec.path
        if skip is not None and layer.identifier == skip.identifier:
            continue
        if layer.GetNumTimeSamplesForPath(path):
            return layer, path, offset
        if spec.HasDefaultValue():  # a stronger default would win: not the simple case
            return None
    return None


def wrong_count(value, time, where: str, count: int) -> None:
    """Raise the one-line error for an array sample with the wrong number of entries, or none (a
    blocked sample: UsdSkel poses the rest pose there)."""
    at = "default" if time is None else f"time {time:g}"
    if value is None or isinstance(value, Sdf.ValueBlock):
        raise UsdGazeError(f"{where}: has no value at {at} (blocked)")
    value = np.asarray(value)
    n = value.shape[0] if value.ndim else 0
    raise UsdGazeError(f"{where}: {n} entries at {at}, expected {count} (one per joint)")


_CHUNK_SAMPLES = 256  # samples made one numpy array at a time: no second copy of a whole attribute


class _Rows:
    """The ``(F, count, width)`` result, filled a sample at a time with each sample's entries checked."""

    def __init__(self, times: np.ndarray, dtype, width: int, count: int, where: str):
        self.out = np.empty((len(times), count, width), dtype=dtype)
        self.times, self.count, self.width, self.where = times, count, width, where

    def put(self, rows, value, first: bool = False) -> None:
        try:
            # A shorter array would broadcast; the first sample's full shape stands for the attribute's type.
            if len(value) != self.count or (first and np.asarray(value).shape != (self.count, self.width)):
                raise ValueError
            self.out[rows] = value  # a Vt array: numpy copies it through the buffer protocol
        except (TypeError, ValueError):
            at = rows if np.ndim(rows) == 0 else rows[0]
            wrong_count(value, self.times[at], self.where, self.count)

    def put_all(self, values) -> None:
        """Every row in order from an iterator of samples, one numpy conversion per chunk: a chunk
        that is not ``(n, count, width)`` (unlike lengths raise) goes through ``put`` sample by sample,
        which refuses its first wrong sample as it would have alone."""
        for lo in range(0, len(self.out), _CHUNK_SAMPLES):
            chunk = list(islice(values, _CHUNK_SAMPLES))
            try:
                block = np.array(chunk, dtype=self.out.dtype)
            except (TypeError, ValueError):
                block = None
            if block is not None and block.shape[1:] == self.out.shape[1:]:
                self.out[lo:lo + len(chunk)] = block
                continue
            for i, value in enumerate(chunk, lo):
                self.put(i, value, first=i == 0)


def _sources(own_times: np.ndarray, times: np.ndarray) -> np.ndarray:
    """For each stage time, the index of the authored sample that is its value, or -1 where USD
    interpolates: a time at a sample takes it, one before the first or after the last sample takes
    that sample (USD holds the end values), one strictly between two samples needs USD."""
    last = len(own_times) - 1
    at = np.minimum(np.searchsorted(own_times, times), last)
    source = np.where(own_times[at] == times, at, -1)
    source[times < own_times[0]] = 0
    source[times > own_times[-1]] = last
    return source


class Samples:
    """An array attribute's time samples, listed once: from the one layer spec that holds them where
    value resolution is that simple (``found``, see :func:`authored_samples`), else from Usd."""

    def __init__(self, attr: Usd.Attribute):
        self.attr = attr
        self.found = authored_samples(attr) if attr else None
        self.own = self.found[0].ListTimeSamplesForPath(self.found[1]) if self.found else None

    def times(self) -> np.ndarray:
        """Stage times, as ``Usd.Attribute.GetTimeSamples`` gives them (which composes them anew on
        every call: several times the cost of listing them from the layer)."""
        if self.found is not None and self.found[2].IsIdentity():
            return np.asarray(self.own, dtype=float)
        return np.asarray(self.attr.GetTimeSamples() if self.attr else [], dtype=float)


def _read_sdf(samples: Samples, times: np.ndarray, rows: _Rows) -> None:
    """Fill ``rows`` from the one layer that holds the samples (USD for times between samples)."""
    layer, path, offset = samples.found
    own = samples.own
    own_times = np.array([offset * t for t in own], dtype=float) if not offset.IsIdentity() else np.asarray(own, float)
    query = layer.QueryTimeSample
    if len(own_times) == len(times) and np.array_equal(own_times, times):
        rows.put_all(map(query, repeat(path), own))
        return
    source = _sources(own_times, times)
    held = np.flatnonzero(source >= 0)
    # Times are sorted, so each sample's frames are one run of ``held``.
    starts = np.flatnonzero(np.r_[True, np.diff(source[held]) != 0])
    for n, (lo, hi) in enumerate(zip(starts, np.r_[starts[1:], len(held)])):
        rows.put(held[lo:hi], query(path, own[source[held[lo]]]), first=n == 0)
    for i in np.flatnonzero(source < 0):
        rows.put(i, samples.attr.Get(float(times[i])))


NOT_AUTHORED = "not authored (UsdSkel needs translations, rotations and scales for every animated joint)"
"""Why an animation array missing (no value, no samples) is refused: UsdSkel poses nothing without all three."""


def read_array(samples: Samples, times: np.ndarray, dtype, width: int, count: int, where: str) -> np.ndarray:
    """Values of an array attribute at ``times`` as ``(F, count, width)``; a default is broadcast.

    Read at the Sdf level when one layer holds the samples (the common case), else through Usd.
    """
    attr = samples.attr
    if not attr or not attr.HasAuthoredValue():
        raise UsdGazeError(f"{where}: {NOT_AUTHORED}")
    if samples.found is None and attr.GetNumTimeSamples() == 0:
        value = np.asarray(attr.Get(), dtype=dtype)
        if value.shape != (count, width):
            wrong_count(value, None, where, count)
        return np.broadcast_to(value, (len(times), count, width)).copy()
    rows = _Rows(times, dtype, width, count, where)
    if samples.found is not None:
        _read_sdf(samples, times, rows)
    else:
        for i, t in enumerate(times):
            rows.put(i, attr.Get(float(t)), first=True)
    return rows.out


_CHUNK_FRAMES = 4096  # checks run over frame chunks: no float64 or boolean copy of the whole animation


def check_values(rotations: np.ndarray, translations: np.ndarray, where: str, times=None, joints=None,
                 authored=None) -> None:
    """Finite values and unit quaternions, computed chunk by chunk in the arrays' own float32.

    A failure names the attribute, the time code and the joint (``times``, ``joints``: the arrays'
    frames and columns; ``authored``: per attribute, the times it authors, preferred over a frame
    that USD interpolates from a bad key)."""
    for lo in range(0, len(rotations), _CHUNK_FRAMES):
        r = rotations[lo:lo + _CHUNK_FRAMES]
        t = translations[lo:lo + _CHUNK_FRAMES]
        if not (np.isfinite(r).all() and np.isfinite(t).all()):
            bad = [(k, name, ~np.isfinite(v).all(axis=-1)) for k, (name, v) in
                   enumerate((("rotations", r), ("translations", t))) if not np.isfinite(v).all()]
            at = [_first_bad(mask, lo, times, (authored or {}).get(name)) + (name,) for k, name, mask in bad]
            frame, joint, name = min(at)
            raise UsdGazeError(f"{where}.{name}: NaN or infinite values{_at(frame, joint, times, joints)}")
        norm = np.sqrt(np.einsum("fjk,fjk->fj", r, r))
        off = np.abs(norm - 1.0) > 1e-2
        if np.any(off):
            frame, joint = _first_bad(off, lo, times, (authored or {}).get("rotations"))
            raise UsdGazeError(f"{where}.rotations: not unit quaternions{_at(frame, joint, times, joints)}"
                               f"{'' if times is None else f' (length {float(norm[frame - lo, joint]):.3g})'}")


def _first_bad(mask: np.ndarray, lo: int, times, authored) -> tuple[int, int]:
    """(frame, joint) of the first bad entry of a chunk's ``(F, J)`` mask: at an authored time where one is."""
    frames = np.flatnonzero(mask.any(axis=1))
    if times is not None and authored is not None and len(authored):
        keyed = frames[np.isin(np.asarray(times)[lo + frames], np.asarray(authored, dtype=float))]
        frames = keyed if len(keyed) else frames
    f = int(frames[0])
    return lo + f, int(np.flatnonzero(mask[f])[0])


def _at(frame: int, joint: int, times, joints) -> str:
    where = "" if times is None else f" at time code {float(times[frame]):g}"
    return where + ("" if joints is None else f" (joint '{joints[joint]}')")
