"""Catalogue builders for what the unusual-inputs sweep found (2026-12-07)."""

from __future__ import annotations

from .bad_common import apply_argv, edited, remove


def b_sparse_animation_without_rest_transforms(d):
    """No restTransforms, and the animation leaves one joint out: UsdSkel poses nothing (0 joint
    transforms), and a layer over it posed nothing either, while apply said it was written."""
    def bare(layer, rig):
        remove(layer, rig.skeleton + ".restTransforms")
    return apply_argv(d, edited(d, bare, unanimated=("spine_b",)))
