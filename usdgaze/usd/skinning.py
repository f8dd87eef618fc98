"""The meshes UsdSkel skins with a Skeleton, and what their joint influences get wrong: an index past
the joints it indexes, or ``jointIndices`` and ``jointWeights`` of different lengths. UsdSkel cannot
skin such a mesh; ``validate`` reports each, the reader notes each (apply and attend warn), and a pass
that adds eye joints refuses where an index past the skeleton's joints would land on an added eye."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdSkel


@dataclass(frozen=True)
class Influences:
    """One skinned mesh's problem, for messages."""

    prim: Usd.Prim
    attribute: str
    """The primvar at fault: ``primvars:skel:jointIndices``."""
    problem: str
    beyond: int | None
    """The smallest index past the Skeleton's own joints (a mesh that names its own ``skel:joints``
    indexes those instead, and joints added to the Skeleton never reach it): None where none is."""


def _targets(skel: Usd.Prim) -> list:
    """The skinning queries of the meshes UsdSkel binds to ``skel`` (under its SkelRoot)."""
    root = UsdSkel.Root.Find(skel)
    if not root:
        return []
    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.TraverseInstanceProxies())
    for binding in cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies()):
        if binding.GetSkeleton().GetPrim() == skel:
            return list(binding.GetSkinningTargets())
    return []


def _problem(query, joints: int) -> Influences | None:
    indices_pv, weights_pv = query.GetJointIndicesPrimvar(), query.GetJointWeightsPrimvar()
    attr = indices_pv.GetAttr()
    indices = np.asarray(indices_pv.Get() if indices_pv else [], dtype=np.int64)
    weights = weights_pv.Get() if weights_pv else None
    order = query.GetJointOrder()  # the mesh's own skel:joints, where it names them
    count = len(order) if order is not None else joints
    of = f"the mesh's {count} skel:joints" if order is not None else f"the skeleton's {count} joints"
    if weights is not None and len(weights) != len(indices):
        return Influences(query.GetPrim(), attr.GetName(), f"{len(indices)} entries, but {weights_pv.GetAttr().GetName()} "
                          f"has {len(weights)}; UsdSkel cannot skin the mesh", None)
    bad = indices[(indices < 0) | (indices >= count)]
    if not len(bad):
        return None
    past = bad[bad >= count]
    beyond = int(past.min()) if len(past) and order is None else None
    return Influences(query.GetPrim(), attr.GetName(), f"index {int(bad[0])} is out of range for {of} (0 to "
                      f"{count - 1}); UsdSkel cannot skin the mesh", beyond)


def influence_problems(skel: Usd.Prim) -> list[Influences]:
    """One :class:`Influences` per mesh skinned by ``skel`` whose joint influences UsdSkel cannot use."""
    joints = len(UsdSkel.Skeleton(skel).GetJointsAttr().Get() or [])
    found = (_problem(q, joints) for q in _targets(skel))
    return [p for p in found if p is not None]
