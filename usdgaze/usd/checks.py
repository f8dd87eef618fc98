"""Stage checks before a skeleton is read: metadata, authored types, instancing, rest/bind values.

Each check raises one :class:`UsdGazeError` line naming the file, prim and attribute; the reader
(:mod:`usdgaze.usd.skelio`) calls them so every command that reads a clip refuses the same things.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Usd

from usdgaze.errors import UsdGazeError

ANIMATION_TYPES = {"joints": "token[]", "rotations": "quatf[]", "translations": "float3[]", "scales": "half3[]"}
SKELETON_TYPES = {"joints": "token[]", "restTransforms": "matrix4d[]", "bindTransforms": "matrix4d[]",
                  "jointNames": "token[]"}
_SINGULAR = 1e-12  # |det| of a joint's 3x3 below this: a zero scale, no inverse


def check_stage(stage: Usd.Stage, source: str) -> None:
    """upAxis Y or Z; metersPerUnit, timeCodesPerSecond and framesPerSecond finite and positive."""
    up = stage.GetMetadata("upAxis") if stage.HasAuthoredMetadata("upAxis") else "Y"
    if str(up) not in ("Y", "Z"):
        raise UsdGazeError(f"{source}: upAxis is '{up}', expected Y or Z (UsdGeom knows no other up axis)")
    _check_root_metadata(stage, source)
    for key, what in (("metersPerUnit", "a length"), ("timeCodesPerSecond", "a rate"), ("framesPerSecond", "a rate")):
        if not stage.HasAuthoredMetadata(key):
            continue
        value = stage.GetMetadata(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise UsdGazeError(f"{source}: {key} is {value!r}, expected {what} > 0")
    if stage.HasAuthoredTimeCodeRange() and stage.GetStartTimeCode() > stage.GetEndTimeCode():
        raise UsdGazeError(f"{source}: startTimeCode {stage.GetStartTimeCode():g} is after endTimeCode "
                           f"{stage.GetEndTimeCode():g}")


def _check_root_metadata(stage: Usd.Stage, source: str) -> None:
    """Stage metadata comes from the root layer alone: a sublayer's own up axis or unit is ignored, so
    a root that authors none over a sublayer that says otherwise is read in USD's fallback."""
    for key, fallback in (("upAxis", "Y"), ("metersPerUnit", 0.01)):
        if stage.HasAuthoredMetadata(key):
            continue
        for layer in stage.GetLayerStack(includeSessionLayers=False)[1:]:
            if layer.pseudoRoot.HasInfo(key) and layer.pseudoRoot.GetInfo(key) != fallback:
                raise UsdGazeError(
                    f"{source}: authors no {key}, so USD takes {fallback}, but its sublayer {layer.identifier} says "
                    f"{layer.pseudoRoot.GetInfo(key)}; author {key} on {source} itself")


def authored_type(attr: Usd.Attribute) -> str:
    """The type an attribute's strongest opinion is authored with (``float``, ``string``, ...): where a
    registered schema defines the attribute, USD reports the schema's type whatever was authored."""
    stack = attr.GetPropertyStack(Usd.TimeCode.Default())
    return str(stack[0].typeName) if stack else str(attr.GetTypeName())


def check_types(prim: Usd.Prim, expected: dict[str, str], where: str) -> None:
    """Each attribute authored with the type UsdSkel reads (the schema reports its own type, so look at specs)."""
    for name, type_name in expected.items():
        attr = prim.GetAttribute(name)
        if not attr:
            continue
        for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
            authored = str(spec.typeName)
            if authored and authored != type_name:
                raise UsdGazeError(f"{where}.{name}: authored as {authored}, expected {type_name} (UsdSkel reads only that type)")
            break


def check_not_instanced(prim: Usd.Prim, where: str) -> None:
    """An override cannot land inside an instance: refuse instance proxies and instanceable prims."""
    if prim.IsInstanceProxy():
        outer = prim
        while outer and not outer.IsInstance():
            outer = outer.GetParent()
        name = outer.GetPath() if outer else "an ancestor"
        raise UsdGazeError(f"{where}: is inside the instance {name}, where no override can reach; "
                           f"set instanceable = false on {name} to work on it")
    if prim.IsInstance():
        raise UsdGazeError(f"{where}: is instanceable, so its skeleton cannot be overridden; set instanceable = false on it")


def check_matrices(mats: np.ndarray | None, joints: list[str], where: str) -> None:
    """Finite, invertible joint transforms (``(J, 4, 4)``, any convention)."""
    if mats is None:
        return
    finite = np.isfinite(mats).all(axis=(1, 2))
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise UsdGazeError(f"{where}: entry {i} (joint '{joints[i]}') holds NaN or infinite values")
    det = np.linalg.det(mats[:, :3, :3])
    bad = np.abs(det) < _SINGULAR
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise UsdGazeError(f"{where}: entry {i} (joint '{joints[i]}') is singular (a zero scale); it has no inverse")


def check_scales(scales: np.ndarray, where: str) -> None:
    if scales.dtype == np.float16:  # inf and NaN are the all-ones exponent; numpy's float16 isfinite is 13x slower
        finite = not ((scales.view(np.uint16) & 0x7C00) == 0x7C00).any()
    else:
        finite = bool(np.isfinite(scales).all())
    if not finite:
        raise UsdGazeError(f"{where}: holds NaN or infinite values")


def check_rest_covers(rest_authored: bool, joints: list[str], anim_to_skel: np.ndarray, where_skel: str,
                      animation: str) -> None:
    """A sparse animation needs restTransforms: UsdSkel takes the joints an animation leaves out from
    them, and without them poses nothing at all (neither the input nor a layer over it would move)."""
    if rest_authored:
        return
    covered = np.zeros(len(joints), dtype=bool)
    covered[anim_to_skel[anim_to_skel >= 0]] = True
    if covered.all():
        return
    left_out = [joints[i] for i in np.flatnonzero(~covered)]
    raise UsdGazeError(
        f"{where_skel}.restTransforms: not authored, and {animation} leaves {len(left_out)} of the skeleton's "
        f"{len(joints)} joints out ('{left_out[0]}'{', ...' if len(left_out) > 1 else ''}); UsdSkel takes those "
        "from restTransforms, so it cannot pose this skeleton: author restTransforms or animate every joint")
