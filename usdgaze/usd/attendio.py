"""The attend pass's inspection prims: point of sight, eye pose, per-object estimate and uncertainty.

They live under ``/UsdGazeAttend/<character>`` (the SkelRoot's path with ``_`` for ``/``, ``_2``... where
another character spells the same) in the override layer (``def Scope`` prims, so muting
the layer removes them with the animation override), authored at the Sdf level:

* ``string gaze:attend:character`` (the SkelRoot's path: the scope's name alone cannot say whose it
  is, ``/A_B`` and ``/A/B`` both spell ``A_B``), ``point3f gaze:attend:pointOfSight`` (world, stage
  units) and ``float3 gaze:attend:eyePose`` (theta, psi in degrees, zeta in mm) per frame;
* one child per object: ``string gaze:attend:object`` (its prim path), ``point3f
  gaze:attend:estimate`` (world, stage units) and ``float gaze:attend:uncertainty`` (sigma_p, m^2),
  both NaN at frames where the character does not track the object.
"""

from __future__ import annotations

import re

import numpy as np
from pxr import Gf, Sdf

from usdgaze.core.names import unique

ROOT = "/UsdGazeAttend"
CHARACTER = "gaze:attend:character"
"""The SkelRoot path a character scope holds the inspection of (layers before it: none)."""


def scope_name(path: str) -> str:
    """The inspection scope's name for a character's or an object's prim path (``/root/Body`` ->
    ``root_Body``, ``/Pérsonnage`` -> ``P_rsonnage``), before it is made unique among its siblings."""
    base = re.sub(r"[^A-Za-z0-9_]", "_", path.strip("/").replace("/", "_")) or "object"
    return "_" + base if base[0].isdigit() else base


def _name(path: str, taken: set[str]) -> str:
    return unique(scope_name(path), taken)


def _attr(prim: Sdf.PrimSpec, name: str, type_name) -> Sdf.AttributeSpec:
    return Sdf.AttributeSpec(prim, name, type_name)


def _scope(layer: Sdf.Layer, path: str) -> Sdf.PrimSpec:
    prim = Sdf.CreatePrimInLayer(layer, path)
    prim.specifier = Sdf.SpecifierDef
    prim.typeName = "Scope"
    return prim


def add_inspection(layer: Sdf.Layer, character: str, times: np.ndarray, sight: np.ndarray, eye_pose: np.ndarray,
                   objects: list[str], estimates: np.ndarray, uncertainty: np.ndarray) -> str:
    """Author the inspection prims of one character; returns its prim path."""
    taken: set[str] = set()
    with Sdf.ChangeBlock():
        # Names already there are taken: /A_B and /A/B both spell A_B, and the second was authored
        # over the first (an Sdf error, exit 1).
        characters = {child.name for child in _scope(layer, ROOT).nameChildren}
        path = f"{ROOT}/{_name(character, characters)}"
        prim = _scope(layer, path)
        _attr(prim, CHARACTER, Sdf.ValueTypeNames.String).default = character
        pos = _attr(prim, "gaze:attend:pointOfSight", Sdf.ValueTypeNames.Point3f).path
        eye = _attr(prim, "gaze:attend:eyePose", Sdf.ValueTypeNames.Float3).path
        for t, p, e in zip(times, sight.astype(np.float32), eye_pose.astype(np.float32)):
            layer.SetTimeSample(pos, float(t), Gf.Vec3f(*map(float, p)))
            layer.SetTimeSample(eye, float(t), Gf.Vec3f(*map(float, e)))
        for j, obj in enumerate(objects):
            child = _scope(layer, f"{path}/{_name(obj, taken)}")
            _attr(child, "gaze:attend:object", Sdf.ValueTypeNames.String).default = obj
            est = _attr(child, "gaze:attend:estimate", Sdf.ValueTypeNames.Point3f).path
            unc = _attr(child, "gaze:attend:uncertainty", Sdf.ValueTypeNames.Float).path
            for t, p, u in zip(times, estimates[:, j].astype(np.float32), uncertainty[:, j].astype(np.float32)):
                layer.SetTimeSample(est, float(t), Gf.Vec3f(*map(float, p)))
                layer.SetTimeSample(unc, float(t), float(u))
    return path
