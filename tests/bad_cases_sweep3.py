"""Catalogue builders for what the unusual-inputs sweep found (2026-12-07)."""

from __future__ import annotations

from pxr import Gf, Sdf, Vt

from .bad_common import apply_argv, edited, remove


def b_sparse_animation_without_rest_transforms(d):
    """No restTransforms, and the animation leaves one joint out: UsdSkel poses nothing (0 joint
    transforms), and a layer over it posed nothing either, while apply said it was written."""
    def bare(layer, rig):
        remove(layer, rig.skeleton + ".restTransforms")
    return apply_argv(d, edited(d, bare, unanimated=("spine_b",)))


def b_physics_skelroot_squashed(d):
    """A SkelRoot scaled (1, 1.2, 1): rigid bodies cannot follow the squash (the model's joints were
    10-15 cm from UsdSkel's as they turned, exit 0)."""
    def squash(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "xformOp:scale", Sdf.ValueTypeNames.Float3).default = Gf.Vec3f(1.0, 1.2, 1.0)
        Sdf.AttributeSpec(root, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:scale"])
    return ["physics-model", str(edited(d, squash)), "--out", str(d / "body.xml")]
