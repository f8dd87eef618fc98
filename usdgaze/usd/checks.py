"""Stage checks before a skeleton is read: metadata, authored types, instancing, rest/bind values.

Each check raises one :class:`UsdGazeError` line naming the file, prim and attribute; the reader
(:mod:`usdgaze.usd.skelio`) calls them so every command that reads a clip refuses the same things.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Pcp, Usd, UsdGeom

from usdgaze.core.zero_scale import singular, time_code_spans
from usdgaze.errors import UsdGazeError

ANIMATION_TYPES = {"joints": "token[]", "rotations": "quatf[]", "translations": "float3[]", "scales": "half3[]"}
SKELETON_TYPES = {"joints": "token[]", "restTransforms": "matrix4d[]", "bindTransforms": "matrix4d[]",
                  "jointNames": "token[]"}


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


_ARCS = {Pcp.ArcTypeReference: "reference", Pcp.ArcTypePayload: "payload"}
_UNIT_TOLERANCE = 1e-3  # relative: a unit or a scale authored as 0.0254 or 1/39.37


def check_arcs(stage: Usd.Stage, skel: Usd.Prim, prims: list[Usd.Prim | None], source: str) -> None:
    """Refuse what :func:`arc_units_problem` or :func:`arc_up_axis_problem` finds, in one line naming
    the file and prim: what USD does not carry across a reference or payload."""
    for find in (arc_units_problem, arc_up_axis_problem):
        problem = find(stage, skel, prims)
        if problem:
            raise UsdGazeError(f"{source}:{problem[0].GetPath()}: {problem[1]}")


def _said(stage: Usd.Stage, key: str) -> str:
    return "authored on it" if stage.HasAuthoredMetadata(key) else "USD's fallback: it authors none"


def arc_units_problem(stage: Usd.Stage, skel: Usd.Prim, prims: list[Usd.Prim | None]) -> tuple[Usd.Prim, str] | None:
    """The first of ``prims`` (the SkelRoot, Skeleton and animation) that a reference or payload brings
    in from a layer authoring another metersPerUnit than the stage's, with what to say; None if every
    one measures in the stage's unit or the reference is scaled to make up for it (the Skeleton
    ``skel``'s world scale at its first time does). USD takes the stage's unit for them, whatever the
    asset says: a metre asset referenced into a stage that authors none (0.01) made a 1.6 cm character
    that showed only as targets out of reach. An asset that authors no unit is taken in the stage's."""
    stage_mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    assets: dict = {}
    for prim, node, arc in _arc_layers(stage, prims):
        layer = node.layerStack.identifier.rootLayer
        value = layer.pseudoRoot.GetInfo("metersPerUnit") if layer.pseudoRoot.HasInfo("metersPerUnit") else None
        if not isinstance(value, (int, float)) or abs(value / stage_mpu - 1.0) <= _UNIT_TOLERANCE:
            continue
        # read only where units differ: most characters are never asked
        scale = float(np.cbrt(abs(np.linalg.det(_asset_to_stage(skel, node, assets)))))
        if abs(value / (stage_mpu * scale) - 1.0) <= _UNIT_TOLERANCE:
            continue
        return prim, (
            f"is defined through a {arc} of {layer.identifier}, which says metersPerUnit {value:g}, but the stage "
            f"measures in {stage_mpu:g} ({_said(stage, 'metersPerUnit')}), so USD reads the character "
            f"{value / stage_mpu:g} times too {'small' if value > stage_mpu else 'large'}; author metersPerUnit = "
            f"{value:g} on {stage.GetRootLayer().identifier} or scale the {arc} by {value / stage_mpu:g}")
    return None


_AXES = {"Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}
_UP_TOLERANCE_DEG = 5.0  # a reference turned by hand to about the stage's up
# The turn about X that takes the asset's up onto the stage's (X is the axis both Y and Z lie across).
_TURN = {("Z", "Y"): -90, ("Y", "Z"): 90}


def arc_up_axis_problem(stage: Usd.Stage, skel: Usd.Prim, prims: list[Usd.Prim | None]) -> tuple[Usd.Prim, str] | None:
    """The first of ``prims`` (the SkelRoot, Skeleton and animation) that a reference or payload brings
    in from a layer authoring another upAxis than the stage's, with what to say; None if every one
    stands in the stage's up or the reference is turned to make up for it (the Skeleton ``skel``'s
    world transform at its first time takes the asset's up to within 5 deg of the stage's). USD does
    not convert axes: a Z-up export referenced into a Y-up stage lies on its back. An asset that
    authors no upAxis is taken in the stage's; one authoring neither Y nor Z is not judged here."""
    stage_up = str(UsdGeom.GetStageUpAxis(stage))
    assets: dict = {}
    for prim, node, arc in _arc_layers(stage, prims):
        layer = node.layerStack.identifier.rootLayer
        value = str(layer.pseudoRoot.GetInfo("upAxis")) if layer.pseudoRoot.HasInfo("upAxis") else stage_up
        if value == stage_up or value not in _AXES or stage_up not in _AXES:
            continue
        # read only where axes differ: most characters are never asked
        turned = _AXES[value] @ _asset_to_stage(skel, node, assets)  # USD's matrices act on row vectors
        norm = float(np.linalg.norm(turned))
        cos = float(turned @ _AXES[stage_up]) / norm if norm > 0 else -1.0
        off = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
        if off <= _UP_TOLERANCE_DEG:
            continue
        return prim, (
            f"is defined through a {arc} of {layer.identifier}, which says upAxis {value}, but the stage's up is "
            f"{stage_up} ({_said(stage, 'upAxis')}), and USD does not turn an asset to the stage's axis: the "
            f"character's up lands {off:.0f} deg off {stage_up}; author upAxis = {value} on "
            f"{stage.GetRootLayer().identifier} or rotate the {arc} to take {value} onto {stage_up} "
            f"({_TURN[value, stage_up]:+d} deg about X)")
    return None


def _first_world(skel: Usd.Prim) -> np.ndarray:
    """The Skeleton's local-to-world matrix (USD's row-vector convention) at its first time."""
    return np.array(UsdGeom.Xformable(skel).ComputeLocalToWorldTransform(Usd.TimeCode.EarliestTime()))


def _asset_to_stage(skel: Usd.Prim, node, assets: dict) -> np.ndarray:
    """The 3x3 (row vectors) taking the world of the file that ``node``'s arc brings in (the asset, whose
    upAxis and metersPerUnit are its world's) to the stage's world: the Skeleton's world in the stage
    with its world in the asset, opened alone, undone. A transform the asset itself carries (Blender's
    export turns Z-up data Y-up on its root prim) is the asset's, not the arc's: counted as the arc's,
    the Y-up CMU clip turned +90 deg about X into a Z-up stage was refused as lying 90 deg off, and one
    whose reference dropped that turn was taken. Where the asset does not place the Skeleton (another
    file brings it in), the Skeleton's world in the stage is taken whole."""
    stage_world = _first_world(skel)[:3, :3]
    path = node.mapToRoot.Evaluate().MapTargetToSource(skel.GetPath())
    ident = node.layerStack.identifier
    if path.isEmpty:
        return stage_world
    if (ident, path) not in assets:  # the Skeleton and its ancestors alone: an asset may be a whole set
        mask = Usd.StagePopulationMask([path])
        assets[ident, path] = Usd.Stage.OpenMasked(ident.rootLayer, ident.pathResolverContext, mask)
    own = assets[ident, path].GetPrimAtPath(path)
    if not own or not own.IsA(UsdGeom.Xformable):
        return stage_world
    asset_world = _first_world(own)[:3, :3]
    if singular(asset_world[None])[0]:
        return stage_world
    return np.linalg.inv(asset_world) @ stage_world


def _arc_layers(stage: Usd.Stage, prims: list[Usd.Prim | None]):
    """``(prim, node, arc)`` for each of ``prims`` and each prim index node by which a reference or payload
    brings specs of it in from another file (``arc``: the outermost arc's kind)."""
    root_layer = stage.GetRootLayer()
    for prim in prims:
        if not prim:
            continue
        for node, arc in _arc_nodes(prim.GetPrimIndex().rootNode, root_layer, None):
            yield prim, node, arc


def _arc_nodes(node, root_layer, arc: str | None):
    """The nodes of a prim index outside the stage's own layer stack, each with the reference or payload
    that brought its layer stack in (nested arcs: the outermost)."""
    for child in node.children:
        inside = child.layerStack.identifier.rootLayer == root_layer
        here = arc or (None if inside else _ARCS.get(child.arcType, "composition arc"))
        if not inside and child.hasSpecs:
            yield child, here
        yield from _arc_nodes(child, root_layer, here)


def value_spec(attr: Usd.Attribute):
    """The strongest spec that authors the attribute's value (a default or time samples), or None: a
    stronger spec that only declares the attribute (an ``over`` with no value) holds neither the value
    nor the type it was authored with, and names the wrong file for a bad value."""
    for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
        if spec.HasDefaultValue() or spec.layer.GetNumTimeSamplesForPath(spec.path):
            return spec
    return None


def authored_type(attr: Usd.Attribute) -> str:
    """The type an attribute's value is authored with, as ``Sdf.ValueTypeNames`` spell it (``float``,
    ``string``, ``double[]``): where a registered schema defines the attribute, USD reports the schema's
    type whatever was authored."""
    spec = value_spec(attr)
    stack = [spec] if spec is not None else attr.GetPropertyStack(Usd.TimeCode.Default())
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


def instanced_problem(prim: Usd.Prim | None) -> str | None:
    """Why an override cannot land on ``prim`` (an instance proxy, or an instanceable prim), or None;
    ``apply`` refuses such a skeleton or animation and ``validate`` reports it, in these words."""
    if prim is None:
        return None
    if prim.IsInstanceProxy():
        outer = prim
        while outer and not outer.IsInstance():
            outer = outer.GetParent()
        name = outer.GetPath() if outer else "an ancestor"
        return (f"is inside the instance {name}, where no override can reach; "
                f"set instanceable = false on {name} to work on it")
    if prim.IsInstance():
        return "is instanceable, so its skeleton cannot be overridden; set instanceable = false on it"
    return None


def check_not_instanced(prim: Usd.Prim, where: str) -> None:
    """An override cannot land inside an instance: refuse instance proxies and instanceable prims."""
    problem = instanced_problem(prim)
    if problem:
        raise UsdGazeError(f"{where}: {problem}")


def check_matrices(mats: np.ndarray | None, joints: list[str], where: str) -> None:
    """Finite, invertible joint transforms (``(J, 4, 4)``, any convention)."""
    if mats is None:
        return
    finite = np.isfinite(mats).all(axis=(1, 2))
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise UsdGazeError(f"{where}: entry {i} (joint '{joints[i]}') holds NaN or infinite values")
    bad = singular(mats[:, :3, :3])
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise UsdGazeError(f"{where}: entry {i} (joint '{joints[i]}') is singular (a zero scale); it has no inverse")


def check_scaled_away(skel: Usd.Prim, times: np.ndarray, skel_to_world: np.ndarray, source: str) -> list[str]:
    """The Skeleton's world transform ``skel_to_world`` (one, or one per frame of ``times``) scaled to
    nothing, as animators hide a character: refused where it holds on every frame (there is no head to
    aim); else one note naming the transform and its time codes, whose frames the passes leave as the
    base motion (see :mod:`usdgaze.passes.hidden`)."""
    gone = singular(skel_to_world[:, :3, :3])
    if not gone.any():
        return []
    first = float(times[int(np.argmax(gone))]) if len(gone) > 1 else float(times[0]) if len(times) else None
    prim, op = _scaled_away_by(skel, Usd.TimeCode(first) if first is not None else Usd.TimeCode.Default())
    where = f"{source}:{prim.GetPath()}.{op}"
    if gone.all():
        when = "at every time" if len(gone) == 1 else f"on every frame (time codes {time_code_spans(times, gone)})"
        raise UsdGazeError(f"{where}: scales the character to nothing (a zero scale) {when}, so it has no head "
                           "to aim; give it a scale other than 0 on the frames to add gaze to")
    return [f"{where}: scales the character to nothing (a zero scale) at time codes {time_code_spans(times, gone)}; "
            "those frames keep the base motion (no gaze offset), and the gaze goes on after them"]


def _scaled_away_by(skel: Usd.Prim, time: Usd.TimeCode) -> tuple[Usd.Prim, str]:
    """The prim, from the Skeleton up, and its xformOp whose transform at ``time`` has no inverse."""
    prim = skel
    while prim and not prim.IsPseudoRoot():
        x = UsdGeom.Xformable(prim)
        for op in (x.GetOrderedXformOps() if x else []):
            if singular(np.array(op.GetOpTransform(time), dtype=float)[None, :3, :3])[0]:
                return prim, op.GetName()
        prim = prim.GetParent()
    return skel, "xformOpOrder"  # no one op is singular, only their product: the order says which make it


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
