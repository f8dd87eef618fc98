"""Look-at targets from a stage: a prim's world position per time code.

A character (a SkelRoot, or a prim holding one Skeleton) is looked at in its eyes (``usdgaze.usd.faces``);
a Boundable prim (geometry, a Skeleton, ...) in the centre of its world bounding box; any other Xformable at its pivot (``xformOp:translate:pivot`` when authored, else its origin).
A target whose transform and extent cannot change over time is computed once; an animated one at
each of the clip's time codes (USD's own interpolation between authored samples).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from usdgaze.errors import UsdGazeError
from usdgaze.usd.faces import eye_positions
from usdgaze.usd.xformops import check_transform

PURPOSES = [UsdGeom.Tokens.default_, UsdGeom.Tokens.render, UsdGeom.Tokens.proxy]


def check_target(stage: Usd.Stage, path: str, source: str) -> Usd.Prim:
    """The prim at ``path``, which must exist and be Xformable or Boundable."""
    if not Sdf.Path.IsValidPathString(path) or not Sdf.Path(path).IsAbsolutePath() or not Sdf.Path(path).IsPrimPath():
        raise UsdGazeError(f"{source}: look-at target '{path}' is neither an absolute prim path nor a point X,Y,Z")
    prim = stage.GetPrimAtPath(path)
    if not prim or not prim.IsValid():
        above = Sdf.Path(path).GetParentPath()
        while not above.IsAbsoluteRootPath() and not stage.GetPrimAtPath(above):
            above = above.GetParentPath()
        holder = stage.GetPrimAtPath(above)
        if holder and not holder.IsPseudoRoot() and not holder.IsActive():  # its children are not composed
            raise UsdGazeError(f"{source}:{path}: is under the inactive prim {above} (active = false), so it is not "
                               "in the scene (look-at target)")
        raise UsdGazeError(f"{source}:{path}: no such prim (look-at target)")
    if not prim.IsActive():
        raise UsdGazeError(f"{source}:{path}: is inactive (active = false), so it is not in the scene (look-at target)")
    if not (prim.IsA(UsdGeom.Xformable) or prim.IsA(UsdGeom.Boundable)):
        raise UsdGazeError(f"{source}:{path}: is a {prim.GetTypeName() or 'typeless prim'}; "
                           "a look-at target must be Xformable or Boundable")
    instancer = prototype_instancer(prim)
    if instancer is not None:
        raise UsdGazeError(f"{source}:{path}: is a prototype of the PointInstancer {instancer.GetPath()}, drawn only "
                           "where its instances are; look at the PointInstancer or at a point X,Y,Z")
    problem = drawn_problem(prim)
    if problem:
        raise UsdGazeError(f"{source}:{path}: {problem}; look at one of those or at a point X,Y,Z")
    # As an attend object's: an op USD cannot evaluate stopped apply with an internal error (exit 1), and
    # one it skips (an op the order names but the prim lacks, an order that is no token[]) was looked at
    # where USD's identity put it, the world's origin (exit 0).
    check_transform(prim, source)
    return prim


def drawn_problem(prim: Usd.Prim) -> str | None:
    """Why USD draws ``prim`` nowhere at its own place, or None: a prim of an instancing prototype
    (``/__Prototype_1/Ball``) or an abstract class prim was looked at where nothing is."""
    if prim.IsInPrototype() or prim.IsPrototype():
        proto = prim
        while not proto.IsPrototype():
            proto = proto.GetParent()
        instances = proto.GetInstances()
        such = f", such as {prim.GetPath().ReplacePrefix(proto.GetPath(), instances[0].GetPath())}" if instances else ""
        return f"lies in the instancing prototype {proto.GetPath()}, drawn only as the prims of its instances{such}"
    if prim.IsAbstract():
        return "is an abstract class prim (or lies under one), which USD does not draw, only the prims inheriting it"
    return None


def prototype_instancer(prim: Usd.Prim) -> Usd.Prim | None:
    """The PointInstancer above ``prim`` whose prototype holds it: such a prototype is not drawn at its
    own place (a target there was looked at where no instance is)."""
    parent = prim.GetParent()
    while parent and not parent.IsPseudoRoot():
        if parent.IsA(UsdGeom.PointInstancer):
            targets = UsdGeom.PointInstancer(parent).GetPrototypesRel().GetForwardedTargets()
            if any(prim.GetPath().HasPrefix(t) for t in targets):
                return parent
        parent = parent.GetParent()
    return None


def instances_note(prim: Usd.Prim, source: str) -> str | None:
    """A line for a PointInstancer drawing more than one instance (at some authored time), or None: as one
    object or target it is the centre of their bounds, where none of them may be (two balls 2.4 m apart
    were looked at between them, 32 deg off each). A swarm's centre may be what is meant: said, not refused."""
    if not prim.IsA(UsdGeom.PointInstancer):
        return None
    attr = UsdGeom.PointInstancer(prim).GetProtoIndicesAttr()
    times = attr.GetTimeSamples() or [Usd.TimeCode.Default()]
    counts = [(len(attr.Get(t) or []), t) for t in times]
    most, at = max(counts, key=lambda c: c[0])
    if most < 2:
        return None
    when = "" if isinstance(at, Usd.TimeCode) else f" at time code {at:g}"
    return (f"{source}:{prim.GetPath()}: a PointInstancer drawing {most} instances{when} is one object, looked at "
            "in the centre of their bounds, where none of them may be; to look at each, give each a prim of its own")


def _varying(prim: Usd.Prim, boundable: bool) -> bool:
    """Whether the prim's world position can change over time (its transform, or for geometry what
    its bounds come from)."""
    p = prim
    while p and not p.IsPseudoRoot():
        x = UsdGeom.Xformable(p)
        if x and x.TransformMightBeTimeVarying():
            return True
        p = p.GetParent()
    if boundable:
        return bounds_vary(prim)
    pivot = _pivot(prim)
    return pivot is not None and pivot.ValueMightBeTimeVarying()


def bounds_vary(prim: Usd.Prim) -> bool:
    """Whether the prim's bounds in its own space can change over time: an attribute of it or of a
    prim below it is animated (baked points, an extent, a child's transform), its own transform ops and
    usdgaze's own attributes (an animated importance) aside."""
    for q in Usd.PrimRange(prim):
        # A Skeleton's bounds are its posed joints: they move with the animation it binds, which
        # need not lie below it (another character's Skeleton was looked at where it was at the start).
        anim = UsdSkel.BindingAPI(q).GetInheritedAnimationSource() if q.IsA(UsdSkel.Skeleton) else None
        for attr in q.GetAttributes() + (anim.GetAttributes() if anim else []):
            name = attr.GetName()
            if name.startswith(("gaze:", "usdgaze:")) or (q == prim and name.startswith("xformOp")):
                continue
            if attr.GetNumTimeSamples() > 1 or attr.ValueMightBeTimeVarying():
                return True
    return False


PIVOTS = ("xformOp:translate:pivot", "xformOp:translate:rotatePivot")
"""The pivot ops a target's point is taken from, the first the prim uses: USD's common pivot, then
Maya's rotate pivot (as mayaUSD exports a transform whose pivot was moved)."""


def _pivot(prim: Usd.Prim) -> Usd.Attribute | None:
    """The first of :data:`PIVOTS` that the prim's xformOpOrder uses and that has a value: an attribute
    of that name left out of the order does not move the prim, and its point was looked at."""
    order = [str(o) for o in (UsdGeom.Xformable(prim).GetXformOpOrderAttr().Get() or [])]
    for name in PIVOTS:
        attr = prim.GetAttribute(name)
        if attr and attr.HasValue() and name in order:
            return attr
    return None


def sample_target(stage: Usd.Stage, path: str, times: np.ndarray, source: str,
                  notes: list[str] | None = None, faces: bool = True) -> np.ndarray:
    """World position ``(F, 3)`` of the target prim at ``path`` at each time code; with ``faces`` a
    character's eyes, ``notes`` getting the line for one whose eyes cannot be found (looked at in its
    bounds' centre)."""
    prim = check_target(stage, path, source)
    eyes = eye_positions(prim, np.asarray(times, dtype=float), source, notes) if faces else None
    if eyes is not None:
        if not np.all(np.isfinite(eyes)):
            raise UsdGazeError(f"{source}:{path}: world position of its eyes is not finite")
        return eyes
    note = instances_note(prim, source)
    if note and notes is not None and note not in notes:
        notes.append(note)
    boundable = prim.IsA(UsdGeom.Boundable)
    sample_times = np.asarray(times, dtype=float) if _varying(prim, boundable) else np.asarray(times[:1], dtype=float)
    out = np.empty((len(sample_times), 3))
    if boundable:
        for i, t in enumerate(sample_times):
            # A cache per time: BBoxCache.SetTime keeps the bounds it computed for prims with no authored
            # extent (a Mesh with animated points, a SkelRoot or Skeleton, whose extent is computed), so
            # one cache moved through the frames gave the first frame's bounds on every frame.
            cache = UsdGeom.BBoxCache(Usd.TimeCode(float(t)), PURPOSES, useExtentsHint=True)
            box = cache.ComputeWorldBound(prim)
            if box.GetRange().IsEmpty():
                raise UsdGazeError(f"{source}:{path}: has no extent at time code {t:g}; "
                                   "author an extent (or look at a point X,Y,Z)")
            out[i] = np.array(box.ComputeCentroid(), dtype=float)
    else:
        pivot_attr = _pivot(prim)
        cache = UsdGeom.XformCache(Usd.TimeCode(float(sample_times[0])))
        for i, t in enumerate(sample_times):
            cache.SetTime(Usd.TimeCode(float(t)))
            m = np.array(cache.GetLocalToWorldTransform(prim), dtype=float)  # row vectors
            value = pivot_attr.Get(Usd.TimeCode(float(t))) if pivot_attr is not None else None
            # No value (a blocked sample): USD leaves the pivot ops out there, so the point is the origin.
            pivot = np.zeros(3) if value is None else np.array(value, dtype=float)
            out[i] = np.append(pivot, 1.0) @ m[:, :3]
    if not np.all(np.isfinite(out)):
        raise UsdGazeError(f"{source}:{path}: world position is not finite")
    return np.broadcast_to(out, (len(times), 3)).copy() if len(sample_times) == 1 else out
