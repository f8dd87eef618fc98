"""A shot cut from a longer take by its stage's playback range (``attend``, kinematic or ``--physics``).

Only the range is simulated, but the layer holds the take's own samples outside it: USD holds a
layer's first and last samples before and after them, so a layer of the range alone froze the
character on every frame of the take the shot does not play (its handles included), over a take it
was never asked to change. Composed over the take, those frames now keep the input's animation.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from usdgaze.errors import UsdGazeError


def cut_to_range(clip, stage, ahead_s: float, verbs: tuple[str, str] = ("simulated", "simulate")):
    """``(shot, ahead, take)``: the clip cut to the stage's playback range where the stage authors one
    inside the animation (a shot's root layer over a longer take; simulating the rest cost time for
    nothing: five times the shot's on a 49-frame shot over 241), the take's frames up to ``ahead_s``
    after the shot's end for the planner's windows there, and the whole take. Without a range inside
    the animation: ``(clip, None, None)``. ``verbs``: what the pass does to a shot's frames, for the refusal."""
    if not stage.HasAuthoredTimeCodeRange():
        return clip, None, None
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    lo, hi = np.searchsorted(clip.times, [start - 1e-9, end + 1e-9])
    if hi - lo < 2:  # nothing, or one pose, to simulate: the whole take was simulated and written before
        raise UsdGazeError(f"{clip.where()}: the stage's playback range {start:g} to {end:g} holds {hi - lo} of the "
                           f"animation's samples (time codes {clip.times[0]:g}-{clip.times[-1]:g}); a {verbs[0]} "
                           f"shot needs two or more: set the range to the frames to {verbs[1]}")
    if lo == 0 and hi == len(clip.times):
        return clip, None, None
    last = np.searchsorted(clip.seconds, clip.seconds[hi - 1] + ahead_s + 1e-9)
    return clip.frames(int(lo), int(hi)), (clip.frames(int(hi), int(last)) if last > hi else None), clip


def with_ahead(shot, ahead, take):
    """The shot and the take's frames after it (``cut_to_range``'s ``ahead``) as one clip, for a
    planner whose windows reach past the shot's end; the shot itself where there is none."""
    if ahead is None:
        return shot
    lo = int(np.searchsorted(take.times, shot.times[0] - 1e-9))
    return take.frames(lo, lo + len(shot.times) + len(ahead.times))


def through_take(override, take, shot):
    """``override`` (an ``AnimOverride`` of ``shot``, the take cut to its range: its every frame) over
    the whole take: outside the range the take's own values, bit for bit: an animated joint's samples,
    a joint the animation does not list at the skeleton's rest. A joint the input does not have (eyes
    the pass added) holds its nearest written frame: the input has nothing to give back for it."""
    lo = int(np.searchsorted(take.times, shot.times[0] - 1e-9))
    hi = lo + len(shot.times)
    columns = _sources(override.joints, take)
    padded = {}
    for name, values in (("rotations", override.rotations), ("translations", override.translations),
                         ("scales", override.scales)):
        if values is not None:
            before = _outside(name, take, np.arange(lo), columns, values[0], values.dtype)
            after = _outside(name, take, np.arange(hi, len(take.times)), columns, values[-1], values.dtype)
            padded[name] = np.concatenate([before, values, after])
    return dataclasses.replace(override, times=take.times, **padded)


def _sources(joints: list[str], take) -> tuple[list, list, list]:
    """For each written joint, where its value outside the range comes from: ``(column, animation
    index)`` pairs of the animated ones, ``(column, skeleton index)`` of those at rest, and the
    columns of joints the take does not have."""
    animated = {j: i for i, j in enumerate(take.anim_joints)}
    skeleton = {j: i for i, j in enumerate(take.joints)}
    anim, rest, added = [], [], []
    for c, joint in enumerate(joints):
        if joint in animated:
            anim.append((c, animated[joint]))
        elif joint in skeleton:
            rest.append((c, skeleton[joint]))
        else:
            added.append(c)
    return anim, rest, added


def _outside(name: str, take, frames: np.ndarray, columns, edge: np.ndarray, dtype) -> np.ndarray:
    """The written joints' ``name`` values at the take's ``frames`` outside the range (``edge``: the
    nearest written frame, for the joints the take does not have)."""
    from usdgaze.core import rotations as rot

    anim, rest, added = columns
    out = np.empty((len(frames),) + edge.shape, dtype=dtype)
    if anim:
        cols, idx = map(list, zip(*anim))
        out[:, cols] = getattr(take, name)[frames][:, idx]
    if rest:
        cols, idx = map(list, zip(*rest))
        parts = dict(zip(("translations", "rotations", "scales"), rot.decompose_tr(take.rest_local[idx])))
        out[:, cols] = parts[name].astype(dtype)
    out[:, added] = edge[added]
    return out
