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

from usdgaze import __version__
from usdgaze.core import rotations as rot
from usdgaze.errors import UsdGazeError
from usdgaze.files.transaction import Outputs, outputs_of

USD_FORMATS = {".usda", ".usdc", ".usd"}


def check_output_path(path: str | os.PathLike, flag: str = "--out") -> Path:
    """The output path, or a one-line error (naming ``flag``, the option that gave it) if its extension
    or folder is unusable."""
    p = Path(path)
    if p.suffix.lower() not in USD_FORMATS:
        raise UsdGazeError(f"{flag} {p}: must end in .usda, .usdc or .usd")
    if not os.path.exists(p.parent):  # os.path: Path.exists() raises for a name over NAME_MAX
        raise UsdGazeError(f"{p}: folder {p.parent} does not exist")
    return p


def atomic_export(layer: Sdf.Layer, path: str | os.PathLike, outputs: Outputs | None = None,
                  flag: str = "--out") -> None:
    """Write ``layer`` to ``path`` as part of ``outputs`` (or on its own, when none is given)."""
    path = check_output_path(path, flag)
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
        if new and clip.authored_poses[0]:
            override._driven_only(set(result.changed_joints) | set(result.added_joints))
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

    def _driven_only(self, driven: set[str]) -> None:
        """A new animation lists only the joints the pass drives: the others keep the skeleton's rest
        pose to the bit (listed, each was its float copy, ~1e-7 off the double-precision rest)."""
        keep = [i for i, j in enumerate(self.joints) if j in driven]
        self.joints = [self.joints[i] for i in keep]
        for name in ("rotations", "translations", "scales"):
            values = getattr(self, name)
            if values is not None:
                setattr(self, name, values[:, keep])


@dataclass
class LayerInfo:
    """Timing metadata copied from the input so samples are neither rescaled nor shifted."""

    time_codes_per_second: float
    frames_per_second: float
    start_time: float | None
    end_time: float | None
    """The input's startTimeCode and endTimeCode, each None where the input authors none: a layer that
    authored USD's fallback 0 would give the preview a range of [0, 0] (or [start, 0]) the input lacks."""
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


def layer_info(stage) -> LayerInfo:
    """Timing and units metadata of the input stage, copied to every layer written (a time range only
    where the input authors one: USD's fallback 0 is no range)."""
    from pxr import UsdGeom

    def authored(key: str, value: float) -> float | None:
        return float(value) if stage.HasAuthoredMetadata(key) else None

    return LayerInfo(float(stage.GetTimeCodesPerSecond()), float(stage.GetFramesPerSecond()),
                     authored("startTimeCode", stage.GetStartTimeCode()),
                     authored("endTimeCode", stage.GetEndTimeCode()),
                     str(UsdGeom.GetStageUpAxis(stage)), float(UsdGeom.GetStageMetersPerUnit(stage)),
                     default_prim=stage.GetRootLayer().defaultPrim or None)


def _set_info(layer: Sdf.Layer, info: LayerInfo) -> None:
    layer.timeCodesPerSecond = info.time_codes_per_second
    layer.framesPerSecond = info.frames_per_second
    if info.start_time is not None:
        layer.startTimeCode = info.start_time
    if info.end_time is not None:
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


class OverrideLayer:
    """The override layer, filled one animation at a time: a crowd's characters are written as each
    is done, so their float64 results need not all be held until the end."""

    def __init__(self, info: LayerInfo, fmt: str = "usdc", custom_later: bool = False):
        self.layer = Sdf.Layer.CreateAnonymous(f"usdgaze_override.{fmt}")
        self.info = info
        self.bound: list[str] = []
        """Skeletons a new animation was bound to."""
        self._custom_later = custom_later
        with Sdf.ChangeBlock():
            _set_info(self.layer, info)
            if custom_later:  # hold its place among the layer's fields: the file is the same either way
                self.layer.customLayerData = {"usdgaze": "pending"}

    def add(self, o: AnimOverride) -> None:
        """Author ``over`` opinions (or a new, bound animation) for one animation."""
        with Sdf.ChangeBlock():
            _author(self.layer, o)
        if o.define:
            self.bound.append(o.skeleton)

    def finish(self, custom: dict | None = None) -> Sdf.Layer:
        """The layer, with ``custom`` as its customLayerData and the input's default prim where the
        layer has that prim."""
        layer, info = self.layer, self.info
        if self._custom_later != (custom is not None):
            raise ValueError("finish() takes custom data exactly when the layer was made with custom_later")
        with Sdf.ChangeBlock():
            if custom is not None:
                layer.customLayerData = _to_vt(custom)
            if info.default_prim and layer.GetPrimAtPath(Sdf.Path.absoluteRootPath.AppendChild(info.default_prim)):
                layer.defaultPrim = info.default_prim
        return layer


def build_override(overrides: list[AnimOverride], info: LayerInfo, fmt: str = "usdc") -> Sdf.Layer:
    """An anonymous layer holding only ``over`` opinions for the given animations and skeletons."""
    out = OverrideLayer(info, fmt)
    for o in overrides:
        out.add(o)
    return out.finish()


def _author(layer: Sdf.Layer, o: AnimOverride) -> None:
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


def _bind_animation(layer: Sdf.Layer, skeleton: str, animation: str) -> None:
    """``skel:animationSource`` on ``skeleton`` (an over applying SkelBindingAPI) targeting ``animation``."""
    skel = Sdf.CreatePrimInLayer(layer, skeleton)
    skel.specifier = Sdf.SpecifierOver
    skel.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
    rel = Sdf.RelationshipSpec(skel, "skel:animationSource", custom=False)
    rel.targetPathList.explicitItems = [Sdf.Path(animation)]


def is_override_record(record) -> bool:
    """Whether ``customLayerData["usdgaze"]`` is that of an override usdgaze wrote: ``apply``'s (its
    shifts) or ``attend``'s (its command; it records no shifts). A gaze map file is marked usdgaze's
    too, and is no override."""
    return isinstance(record, dict) and ("shifts" in record or str(record.get("command", "")).startswith("attend"))


def preview_overrides(layer: Sdf.Layer) -> list[str] | None:
    """Where ``layer`` is a root ``--preview`` wrote (usdgaze's mark on it), the overrides it sublayers
    (absolute paths; none found: []), else None. Such a root is a stage to open, holding no prims of
    its own: no override to review over its input."""
    record = (layer.customLayerData or {}).get("usdgaze")
    if not (isinstance(record, dict) and record.get("preview")):
        return None
    out = []
    for sub in layer.subLayerPaths:
        path = layer.ComputeAbsolutePath(sub)
        try:
            found = Sdf.Layer.FindOrOpen(path)
        except Exception:  # pxr raises Tf.ErrorException for a missing or broken sublayer
            found = None
        if found is not None and is_override_record((found.customLayerData or {}).get("usdgaze")):
            out.append(path)
    return out


def composed_override_notes(stage, source: str) -> list[str]:
    """A warning for each usdgaze override the input stage composes: a pass on that stage starts from
    the motion with that layer's gaze in it, so its offsets add to the old ones (a rerun meant to
    replace the layer reads the stage without it)."""
    notes = []
    used = [layer for layer in stage.GetUsedLayers() if layer is not None and not layer.anonymous and layer.realPath]
    for layer in sorted(used, key=lambda layer: layer.realPath):  # USD lists them in no set order
        record = dict(layer.customLayerData).get("usdgaze")
        if is_override_record(record):
            notes.append(f"{source}: composes {layer.realPath}, a layer usdgaze wrote ({record.get('command', 'apply')}): "
                         "this pass adds to the gaze in it; to redo that pass instead, run on the stage without it")
    return notes


def is_override(path: str | os.PathLike) -> bool:
    """Whether the layer file at ``path`` is an override usdgaze wrote (:func:`is_override_record`)."""
    try:
        layer = Sdf.Layer.OpenAsAnonymous(os.fspath(path), metadataOnly=True)
    except Exception:  # unreadable: not ours
        return False
    return layer is not None and is_override_record(dict(layer.customLayerData).get("usdgaze"))


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
        # usdgaze's mark: the next run may replace this root, which holds no prims of its own
        # (a shot's root of sublayers looks the same and is refused, see files.paths._foreign_layer)
        layer.customLayerData = {"usdgaze": {"preview": True, "version": __version__}}
    atomic_export(layer, preview, outputs, flag="--preview")


def reload_if_open(path: str | os.PathLike) -> None:
    """Keep a layer this process has open in step with the file a command just replaced."""
    layer = Sdf.Layer.Find(str(path))
    if layer is not None:
        layer.Reload(force=True)
