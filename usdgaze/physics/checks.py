"""Skeletons the rigid body model cannot follow, refused in one line each (pure numpy): a skeleton scaled
unevenly or by a changing factor in the stage, a joint turning below a mirrored or unevenly scaled one."""

from __future__ import annotations

import numpy as np

from usdgaze.errors import UsdGazeError

# How unevenly the skeleton's transform in the stage may scale it: 0.5% of a 2 m body is 1 cm.
_SCALE_SPREAD = 1.005


def _spread(lin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each 3x3 map's scales along its axes ``(N, 3)`` and how uneven they are (largest over smallest)."""
    scales = np.linalg.svd(lin, compute_uv=False)
    return scales, scales.max(axis=1) / np.maximum(scales.min(axis=1), 1e-300)


def rigid_placement(skel_to_world, where: str) -> None:
    """The skeleton's transform in the stage must scale it evenly and by one factor throughout: the model
    is built once, of rigid bodies, so a squash (a SkelRoot scaled (1, 1.2, 1)) or a scale animated over
    the clip put the model's joints 10-15 cm from UsdSkel's as the joints turned."""
    scales, uneven = _spread(np.asarray(skel_to_world, dtype=float).reshape(-1, 4, 4)[:, :3, :3])
    f = int(np.argmax(uneven))
    if uneven[f] > _SCALE_SPREAD:
        raise UsdGazeError(f"{where}: its transform in the stage (the SkelRoot's or a prim's above the Skeleton) "
                           f"scales it unevenly ({scales[f].min():.4g} to {scales[f].max():.4g} along its axes"
                           f"{f' at its sample {f}' if len(scales) > 1 else ''}); the physics body is rigid: "
                           "scale it by one factor, or bake the squash into the joints")
    if scales.max() / max(scales.min(), 1e-300) > _SCALE_SPREAD:
        raise UsdGazeError(f"{where}: its transform in the stage scales it by {scales[:, 0].min():.4g} to "
                           f"{scales[:, 0].max():.4g} over the clip; the physics body is built once at one size: "
                           "keep the scale of the SkelRoot and the prims above the Skeleton constant")


def unmirrored(joints, idx, bparent, kind, lin: np.ndarray, where: str) -> None:
    """A body below a mirrored joint (a negative scale in the rest pose) may only be welded: a mirrored
    leaf or welded chain (an eye, a hand's fingers) rides as the input has it, but the joints a
    mirrored frame carries turn the other way round in the skeleton than in the model, which the
    written animation would get wrong; the base's own frame must be unmirrored."""
    mirrored = np.linalg.det(lin) < 0.0
    bad = [b for b in range(len(idx)) if (b == 0 and mirrored[0]) or (b and kind[b] != "weld" and mirrored[bparent[b]])]
    if bad:
        b = bad[0]
        what = (f"the simulated root joint '{joints[idx[b]]}' is mirrored" if b == 0 else
                f"joint '{joints[idx[b]]}' moves below mirrored joint '{joints[idx[bparent[b]]]}'")
        raise UsdGazeError(f"{where}: {what} at rest (a negative scale); the body cannot simulate a mirrored "
                           f"limb: unmirror it in the rig (mirror the SkelRoot's transform to mirror the whole character)")


def evenly_scaled(joints, idx, bparent, kind, lin: np.ndarray, where: str) -> None:
    """A body below a joint scaled unevenly at rest may only be welded: its rotation turns what hangs
    from it inside a squashed frame, which no rigid body follows (a thigh scaled (1, 1.3, 1) put the
    model's knee and foot 9.7 cm from UsdSkel's as the leg swung). Its own scale is fine: the bones it
    scales turn with it."""
    scales, spread = _spread(lin)
    uneven = spread > _SCALE_SPREAD
    bad = [b for b in range(1, len(idx)) if kind[b] != "weld" and uneven[bparent[b]]]
    if bad:
        b, p = bad[0], bparent[bad[0]]
        raise UsdGazeError(f"{where}: joint '{joints[idx[b]]}' turns below joint '{joints[idx[p]]}', scaled unevenly at "
                           f"rest ({scales[p].min():.4g} to {scales[p].max():.4g} along its axes); the body's limbs are "
                           "rigid: scale joints by one factor each in the rig")
