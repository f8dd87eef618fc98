"""Gaze maps stored in USD: the ``GazeMapAPI`` applied schema (source: ``schemas/schema.usda``).

A map lives on a SkelRoot, either authored there or brought in by composition from a map file
written by :func:`dump_map` (an abstract ``class SkelRoot`` prim), so one file can serve many
characters. Reading goes through composed values, so referenced and inherited maps read alike.

Every problem is a one-line :class:`~usdgaze.errors.GazeMapError` reading
``FILE:PRIMPATH.ATTRIBUTE: problem``. This module checks storage (missing, mistyped, animated,
unequal arrays, non-unit quaternions); :func:`usdgaze.gaze.definition.validate` checks values.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from pxr import Gf, Sdf, Usd, UsdSkel, Vt

from usdgaze.usd import plugin as _plugin
from usdgaze.usd.checks import authored_type, value_spec
from usdgaze.usd.stage import composed_files, open_stage
from usdgaze.gaze.definition import (
    API_NAME,
    BINDING_ATTRS,
    EXAMPLE_ATTRS,
    FORWARD_ATTR,
    OFFSET_ATTRS,
    PITCH_ATTR,
    SETTING_ATTRS,
    TIMING_ATTRS,
    YAW_ATTR,
    GazeMapDefinition,
    SynthesisSettings,
    check_unit_quaternions,
    validate,
)
from usdgaze.errors import GazeMapError
from usdgaze.files.transaction import Outputs, outputs_of
from usdgaze.gaze.motion import GazeMotions

# Normally done by ``import usdgaze`` already; it must precede any stage in the process.
_plugin.register()

_T = Sdf.ValueTypeNames
_INT_SETTINGS = {f.name for f in dataclasses.fields(SynthesisSettings) if f.type in ("int", int)}
_SETTING_DEFAULTS = SynthesisSettings()

# attribute -> (Sdf type authored by write_map, Python type Get() must return)
_TYPES: dict[str, tuple[Sdf.ValueTypeName, type | tuple[type, ...]]] = {
    **{a: (_T.FloatArray, Vt.FloatArray) for a in (YAW_ATTR, PITCH_ATTR) + TIMING_ATTRS},
    **{a: (_T.QuatfArray, Vt.QuatfArray) for a in OFFSET_ATTRS},
    **{a: (_T.TokenArray, Vt.TokenArray) for a in BINDING_ATTRS.values()},
    FORWARD_ATTR: (_T.Float3, Gf.Vec3f),
    **{a: ((_T.Int, int) if n in _INT_SETTINGS else (_T.Float, (float, int))) for n, a in SETTING_ATTRS.items()},
}
_INT32 = (-(2**31), 2**31 - 1)
# A float32 that reads back within this of length 1 was a unit quaternion before it was stored.


def has_map(prim: Usd.Prim) -> bool:
    """Whether ``prim`` has ``GazeMapAPI`` applied (authored or composed)."""
    return _plugin.has_api(prim, API_NAME, GazeMapError)


def root_map(root: Usd.Prim, source: str) -> GazeMapDefinition | None:
    """The gaze map of a character's SkelRoot ``root``, None where it has none. A GazeMapAPI on a prim
    under it (a map file referenced onto the Skeleton) or above it (onto a crowd's Xform) is refused: it
    went unused without a word, the built-in map in its place (``validate`` says it too)."""
    prims = iter(Usd.PrimRange(root, Usd.PrimDefaultPredicate))  # active, defined: what UsdSkel sees
    for prim in prims:
        if prim.IsA(UsdSkel.Root) and prim != root:  # another character's, with its own map
            prims.PruneChildren()
        elif prim != root and has_map(prim):
            raise _misplaced(prim, root, source)
    parent = root.GetParent()
    while parent and not parent.IsPseudoRoot():
        if has_map(parent) and not parent.IsA(UsdSkel.Root):
            raise _misplaced(parent, root, source)
        parent = parent.GetParent()
    return read_map(root, source) if has_map(root) else None


def _misplaced(prim: Usd.Prim, root: Usd.Prim, source: str) -> GazeMapError:
    return GazeMapError(f"{source}:{prim.GetPath()}: {API_NAME} is applied to a {prim.GetTypeName() or 'typeless prim'}; "
                        f"it applies only to SkelRoot (this character's is {root.GetPath()}): apply it there")


def _check_map_prim(prim: Usd.Prim, where: str) -> None:
    """Raise unless ``prim`` exists, has ``GazeMapAPI`` and is a SkelRoot (and the schema is registered)."""
    _require_schema(where)
    if not prim:
        raise GazeMapError(f"{where}: no such prim")
    if not prim.IsActive():  # composed, but out of the scene: a map switched off is no map to use
        raise GazeMapError(f"{where}: is inactive (active = false), so its {API_NAME} is not in the scene")
    if not has_map(prim):
        unloaded = prim.HasAuthoredPayloads() and not prim.IsLoaded()
        raise GazeMapError(f"{where}: no {API_NAME} applied" + (" (its payload is not loaded)" if unloaded else ""))
    if not prim.IsA(UsdSkel.Root):
        raise GazeMapError(f"{where}: {API_NAME} is applied to a prim of type {_type_name(prim)}; it applies only to SkelRoot")


def _example_arrays(prim: Usd.Prim, where: str) -> dict[str, np.ndarray]:
    """Every per-example array, checked to hold one entry per example and unit offsets."""
    arrays = {name: np.asarray(_get(prim, name, where, required=True)) for name in EXAMPLE_ATTRS}
    lengths = np.array([len(a) for a in arrays.values()])
    # Blame the odd ones out: the length most arrays agree on is the example count.
    values, counts = np.unique(lengths, return_counts=True)
    count = int(values[np.argmax(counts)]) if counts.max() > 1 else int(lengths[0])
    if count == 0:
        raise GazeMapError(f"{where}.{YAW_ATTR}: no examples, expected at least one")
    for name, array in arrays.items():
        if len(array) != count:
            raise GazeMapError(f"{where}.{name}: {len(array)} entries, expected {count} (one per example)")
    for name in OFFSET_ATTRS:
        check_unit_quaternions(arrays[name], f"{where}.{name}")
    return arrays


def _read_bindings(prim: Usd.Prim, where: str) -> dict[str, tuple[str, ...]]:
    """Role -> joint paths for every role bound to a non-empty list of valid paths."""
    bindings: dict[str, tuple[str, ...]] = {}
    for role, name in BINDING_ATTRS.items():
        value = _get(prim, name, where)
        joints = tuple(str(t) for t in value) if value is not None else ()
        for k, joint in enumerate(joints):
            if not joint.strip() or not Sdf.Path.IsValidPathString(joint):
                raise GazeMapError(f"{where}.{name}: entry {k} is {joint!r}, expected a joint path")
        if joints:
            bindings[role] = joints
    return bindings


def _read_forward(prim: Usd.Prim, where: str) -> tuple[float, float, float] | None:
    """The authored non-zero forward, or None."""
    forward_value = _get(prim, FORWARD_ATTR, where)
    forward = None
    if forward_value is not None and any(c != 0.0 for c in forward_value):
        forward = tuple(_shortest(c) for c in forward_value)
    return forward


def _read_settings(prim: Usd.Prim, where: str) -> SynthesisSettings:
    """The synthesis settings, dataclass defaults where an attribute resolves to nothing."""
    settings = {}
    for field, name in SETTING_ATTRS.items():
        value = _get(prim, name, where)
        if value is None:  # schema not consulted (no fallback): keep the dataclass default
            value = getattr(_SETTING_DEFAULTS, field)
        settings[field] = int(value) if field in _INT_SETTINGS else _shortest(value)
    return SynthesisSettings(**settings)


def read_map(prim: Usd.Prim, source: str | None = None) -> GazeMapDefinition:
    """The gaze map on ``prim``, from composed values; ``source`` names the file in errors.

    Unauthored synthesis settings fall back to the schema's (= :class:`SynthesisSettings`)
    defaults; unauthored or empty bindings are left out (found by name later).
    """
    where = _where(prim, source)
    _check_map_prim(prim, where)
    try:
        return _read_checked(prim, where)
    except GazeMapError as exc:
        raise _named_where_authored(exc, prim, where) from None


def _read_checked(prim: Usd.Prim, where: str) -> GazeMapDefinition:
    arrays = _example_arrays(prim, where)
    params = np.stack([arrays[YAW_ATTR], arrays[PITCH_ATTR]], axis=-1).astype(float)
    offsets = np.stack([arrays[name] for name in OFFSET_ATTRS], axis=1).astype(float)
    timing = np.stack([arrays[name] for name in TIMING_ATTRS], axis=-1).astype(float)
    bindings = _read_bindings(prim, where)
    forward = _read_forward(prim, where)
    settings = _read_settings(prim, where)

    definition = GazeMapDefinition(
        params=params,
        motions=GazeMotions(offsets, timing),
        settings=settings,
        bindings=bindings,
        forward=forward,
    )
    validate(definition, where)
    return definition


def _named_where_authored(exc: GazeMapError, prim: Usd.Prim, where: str) -> GazeMapError:
    """``exc`` naming the layer that authors the attribute at fault where that is not the stage's root
    layer (a map referenced or inherited from a map file, or a sublayer's), as ``validate`` names it:
    ``gaze_map.usda:/Crowd/Walker1.gaze:...`` (it named the stage, which holds no such value)."""
    text = str(exc)
    name = next((n for n in _TYPES if text.startswith(f"{where}.{n}: ")), None)
    spec = value_spec(prim.GetAttribute(name)) if name else None
    layer = spec.layer if spec is not None else None
    if layer is None or layer == prim.GetStage().GetRootLayer() or layer.anonymous or not layer.realPath:
        return exc
    source = where[: -len(f":{prim.GetPath()}")]
    path = layer.realPath if os.path.isabs(source) else os.path.relpath(layer.realPath)
    return GazeMapError(f"{path}:{prim.GetPath()}.{name}: {text[len(where) + len(name) + 3:]}")


def write_map(prim: Usd.Prim, definition: GazeMapDefinition) -> None:
    """Apply ``GazeMapAPI`` to ``prim`` (a SkelRoot) and author every attribute of ``definition``."""
    _write(prim, definition, _where(prim, None))


def load_map(spec: str, outputs: Outputs | None = None) -> GazeMapDefinition:
    """Read a map from ``FILE`` or ``FILE:PRIMPATH``.

    Without a prim path: the default prim if it has the map, else the one prim (abstract
    ``class`` prims included) that has it. ``outputs``: the command's writer, told every file read.
    """
    file, prim_path = _split_spec(spec)
    _require_schema(file)
    stage = open_stage(file, error=GazeMapError)
    if outputs is not None:
        for read in composed_files(stage):
            outputs.read(read, "--map file")
    if prim_path is not None:
        if not Sdf.Path.IsValidPathString(prim_path) or not Sdf.Path(prim_path).IsAbsoluteRootOrPrimPath():
            raise GazeMapError(f"{file}: {prim_path!r} is not an absolute prim path")
        prim = stage.GetPrimAtPath(prim_path)
        if not prim:
            raise GazeMapError(f"{file}:{prim_path}: no such prim")
    else:
        prim = _find_map_prim(stage, file)
    return read_map(prim, source=file)


def check_map_path(path: str | os.PathLike) -> Path:
    """``path`` if a map can be written there by its suffix, else a one-line error."""
    path = Path(path)
    ext = path.suffix.lstrip(".")
    if ext not in ("usda", "usdc", "usd") or Sdf.FileFormat.FindByExtension(ext) is None:
        raise GazeMapError(f"{path}: cannot write a gaze map to a '{path.suffix}' file; use .usda, .usdc or .usd")
    return path


def dump_map(
    definition: GazeMapDefinition,
    path: str | os.PathLike,
    prim_path: str = "/GazeMap",
    custom_layer_data: Mapping[str, Any] | None = None,
    outputs: "Outputs | None" = None,
    flag: str = "map",
) -> None:
    """Write ``definition`` to a new layer at ``path`` (.usda, .usdc or .usd), through ``outputs``.

    The map is an abstract ``class SkelRoot`` at the root prim ``prim_path``, made the default
    prim: it never renders, and characters bring it in with a reference or an inherit.
    """
    path = check_map_path(path)
    ext = path.suffix.lstrip(".")
    if not Sdf.Path.IsValidPathString(prim_path) or not Sdf.Path(prim_path).IsRootPrimPath():
        raise GazeMapError(f"{path}: {prim_path!r} is not a root prim path such as /GazeMap")

    layer = Sdf.Layer.CreateAnonymous("." + ext)
    layer.documentation = (
        f"usdgaze gaze map: {API_NAME} on an abstract SkelRoot class. Bring it into a character's "
        f"SkelRoot with a reference or an inherit."
    )
    from usdgaze import __version__

    # Marked as usdgaze's, so that writing the map again may replace it (files.transaction).
    layer.customLayerData = {"usdgaze": {"version": __version__}, **dict(custom_layer_data or {})}
    stage = Usd.Stage.Open(layer)
    prim = stage.CreateClassPrim(prim_path)
    prim.SetTypeName("SkelRoot")
    _write(prim, definition, f"{path}:{prim_path}")
    layer.defaultPrim = Sdf.Path(prim_path).name

    with outputs_of(outputs) as tx:
        if not tx.claimed(path):
            tx.claim(path, flag)
        tx.stage_layer(path, layer)


# -- helpers -----------------------------------------------------------------------------------------


def _where(prim: Usd.Prim, source: str | None) -> str:
    if source is None:
        stage = prim.GetStage() if prim else None
        source = stage.GetRootLayer().identifier if stage else "<no stage>"
    return f"{source}:{prim.GetPath() if prim else ''}"


def _type_name(prim: Usd.Prim) -> str:
    return prim.GetTypeName() or "(none)"


def _get(prim: Usd.Prim, name: str, where: str, required: bool = False) -> Any:
    """Composed value of ``name``, type-checked; None when unset and not ``required``."""
    attr = prim.GetAttribute(name)
    if attr and attr.GetNumTimeSamples():
        raise GazeMapError(f"{where}.{name}: has time samples; gaze map attributes are uniform (one default value)")
    value = attr.Get() if attr else None
    if value is None or (required and not attr.HasAuthoredValue()):
        if required:
            raise GazeMapError(f"{where}.{name}: missing, expected one entry per example")
        return None
    sdf_type, python_type = _TYPES[name]
    if not isinstance(value, python_type) or isinstance(value, bool):
        raise GazeMapError(f"{where}.{name}: authored as {authored_type(attr)}, expected {sdf_type}")
    return value


def _shortest(x: float) -> float:
    """A float32 read back as the shortest decimal that rounds to it (0.3, not 0.30000001192...)."""
    return float(str(np.float32(x)))


def _require_schema(where: str) -> None:
    if not Usd.SchemaRegistry.GetTypeFromSchemaTypeName(API_NAME):
        raise GazeMapError(
            f"{where}: OpenUSD does not know {API_NAME} in this process (a stage was opened before usdgaze "
            f"was imported); import usdgaze first or set PXR_PLUGINPATH_NAME={_plugin.plugin_dir()}"
        )


def _write(prim: Usd.Prim, definition: GazeMapDefinition, where: str) -> None:
    _require_schema(where)
    if not prim:
        raise GazeMapError(f"{where}: no such prim")
    if not prim.CanApplyAPI(API_NAME):
        raise GazeMapError(f"{where}: cannot hold {API_NAME}: its type is {_type_name(prim)}, and {API_NAME} applies only to SkelRoot")
    validate(definition, where)
    settings = definition.settings
    for field, name in SETTING_ATTRS.items():
        value = getattr(settings, field)
        if field in _INT_SETTINGS and not _INT32[0] <= value <= _INT32[1]:
            raise GazeMapError(f"{where}.{name}: {value} does not fit the attribute's 32-bit int")

    def author(name: str, value: Any) -> None:
        attr = prim.CreateAttribute(name, _TYPES[name][0], False, Sdf.VariabilityUniform)
        attr.Set(value)

    prim.ApplyAPI(API_NAME)
    motions = definition.motions
    author(YAW_ATTR, Vt.FloatArray.FromNumpy(np.ascontiguousarray(definition.params[:, 0], dtype=np.float32)))
    author(PITCH_ATTR, Vt.FloatArray.FromNumpy(np.ascontiguousarray(definition.params[:, 1], dtype=np.float32)))
    for j, name in enumerate(OFFSET_ATTRS):
        author(name, Vt.QuatfArray.FromNumpy(np.ascontiguousarray(motions.offsets[:, j, :], dtype=np.float32)))
    for c, name in enumerate(TIMING_ATTRS):
        author(name, Vt.FloatArray.FromNumpy(np.ascontiguousarray(motions.timing[:, c], dtype=np.float32)))
    for role, name in BINDING_ATTRS.items():
        # Empty arrays too: an explicit "find by name" overrides a map composed from elsewhere.
        author(name, Vt.TokenArray([str(j) for j in definition.bindings.get(role, ())]))
    author(FORWARD_ATTR, Gf.Vec3f(*(definition.forward if definition.forward is not None else (0.0, 0.0, 0.0))))
    for field, name in SETTING_ATTRS.items():
        value = getattr(settings, field)
        author(name, int(value) if field in _INT_SETTINGS else float(value))


def _split_spec(spec: str) -> tuple[str, str | None]:
    """``FILE`` or ``FILE:PRIMPATH``; an existing file wins, so ``C:/maps/a.usda`` stays whole."""
    spec = os.fspath(spec)
    if os.path.exists(spec):
        return spec, None
    file, sep, prim_path = spec.rpartition(":")
    if sep and file and prim_path.startswith("/"):
        return file, prim_path
    if sep and file and prim_path and os.path.exists(file):
        raise GazeMapError(f"{spec}: the prim path after ':' must be absolute, as in {file}:/{prim_path}")
    return spec, None


def _find_map_prim(stage: Usd.Stage, file: str) -> Usd.Prim:
    default = stage.GetDefaultPrim()
    if has_map(default):
        return default
    found = [p for p in Usd.PrimRange.Stage(stage, Usd.PrimAllPrimsPredicate) if has_map(p)]
    if not found:
        raise GazeMapError(f"{file}: no prim has {API_NAME}")
    if len(found) > 1:
        shown = ", ".join(str(p.GetPath()) for p in found[:5]) + (", ..." if len(found) > 5 else "")
        raise GazeMapError(f"{file}: {len(found)} prims have {API_NAME} ({shown}); name one as {file}:PRIMPATH")
    return found[0]
