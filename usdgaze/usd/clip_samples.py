"""The frames a clip is read at and its samples there: an animation's own samples (every frame added
between keys that lie far apart), or the stage's playback range for a character that holds one pose."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdSkel

from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError
from usdgaze.usd import checks
from usdgaze.usd.samples import Samples, check_values, read_array


_MOST_STILL_FRAMES = 1_000_000  # a still pose spread over more frames than this is a typo in the range


_HOLDS_ONE_POSE = "the animation holds one pose (no time samples on rotations, translations or scales)"


def _still_times(stage: Usd.Stage, where: str, what: str = _HOLDS_ONE_POSE) -> np.ndarray:
    """The frames of the stage's playback range, for a character that holds one pose (an animation
    of defaults only, or none): UsdSkel shows that pose at every time, so the gaze is added over the
    range the shot plays."""
    if not stage.HasAuthoredTimeCodeRange():
        raise UsdGazeError(f"{where}: {what} and the stage authors no startTimeCode/endTimeCode; author the "
                           "shot's range to add gaze to a still character")
    start, end = float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    step = float(stage.GetTimeCodesPerSecond()) / float(stage.GetFramesPerSecond())
    count = int(np.floor((end - start) / step + 1e-9)) + 1
    if count > _MOST_STILL_FRAMES:
        raise UsdGazeError(f"{where}: {what.split(' (')[0]} and the stage's range [{start:g}, {end:g}] spans "
                           f"{count} frames (at most {_MOST_STILL_FRAMES}); check startTimeCode/endTimeCode")
    return start + step * np.arange(count, dtype=float)


def rest_pose_samples(stage: Usd.Stage, rest_local: np.ndarray, where_skel: str):
    """Times and every joint's rest transform at each, as the arrays of an animation that holds the
    rest pose: what UsdSkel shows for a Skeleton with no animation bound."""
    times = _still_times(stage, where_skel, "the skeleton has no animation bound (UsdSkel shows its rest pose)")
    t, q, s = rot.decompose_tr(rest_local)
    shape = (len(times),) + t.shape
    return (times, np.broadcast_to(q.astype(np.float32), shape[:2] + (4,)).copy(),
            np.broadcast_to(t.astype(np.float32), shape).copy(), np.broadcast_to(s.astype(np.float16), shape).copy())


_RESOLVES_S = 0.05  # samples this close resolve a saccade's main phase (30-100 ms): left as they are


def _on_every_frame(times: np.ndarray, stage: Usd.Stage, where_anim: str) -> np.ndarray:
    """Sample times of a keyed animation with every frame between its first and last key added where
    keys lie more than a frame and more than 50 ms apart: UsdSkel interpolates between them, and a
    saccade written only at the keys would be smeared over the gap. A capture sampled at 20 Hz or
    faster stays as it is, whatever the stage's frame rate."""
    tcps = float(stage.GetTimeCodesPerSecond())
    step = tcps / float(stage.GetFramesPerSecond())
    if len(times) < 2 or float(np.max(np.diff(times))) <= max(step, _RESOLVES_S * tcps) * (1.0 + 1e-6):
        return times
    count = int(np.floor((times[-1] - times[0]) / step + 1e-9)) + 1
    if count > _MOST_STILL_FRAMES:
        raise UsdGazeError(f"{where_anim}: keys from {times[0]:g} to {times[-1]:g} span {count} frames "
                           f"(at most {_MOST_STILL_FRAMES}); check the time samples")
    grid = times[0] + step * np.arange(count, dtype=float)
    at = np.searchsorted(times, grid)
    near = np.minimum(np.abs(grid - times[np.maximum(at - 1, 0)]), np.abs(grid - times[np.minimum(at, len(times) - 1)]))
    # The keys stay exact; a frame within half a frame of one would only be a near-duplicate sample.
    return np.sort(np.concatenate([times, grid[near >= 0.5 * step]]))


def animation_samples(anim: UsdSkel.Animation, n: int, where_anim: str, joints: list[str] | None = None):
    """Time codes and checked rotation, translation and scale samples ``(F, n, .)`` of the animation,
    and whether it holds one pose: with defaults only, or one time sample (USD holds that value at
    every time), it is sampled at every frame of the stage's range."""
    attrs = [Samples(a) for a in (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr())]
    times = np.sort(np.concatenate([s.times() for s in attrs if s.attr] or [[]]))
    times = times[np.r_[True, times[1:] != times[:-1]]] if len(times) else times  # np.unique would import numpy.ma
    stage = anim.GetPrim().GetStage()
    held = len(times) == 0 or (len(times) == 1 and stage.HasAuthoredTimeCodeRange()
                               and stage.GetEndTimeCode() > stage.GetStartTimeCode())
    if held:
        times = _still_times(stage, where_anim)
    else:
        times = _on_every_frame(times, stage, where_anim)
    rotations = read_array(attrs[0], times, np.float32, 4, n, f"{where_anim}.rotations")
    translations = read_array(attrs[1], times, np.float32, 3, n, f"{where_anim}.translations")
    scales = read_array(attrs[2], times, np.float16, 3, n, f"{where_anim}.scales")
    authored = {name: s.times() for name, s in zip(("rotations", "translations"), attrs[:2]) if s.attr}
    check_values(rotations, translations, where_anim, times, joints, authored)
    checks.check_scales(scales, f"{where_anim}.scales")
    return times, rotations, translations, scales, held
