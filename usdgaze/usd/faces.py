"""Where another character's face is: a look-at target or an object that is a character looks at its eyes.

A prim that is a SkelRoot, or holds exactly one Skeleton (a character's top Xform), is looked at in its
eyes' midpoint (the eye joints bound as ``apply`` binds them: names, the SkelRoot's GazeMapAPI), or at its
head joint where it has no eyes, by forward kinematics of its own animation at every time code. Its
bounds' centre, which it was looked at before, is mid-body: two characters 3 m apart looked 14 deg
below each other's head. A character whose head cannot be bound keeps that centre, said in one line.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdSkel

from usdgaze.errors import UsdGazeError

HEAD_RADIUS_M = 0.12
"""The size a character object is seen at without an authored radius: its head, not its body."""


def character_of(prim: Usd.Prim) -> tuple[Usd.Prim, Usd.Prim] | None:
    """(SkelRoot, Skeleton) of the character ``prim`` is: a SkelRoot (its first Skeleton, the one
    ``attend`` plans), or a prim holding exactly one Skeleton under a SkelRoot; else None."""
    from usdgaze.usd.skelio import skeletons_under

    if prim.IsA(UsdSkel.Root):
        skels = skeletons_under(prim)
        return (prim, skels[0]) if skels else None
    if prim.IsA(UsdSkel.Skeleton):
        return None  # looked at in its own bounds (its posed joints), as before
    roots = [p for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Root)]
    held = [(r, skel) for r in roots for skel in skeletons_under(r)]  # each Skeleton under its nearest SkelRoot
    return held[0] if len(held) == 1 else None


def eye_positions(prim: Usd.Prim, time_codes: np.ndarray, source: str,
                  notes: list[str] | None = None) -> np.ndarray | None:
    """World positions ``(K, 3)``, stage units, of the eyes' midpoint of the character ``prim`` is (its
    head where it has no eyes) at ``time_codes``; None where ``prim`` is no character, or where it
    cannot be bound (then one line in ``notes``: it is looked at in its bounds' centre)."""
    found = character_of(prim)
    if found is None:
        return None
    root, skel = found
    try:
        return _eyes_at(root, skel, np.asarray(time_codes, float), source)
    except UsdGazeError as exc:
        if notes is not None:
            notes.append(f"{source}:{prim.GetPath()}: a character whose eyes cannot be found ({exc}); it is looked "
                         "at in the centre of its bounds, mid-body, not its face")
        return None


def _eyes_at(root: Usd.Prim, skel: Usd.Prim, codes: np.ndarray, source: str) -> np.ndarray:
    from usdgaze.characters import chain_of, own_map
    from usdgaze.core.kinematics import forward, with_ancestors
    from usdgaze.usd.skelio import read_clip, skeleton_to_world

    clip = read_clip(root.GetStage(), skel, root, source)
    chain = chain_of(clip.joints, clip.parents, clip.joint_names, own_map(root, source), None,
                     f"{source}:{skel.GetPath()}")
    ends = list(chain.eyes or (chain.head,))
    pose = forward(with_ancestors(ends, clip.parents), clip.parents, clip.local_trs)
    in_skel = np.mean([pose.position[j] for j in ends], axis=0)  # (F, 3) skeleton space
    # Between its samples UsdSkel interpolates the joints, and holds the ends outside them.
    at = np.stack([np.interp(codes, clip.times, in_skel[:, i]) for i in range(3)], -1)
    to_world = skeleton_to_world(skel, codes)  # column vectors; one matrix where it does not move
    return np.einsum("...ij,...j->...i", to_world[:, :3, :3], at) + to_world[:, :3, 3]
