"""Review guides in the override layer: each eye's line of sight and the point of sight, per frame.

Under each Skeleton the layer defines ``gazeGuides`` (a Scope) holding one guide-purpose
BasisCurves per eye (a two-point line from the eye to the point of sight, time-sampled, in the
Skeleton's space, so it follows the character's transform) and a time-sampled
``gaze:pointOfSight`` (point3d, world space, stage units) on the Scope. Guide purpose keeps them
out of renders; usdview shows them with "Display Guide" on. Authored at the Sdf level; call it
inside the writer's ``Sdf.ChangeBlock``.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Vt

from usdgaze.usd.layers import set_rows

SCOPE = "gazeGuides"
POINT_OF_SIGHT = "gaze:pointOfSight"
EYE_CURVES = ("leftEyeSight", "rightEyeSight")
_T = Sdf.ValueTypeNames


def _attr(prim: Sdf.PrimSpec, name: str, type_name, uniform: bool = False) -> Sdf.AttributeSpec:
    return Sdf.AttributeSpec(prim, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)


def _define(layer: Sdf.Layer, path: Sdf.Path, type_name: str) -> Sdf.PrimSpec:
    prim = Sdf.CreatePrimInLayer(layer, path)
    prim.specifier = Sdf.SpecifierDef
    prim.typeName = type_name
    return prim


def guide_path(skeleton: str) -> Sdf.Path:
    return Sdf.Path(skeleton).AppendChild(SCOPE)


def line_width(meters: float, meters_per_unit: float, skel_to_world: np.ndarray) -> float:
    """``meters`` as a curve width in skeleton units. The curves live in skeleton space, so the
    skeleton's world scale scales their width too: a metre character referenced 100x into a
    centimetre shot drew 3 mm lines 30 cm wide. The median over frames where the scale is animated."""
    scale = float(np.median(np.abs(np.linalg.det(np.asarray(skel_to_world)[..., :3, :3])) ** (1.0 / 3.0)))
    return meters / meters_per_unit / (scale if scale > 0 else 1.0)


def author_guides(layer: Sdf.Layer, skeleton: str, times: np.ndarray, eyes_skel: np.ndarray,
                  sight_skel: np.ndarray, sight_world: np.ndarray, width: float) -> None:
    """Author the guides for one skeleton: ``eyes_skel (2, F, 3)`` and ``sight_skel (F, 3)`` in
    skeleton space, ``sight_world (F, 3)`` in world space, lines ``width`` stage units wide."""
    codes = np.asarray(times, dtype=float).tolist()  # the same floats as float(t), without a numpy scalar per frame
    scope = _define(layer, guide_path(skeleton), "Scope")
    pos_attr = _attr(scope, POINT_OF_SIGHT, _T.Point3d)
    pos_attr.SetInfo("documentation", "World point both eyes fixate, per frame (stage units); written by usdgaze for review.")
    for name, eye in zip(EYE_CURVES, eyes_skel):
        curve = _define(layer, scope.path.AppendChild(name), "BasisCurves")
        _attr(curve, "purpose", _T.Token, uniform=True).default = "guide"
        _attr(curve, "type", _T.Token, uniform=True).default = "linear"
        _attr(curve, "curveVertexCounts", _T.IntArray).default = Vt.IntArray([2])
        _attr(curve, "widths", _T.FloatArray).default = Vt.FloatArray([float(width)])
        curve.attributes["widths"].SetInfo("interpolation", "constant")
        _attr(curve, "primvars:displayColor", _T.Color3fArray).default = Vt.Vec3fArray(
            [(0.1, 0.9, 0.2) if name == EYE_CURVES[0] else (0.9, 0.2, 0.1)])
        curve.attributes["primvars:displayColor"].SetInfo("interpolation", "constant")
        points = _attr(curve, "points", _T.Point3fArray)
        extent = _attr(curve, "extent", _T.Float3Array)
        lines = np.stack([eye, sight_skel], axis=1).astype(np.float32)  # (F, 2, 3)
        # The extent holds the whole drawn line, as UsdGeom.Curves.ComputeExtent pads it: half a width.
        half = np.float32(width) / np.float32(2.0)
        bounds = np.stack([lines.min(axis=1) - half, lines.max(axis=1) + half], axis=1)  # (F, 2, 3)
        set_rows(layer, points.path, codes, lines, Vt.Vec3fArray)
        set_rows(layer, extent.path, codes, bounds, Vt.Vec3fArray)
    set_sample, path = layer.SetTimeSample, pos_attr.path
    # Gf.Vec3d values straight from one Vt array: a tuple per frame would be cast by Sdf, 3x slower.
    for t, point in zip(codes, Vt.Vec3dArray.FromNumpy(np.ascontiguousarray(sight_world, dtype=np.float64))):
        set_sample(path, t, point)

