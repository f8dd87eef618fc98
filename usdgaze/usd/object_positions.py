"""Where an object is: the translation of its local-to-world transform at the planner's times (for a
Boundable whose geometry is not centred on its origin, a mesh baked in world space, the centre of its
world bounds, as ``--look-at`` takes it; for animated geometry, that centre at every time).

Where an object's transform is one translate op whose value resolves to time samples of one layer
(any layer offset applied) under ancestors that do not move, its samples are read once at the Sdf
level and interpolated over all times with numpy, as USD does (linear, or held where the stage says
so). Anything else (several ops, animated parents, value clips, resetXformStack) is read per time
with ``UsdGeom.XformCache``, the general path; both give the same positions (tests/test_attend_objects.py).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from usdgaze.usd.samples import authored_samples
from usdgaze.usd.targets import PURPOSES, bounds_vary, sample_target


def sampled(attr: Usd.Attribute, time_codes: np.ndarray) -> np.ndarray | None:
    """``attr`` at every time code from its strongest layer's time samples, or None where USD must resolve
    it per time (value clips, splines, no samples). Sample times go through the layer offset to the stage."""
    source = attr.GetResolveInfo().GetSource()
    if source == Usd.ResolveInfoSourceDefault:
        value = np.asarray(attr.Get(), float).reshape(1, -1)
        return np.repeat(value, len(time_codes), 0)
    found = authored_samples(attr)  # None for a stronger default over weaker samples: USD says what wins
    if found is None:
        return None
    layer, path, offset = found
    layer_times = layer.ListTimeSamplesForPath(path)
    raw = [layer.QueryTimeSample(path, t) for t in layer_times]
    if any(isinstance(v, Sdf.ValueBlock) for v in raw):
        return None  # a blocked sample has no value there: USD says what the transform is (its op left out)
    values = np.array([np.asarray(v, float) for v in raw])
    times = np.array([offset * t for t in layer_times], float)
    order = np.argsort(times)  # a negative scale reverses them
    times, values = times[order], values[order].reshape(len(times), -1)
    t = np.asarray(time_codes, float)
    if attr.GetStage().GetInterpolationType() == Usd.InterpolationTypeHeld:
        return values[np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)]
    return np.stack([np.interp(t, times, values[:, i]) for i in range(values.shape[1])], -1)


def fast_positions(prim: Usd.Prim, time_codes: np.ndarray) -> np.ndarray | None:
    """World translations from one translate op's time samples under still ancestors, or None."""
    xf = UsdGeom.Xformable(prim)
    ops = xf.GetOrderedXformOps()
    if xf.GetResetXformStack() or len(ops) != 1 or ops[0].GetOpType() != UsdGeom.XformOp.TypeTranslate \
            or ops[0].IsInverseOp():
        return None
    parent = prim.GetParent()
    while parent and not parent.IsPseudoRoot():
        if parent.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(parent).TransformMightBeTimeVarying():
            return None
        parent = parent.GetParent()
    local = sampled(ops[0].GetAttr(), time_codes)
    if local is None:
        return None
    to_world = np.array(UsdGeom.XformCache(Usd.TimeCode(float(time_codes[0]))).GetParentToWorldTransform(prim))
    return local @ to_world[:3, :3] + to_world[3, :3]  # row vectors, as USD's matrices


def _off_centre(prim: Usd.Prim, time_code: float) -> bool:
    """A Boundable whose geometry is not centred on its origin (a mesh baked in world space): its
    position is the centre of its bounds, as a --look-at target's, not its transform's translation."""
    if not prim.IsA(UsdGeom.Boundable):
        return False
    centre, size = _own_centre(prim, time_code)
    return bool(np.linalg.norm(centre) > 1e-6 * max(1.0, float(np.linalg.norm(size))))


def _own_centre(prim: Usd.Prim, time_code: float) -> tuple[np.ndarray, np.ndarray]:
    """The centre and size of a Boundable's bounds in its own space at ``time_code`` (zeros where
    they are empty: it is then at its origin)."""
    # A cache per time: BBoxCache.SetTime keeps computed extents (see targets.sample_target).
    cache = UsdGeom.BBoxCache(Usd.TimeCode(time_code), PURPOSES, useExtentsHint=True)
    box = cache.ComputeUntransformedBound(prim)
    if box.GetRange().IsEmpty():
        return np.zeros(3), np.zeros(3)
    return np.asarray(box.ComputeCentroid(), float), np.asarray(box.GetRange().GetSize(), float)


def positions(prim: Usd.Prim, time_codes: np.ndarray, caches: list, source: str) -> np.ndarray:
    """An object's world position ``(K, 3)`` at ``time_codes``, in stage units; ``caches``: per-time
    ``UsdGeom.XformCache``s shared by every object of the shot (filled on first use)."""
    if prim.IsA(UsdGeom.Boundable) and bounds_vary(prim):
        # Animated geometry (baked points, a character's posed body): the centre of its bounds at each
        # time. Decided once at the first time, a mesh centred there was read at its origin for the shot.
        centres = np.array([np.append(_own_centre(prim, float(t))[0], 1.0) for t in time_codes])
        return np.einsum("ki,kij->kj", centres, _world_matrices(prim, time_codes, caches)[:, :, :3])
    if _off_centre(prim, float(time_codes[0])):
        return sample_target(prim.GetStage(), str(prim.GetPath()), time_codes, source, faces=False)  # its bounds
    fast = fast_positions(prim, time_codes)
    if fast is not None:
        return fast
    return _world_matrices(prim, time_codes, caches)[:, 3, :3]


def _world_matrices(prim: Usd.Prim, time_codes: np.ndarray, caches: list) -> np.ndarray:
    """(K, 4, 4) local-to-world matrices (row vectors), from per-time caches shared by every object."""
    if not caches:
        caches.extend(UsdGeom.XformCache(Usd.TimeCode(float(t))) for t in time_codes)
    return np.array([np.array(c.GetLocalToWorldTransform(prim)) for c in caches])
