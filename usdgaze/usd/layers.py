"""Layer writing: the override layer, the preview root, sublayer insertion.

Everything is authored at the Sdf level inside one ``Sdf.ChangeBlock`` and written through the one
writer, :class:`usdgaze.files.transaction.Outputs` (staged beside the destination, renamed into place
with the command's other outputs, nothing left behind on failure).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from itertools import repeat
from pathlib import Path

import numpy as np
from pxr import Sdf, Vt

from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.files.transaction import Outputs, outputs_of

_FORMATS = {".usda", ".usdc", ".usd"}


def check_output_path(path: str | os.PathLike) -> Path:
    """The output path, or a one-line error if its extension or folder is unusable."""
    p = Path(path)
    if p.suffix.lower() not in _FORMATS:
        raise UsdGazeError(f"{p}: output must end in .usda, .usdc or .usd")
    if not p.parent.exists():
        raise UsdGazeError(f"{p}: folder {p.parent} does not exist")
    return p


def atomic_export(layer: Sdf.Layer, path: str | os.PathLike, outputs: Outputs | None = None,
                  flag: str = "--out") -> None:
    """Write ``layer`` to ``path`` as part of ``outputs`` (or on its own, when none is given)."""
    path = check_output_path(path)
    with outputs_of(outputs) as tx:
        if not tx.claimed(path):
            tx.claim(path, flag)
        tx.stage_layer(path, layer)


def atomic_write(path: str | os.PathLike, write, outputs: Outputs | None = None, flag: str = "--out") -> None:
    """Call ``write(tmp)`` to stage ``path`` (any format) through ``outputs`` (or on its own)."""
    with outputs_of(outputs) as tx:
        if not tx.claimed(path):
            tx.claim(path, flag)
        tx.stage_with(path, write)


@dataclass
class AnimOverride:
    """New full arrays for one SkelAnimation (and, when joints were added, its Skeleton)."""

    animation: str
    times: np.ndarray
    joints: list[str]
    rotations: np.ndarray | None = None
    translations: np.ndarray | None = None
    scales: np.ndarray | None = None
    write_joints: bool = False
    skeleton: str | None = None
    skeleton_joints: list[str] | None = None
    rest_transforms: np.ndarray | None = None
    bind_transforms: np.ndarray | None = None
    joint_names: list[str] | None = None
    define: bool = False
    """The animation is new (the skeleton had none bound): defined, every array written, and bound
    to ``skeleton`` by ``skel:animationSource``."""

    @classmethod
    def of(cls, clip, result, move_roots: bool = False) -> "AnimOverride":
        """The arrays a pass result overrides for ``clip``'s animation (and its skeleton, if eyes
        were added). Translations are written where the joint set grew or ``move_roots`` (the
        pass moved the leg roots); otherwise the input's stay."""
        new = not clip.animation_bound
        grew = len(result.anim_joints) > len(clip.anim_joints) or new
        override = cls(
            animation=clip.animation,
            times=clip.times,
            joints=result.anim_joints,
            rotations=result.rotations,
            translations=result.translations if (move_roots or result.added_joints or grew) else None,
            scales=result.scales if grew else None,
            write_joints=grew,
            skeleton=clip.skeleton if new else None,
            define=new,
        )
        if result.added_joints:
            override.skeleton = clip.skeleton
            override.skeleton_joints = clip.joints + result.added_joints
            rest, bind = clip.authored_poses  # no opinion the input did not have (a bind pose sets up skinning)
            if rest:
                override.rest_transforms = np.concatenate([clip.rest_local, result.added_rest_local])
            if bind:
                override.bind_transforms = np.concatenate([clip.bind_world, result.added_bind_world])
            if clip.joint_names is not None:
                override.joint_names = clip.joint_names + [j.rsplit("/", 1)[-1] for j in result.added_joints]
        return override


@dataclass
class LayerInfo:
    """Timing metadata copied from the input so samples are neither rescaled nor shifted."""

    time_codes_per_second: float
    frames_per_second: float
    start_time: float
    end_time: float
    up_axis: str | None = None
    meters_per_unit: float | None = None
    custom: dict = field(default_factory=dict)
    default_prim: str | None = None
    """The input's defaultPrim: the override names it too where it holds opinions under it, so the
    layer on its own passes the checks that want one (usdchecker's MissingDefaultPrim)."""


def _attr(prim: Sdf.PrimSpec, name: str, type_name, uniform: bool = False) -> Sdf.AttributeSpec:
    spec = prim.attributes[name] if name in prim.attributes else None
    if spec is None:
        variability = Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying
        spec = Sdf.AttributeSpec(prim, name, type_name, variability)
    return spec


def _to_vt(value):
    """Python containers -> types USD can store in customLayerData (lists become typed arrays)."""
    if isinstance(value, dict):
        return {str(k): _to_vt(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, str) for v in value):
            return Vt.StringArray(list(value))
        return Vt.DoubleArray([float(v) for v in value])
    return value


def _set_info(layer: Sdf.Layer, info: LayerInfo) -> None:
    layer.timeCodesPerSecond = info.time_codes_per_second
    layer.framesPerSecond = info.frames_per_second
    layer.startTimeCode = info.start_time
    layer.endTimeCode = info.end_time
    meta = {}
    if info.up_axis:
        meta["upAxis"] = info.up_axis
    if info.meters_per_unit:
        meta["metersPerUnit"] = info.meters_per_unit
    for key, value in meta.items():
        layer.pseudoRoot.SetInfo(key, value)
    if info.custom:
        layer.customLayerData = _to_vt(info.custom)


def set_rows(layer: Sdf.Layer, path: Sdf.Path, times: list[float], values: np.ndarray, vt) -> None:
    """One ``vt`` array sample per frame from the rows of ``values (F, N, width)``: the one loop Sdf
    leaves us (it has no bulk setter), kept to the C calls. Rows that are all bit-identical (scales;
    a still pose's translations) are converted once: the crate file stores equal arrays once anyway."""
    set_sample = layer.SetTimeSample  # bound once: this loop is the writer's cost
    for t, row in zip(times, _vt_rows(values, vt)):
        set_sample(path, t, row)


def _vt_rows(values: np.ndarray, vt):
    """The rows as ``vt`` arrays, lazily; one shared array when every row has the same bits."""
    if values.dtype.kind == "f" and len(values) > 1:
        bits = values.view(f"u{values.itemsize}")  # bits, not values: -0.0 and NaN stay as they are
        if np.array_equal(bits[0], bits[-1]) and (bits == bits[0]).all():
            return repeat(vt.FromNumpy(values[0]), len(values))
    return map(vt.FromNumpy, values)


def build_override(overrides: list[AnimOverride], info: LayerInfo, fmt: str = "usdc") -> Sdf.Layer:
    """An anonymous layer holding only ``over`` opinions for the given animations and skeletons."""
    layer = Sdf.Layer.CreateAnonymous(f"usdgaze_override.{fmt}")
    with Sdf.ChangeBlock():
        _set_info(layer, info)
        for o in overrides:
            prim = Sdf.CreatePrimInLayer(layer, o.animation)
            prim.specifier = Sdf.SpecifierDef if o.define else Sdf.SpecifierOver
            if o.define:
                prim.typeName = "SkelAnimation"
                _bind_animation(layer, o.skeleton, o.animation)
            codes = np.asarray(o.times, dtype=float).tolist()
            if o.write_joints:
                _attr(prim, "joints", Sdf.ValueTypeNames.TokenArray, uniform=True).default = Vt.TokenArray(o.joints)
            columns = (
                ("rotations", Sdf.ValueTypeNames.QuatfArray, o.rotations, Vt.QuatfArray),
                ("translations", Sdf.ValueTypeNames.Float3Array, o.translations, Vt.Vec3fArray),
                ("scales", Sdf.ValueTypeNames.Half3Array, o.scales, Vt.Vec3hArray),
            )
            for name, type_name, values, vt in columns:
                if values is not None:
                    set_rows(layer, _attr(prim, name, type_name).path, codes, values, vt)
            if o.skeleton and o.skeleton_joints is not None:
                skel = Sdf.CreatePrimInLayer(layer, o.skeleton)
                skel.specifier = Sdf.SpecifierOver
                _attr(skel, "joints", Sdf.ValueTypeNames.TokenArray, True).default = Vt.TokenArray(o.skeleton_joints)
                for name, mats in (("restTransforms", o.rest_transforms), ("bindTransforms", o.bind_transforms)):
                    if mats is not None:
                        usd = rot.matrices_to_usd(mats)
                        _attr(skel, name, Sdf.ValueTypeNames.Matrix4dArray, True).default = Vt.Matrix4dArray.FromNumpy(usd)
                if o.joint_names is not None:
                    _attr(skel, "jointNames", Sdf.ValueTypeNames.TokenArray, True).default = Vt.TokenArray(o.joint_names)
        if info.default_prim and layer.GetPrimAtPath(Sdf.Path.absoluteRootPath.AppendChild(info.default_prim)):
            layer.defaultPrim = info.default_prim
    return layer


def _bind_animation(layer: Sdf.Layer, skeleton: str, animation: str) -> None:
    """``skel:animationSource`` on ``skeleton`` (an over applying SkelBindingAPI) targeting ``animation``."""
    skel = Sdf.CreatePrimInLayer(layer, skeleton)
    skel.specifier = Sdf.SpecifierOver
    skel.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
    rel = Sdf.RelationshipSpec(skel, "skel:animationSource", custom=False)
    rel.targetPathList.explicitItems = [Sdf.Path(animation)]


def relative_asset_path(target: str | os.PathLike, from_layer: str | os.PathLike) -> str:
    """``target`` relative to the folder of ``from_layer``, with forward slashes and a ./ prefix."""
    rel = os.path.relpath(os.path.abspath(target), os.path.dirname(os.path.abspath(from_layer)))
    rel = rel.replace(os.sep, "/")
    return rel if rel.startswith("../") else f"./{rel}"


def write_preview(preview: str | os.PathLike, override: str | os.PathLike, input_path: str | os.PathLike,
                  info: LayerInfo, default_prim: str | None, outputs: Outputs | None = None) -> None:
    """A new root layer sublayering [override, input]: open it to see the result, mute the first to compare."""
    fmt = Path(preview).suffix.lstrip(".") or "usda"
    layer = Sdf.Layer.CreateAnonymous(f"usdgaze_preview.{fmt}")
    with Sdf.ChangeBlock():
        _set_info(layer, LayerInfo(info.time_codes_per_second, info.frames_per_second, info.start_time,
                                   info.end_time, info.up_axis, info.meters_per_unit))
        layer.subLayerPaths.append(relative_asset_path(override, preview))
        layer.subLayerPaths.append(relative_asset_path(input_path, preview))
        if default_prim:
            layer.defaultPrim = default_prim
    atomic_export(layer, preview, outputs, flag="--preview")


def check_sublayer_target(root: str | os.PathLike, anim_paths: list[str],
                          input_path: str | os.PathLike | None = None, bound: tuple[str, ...] = ()) -> Sdf.Layer:
    """A copy of the layer ``root`` if the override can go in as its strongest sublayer, else a one-line error.

    Refuses when ``root`` itself holds opinions on the animations, since a sublayer is weaker than
    its root layer's own opinions (on ``bound``, skeletons the override binds a new animation to,
    their ``skel:animationSource``), and when ``root`` does not compose ``input_path`` (given). Called
    before anything is written. The copy is anonymous, so a
    failed command leaves the layer registry's ``root`` as it was.
    """
    if Path(root).suffix.lower() not in _FORMATS:
        raise UsdGazeError(f"{root}: --sublayer-into must name a .usda, .usdc or .usd layer")
    if not os.path.isfile(root):
        raise UsdGazeError(f"{root}: no such file to insert the sublayer into")
    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(root))
    except Exception as exc:  # pxr raises Tf.ErrorException with multi-line text
        raise UsdGazeError(f"{root}: cannot open the layer to insert the sublayer into ({usd_failure(exc)})") from None
    if layer is None:
        raise UsdGazeError(f"{root}: cannot open the layer to insert the sublayer into")
    if input_path is not None:
        from usdgaze.usd.stage import layer_dependencies, without_usd_warnings

        # The edit goes to the file a symlinked root names, so its sublayers are read from there (one may
        # be this command's output, not written yet: USD's warning about it is not ours to pass on).
        with without_usd_warnings():
            composed = {os.path.realpath(f) for f in layer_dependencies(os.path.realpath(root))}
        if os.path.realpath(input_path) not in composed:
            raise UsdGazeError(f"{root}: does not compose {input_path} (no sublayer, reference or payload brings "
                               "it in), so the override would change nothing there; use the shot layer that does")
        _check_same_paths(root, input_path, anim_paths)
    for path in anim_paths:
        for name in ("rotations", "translations", "scales"):
            spec = layer.GetAttributeAtPath(Sdf.Path(path).AppendProperty(name))
            if spec is not None and (spec.HasDefaultValue() or layer.GetNumTimeSamplesForPath(spec.path)):
                raise UsdGazeError(
                    f"{root}:{path}.{name}: this layer's own opinion would win over any sublayer; "
                    "use --preview, or insert into a layer that sublayers this one"
                )
    for path in bound:
        if layer.GetRelationshipAtPath(Sdf.Path(path).AppendProperty("skel:animationSource")) is not None:
            raise UsdGazeError(
                f"{root}:{path}.skel:animationSource: this layer's own opinion would win over the sublayer's "
                "binding of the new animation; use --preview, or insert into a layer that sublayers this one"
            )
    return layer


def _check_same_paths(root: str | os.PathLike, input_path: str | os.PathLike, anim_paths: list[str]) -> None:
    """``root`` composes the input's animations at the input's own paths: a shot that references the
    character at another path (/World/Hero for the asset's /Character) is untouched by opinions at
    /Character (it was said to be 'inserted', and the shot played the input unchanged)."""
    real_input = os.path.realpath(input_path)
    if any(os.path.realpath(p) == real_input for p, _ in _stack_offsets(Sdf.Layer.FindOrOpen(os.path.realpath(root)))):
        return  # sublayered: the same paths
    from pxr import Usd

    from usdgaze.usd.stage import without_usd_warnings

    with without_usd_warnings():  # its sublayers may name this command's output, not written yet
        # Only the animations' prims are composed: a shot's other assets and payloads stay unread.
        stage = Usd.Stage.OpenMasked(os.path.realpath(root), Usd.StagePopulationMask([Sdf.Path(p) for p in anim_paths]))
    for path in anim_paths:
        prim = stage.GetPrimAtPath(path)
        if not prim or not any(os.path.realpath(s.layer.realPath or "") == real_input for s in prim.GetPrimStack()):
            raise UsdGazeError(f"{root}: brings {input_path} in, but not at {path} (a reference or payload puts it "
                               "elsewhere), so the override, made at the input's paths, would change nothing there; "
                               "run apply on this layer itself (--skel-root the shot's character) and sublayer that")
        offset = _arc_offset(prim, real_input)
        plain = _scaling(stage.GetRootLayer(), real_input)
        if offset is not None and not (abs(offset.offset - plain.offset) < 1e-9 and abs(offset.scale - plain.scale) < 1e-12):
            raise UsdGazeError(f"{root}: brings {input_path} in at {path} with a time offset (a reference or payload's "
                               f"offset {offset.offset:g}, scale {offset.scale / plain.scale:g}), which a sublayer "
                               "cannot follow; run apply on this layer itself and sublayer that")


def _arc_offset(prim: Usd.Prim, real_input: str) -> Sdf.LayerOffset | None:
    """The time mapping from ``real_input`` (in a reference or payload's layer stack) to the stage's root."""
    nodes = [prim.GetPrimIndex().rootNode]
    while nodes:
        node = nodes.pop()
        nodes.extend(node.children)
        for layer, offset in zip(node.layerStack.layers, node.layerStack.layerOffsets):
            if os.path.realpath(layer.realPath or "") == real_input:
                return node.mapToRoot.timeOffset * offset
    return None


def _stack_offsets(layer: Sdf.Layer) -> list[tuple[str, Sdf.LayerOffset]]:
    """(real path, offset to the root) of every layer in ``layer``'s layer stack, as Pcp composes it."""
    from pxr import Pcp

    ident = Pcp.LayerStackIdentifier(layer)
    stack, _errors = Pcp.Cache(ident).ComputeLayerStack(ident)
    return [(l.realPath, o) for l, o in zip(stack.layers, stack.layerOffsets)]


def override_offset(root: str | os.PathLike, input_path: str | os.PathLike | None) -> Sdf.LayerOffset:
    """The offset to author on the override as ``root``'s first sublayer so that it plays in step with
    the input: the offset at which ``root``'s layer stack brings the input in (its sublayer offsets
    composed), less the timeCodesPerSecond scaling Pcp gives the override as it gives the input.
    Identity when the input is not in ``root``'s layer stack (a reference or payload brings it in)."""
    if input_path is None:
        return Sdf.LayerOffset()
    target = os.path.realpath(input_path)
    layer = Sdf.Layer.FindOrOpen(os.path.realpath(root))
    found = [o for p, o in _stack_offsets(layer) if p and os.path.realpath(p) == target] if layer else []
    if not found:
        return Sdf.LayerOffset()
    return found[0] * _scaling(layer, target).GetInverse()


def _scaling(layer: Sdf.Layer, target: str) -> Sdf.LayerOffset:
    """The timeCodesPerSecond scaling alone that ``layer`` gives ``target`` brought in without an offset."""
    probe = Sdf.Layer.CreateAnonymous("usdgaze_offset.usda")  # the input as the sublayer of a like root
    if layer.HasTimeCodesPerSecond():
        probe.timeCodesPerSecond = layer.timeCodesPerSecond
    if layer.HasFramesPerSecond():
        probe.framesPerSecond = layer.framesPerSecond
    probe.subLayerPaths.append(target)
    return _stack_offsets(probe)[1][1]


def _listed(layer: Sdf.Layer, real_root: str, override: str | os.PathLike) -> list[int]:
    """Indices of ``layer``'s subLayers that name ``override`` (any spelling, symlinks followed)."""
    target = os.path.realpath(override)
    folder = os.path.dirname(real_root)
    return [i for i, p in enumerate(layer.subLayerPaths) if os.path.realpath(os.path.join(folder, p)) == target]


def sublayered(root: str | os.PathLike, override: str | os.PathLike, input_path=None) -> bool:
    """``override`` is ``root``'s strongest sublayer, at the offset that keeps it in step with the input."""
    real = os.path.realpath(root)
    layer = Sdf.Layer.OpenAsAnonymous(real, metadataOnly=True)
    if layer is None or 0 not in _listed(layer, real, override):
        return False
    return layer.subLayerOffsets[0] == override_offset(real, input_path)


def insert_sublayer(root: str | os.PathLike, override: str | os.PathLike, anim_paths: list[str],
                    outputs: Outputs | None = None, input_path: str | os.PathLike | None = None) -> bool:
    """Make ``override`` the strongest sublayer of ``root``, changing nothing but its subLayers.

    Returns False if it already was there. An entry naming it lower down (weaker than the input, so
    it would change nothing) is moved to the front. It gets the offset at which ``root`` brings in
    ``input_path`` (given), so that it plays in step with the input. Refuses (see
    :func:`check_sublayer_target`) when ``root`` itself holds opinions on the animations. A symlinked
    ``root`` is edited at its target, which keeps its mode; a read-only one is refused.
    """
    real = os.path.realpath(root)
    layer = check_sublayer_target(root, anim_paths)
    offset = override_offset(real, input_path)
    listed = _listed(layer, real, override)
    if listed[:1] == [0] and layer.subLayerOffsets[0] == offset:
        return False
    with outputs_of(outputs) as tx:
        if not tx.claimed(root):
            tx.claim(root, "--sublayer-into", edit=True)
        for i in reversed(listed):
            del layer.subLayerPaths[i]
        layer.subLayerPaths.insert(0, relative_asset_path(override, real))
        layer.subLayerOffsets[0] = offset
        tx.stage_layer(root, layer)
    return True


def reload_if_open(path: str | os.PathLike) -> None:
    """Keep a layer this process has open in step with the file a command just replaced."""
    layer = Sdf.Layer.Find(str(path))
    if layer is not None:
        layer.Reload(force=True)
