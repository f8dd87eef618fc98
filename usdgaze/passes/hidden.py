"""Frames where the character, or a joint of its gaze chain, is scaled to nothing: animators hide a
character so (a SkelRoot's ``xformOp:scale`` keyed to 0 for a few frames, a joint's ``scales`` to
(0, 0, 0)). Such a frame has no head to aim from, and every matrix the passes invert there has no
inverse. The passes run on the clip with those frames holding the nearest frame the character is seen
on (so the plan and the eyes go on through them), and write them back as the input's samples: the base
motion, no gaze offset, the gaze going on after (pure numpy)."""

from __future__ import annotations

import dataclasses

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.kinematics import with_ancestors
from usdgaze.core.rig import Chain
from usdgaze.core.zero_scale import singular, singular_scales, time_code_spans
from usdgaze.errors import UsdGazeError


@dataclasses.dataclass
class Hidden:
    """The frames held (indices) and the input's samples on them, and what to say of them."""

    rows: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    warnings: list[str]


def _seen_from(gone: np.ndarray) -> np.ndarray:
    """Per frame, the frame whose pose it holds: itself where seen, else the last seen one before it
    (the first after it, before any); ``gone`` has a frame that is seen."""
    seen = np.flatnonzero(~gone)
    k = np.searchsorted(seen, np.arange(len(gone)), side="right") - 1
    return np.where(gone, seen[np.maximum(k, 0)], np.arange(len(gone)))


def held_world(skel_to_world: np.ndarray) -> np.ndarray:
    """Skeleton-to-world matrices with each one that has no inverse replaced by the nearest frame's
    that has (as :func:`hold_visible` holds them); the same array where none is singular."""
    gone = singular(skel_to_world[:, :3, :3])
    if not gone.any() or gone.all():
        return skel_to_world
    return skel_to_world[_seen_from(gone)]


def _chain_columns(clip: SkelClip, chain: Chain) -> list[int]:
    """The animation columns of the joints whose world transforms the passes invert: the chain, its
    ancestors and the eyes' parents (an eye scaled to 0 is only drawn so, and is aimed as it is)."""
    eye_parents = [int(clip.parents[e]) for e in chain.eyes] if chain.eyes else []
    above = set(with_ancestors(list(chain.path) + eye_parents, clip.parents))
    return [a for a, j in enumerate(clip.anim_to_skel) if int(j) in above]


def hidden_frames(clip: SkelClip, chain: Chain) -> tuple[np.ndarray, list[str]]:
    """Per frame, whether the character (its skeleton's world transform; the reader said which prim
    scales it) or a joint the passes invert is scaled to nothing; one line per such joint. Refused
    where that holds on every frame: there is nothing to aim."""
    frames = len(clip.times)
    gone = np.broadcast_to(singular(clip.skel_to_world[:, :3, :3]), (frames,)).copy()
    warnings = []
    for a in _chain_columns(clip, chain):
        zero = singular_scales(clip.scales[:, a])
        if not zero.any():
            continue
        name = clip.anim_joints[a].rsplit("/", 1)[-1]
        if zero.all() or (gone | zero).all():
            raise UsdGazeError(f"{clip.where('scales')}: joint '{name}' of the gaze chain is scaled to nothing (a "
                               f"zero scale) on every frame{'' if zero.all() else ' the SkelRoot leaves seen'}, so there "
                               "is no head to aim; give it a scale other than 0 on the frames to add gaze to")
        warnings.append(f"{clip.where('scales')}: joint '{name}' of the gaze chain is scaled to nothing (a zero "
                        f"scale) at time codes {time_code_spans(clip.times, zero)}; those frames keep the base motion "
                        "(no gaze offset), and the gaze goes on after them")
        gone |= zero
    return gone, warnings


def hold_visible(clip: SkelClip, chain: Chain) -> tuple[SkelClip, Hidden | None]:
    """The clip with its hidden frames (:func:`hidden_frames`) holding the nearest seen frame's samples
    and transform, and those frames' own samples to :func:`restore`; the clip itself where none is."""
    gone, warnings = hidden_frames(clip, chain)
    if not gone.any():
        return clip, None
    rows, src = np.flatnonzero(gone), _seen_from(gone)[gone]
    hidden = Hidden(rows, clip.rotations[rows].copy(), clip.translations[rows].copy(), clip.scales[rows].copy(),
                    warnings)
    held = {}
    for name in ("rotations", "translations", "scales"):
        values = getattr(clip, name) if clip.owns_arrays else getattr(clip, name).copy()
        values[rows] = values[src]
        held[name] = values
    moving = len(clip.skel_to_world) > 1
    return dataclasses.replace(clip, **held, owns_arrays=True,
                               skel_to_world=held_world(clip.skel_to_world) if moving else clip.skel_to_world), hidden


def restore(result, hidden: Hidden | None, clip: SkelClip):
    """``result``'s animation arrays with the hidden frames (those of its frames that are) written as the
    input's samples; a joint the pass appended (an added eye, an unanimated chain joint) at its rest
    rotation and translation. Its ``warnings`` gain the hidden joints' lines."""
    if hidden is None:
        return result
    keep = hidden.rows < len(result.rotations)  # a pass over a shot cut from a longer take holds only the shot
    rows, n = hidden.rows[keep], hidden.rotations.shape[1]
    result.rotations[rows, :n] = hidden.rotations[keep]
    result.translations[rows, :n] = hidden.translations[keep]
    result.scales[rows, :n] = hidden.scales[keep]
    index = {j: i for i, j in enumerate(clip.joints)}
    for a, joint in enumerate(result.anim_joints[n:], start=n):
        if joint in index:  # an unanimated joint: UsdSkel would show its rest transform
            t, q, _ = rot.decompose_tr(clip.rest_local[index[joint]])
            result.rotations[rows, a], result.translations[rows, a] = q, t
        else:  # an added eye: no turn in its head
            result.rotations[rows, a] = rot.IDENTITY
    result.warnings.extend(hidden.warnings)
    return result
