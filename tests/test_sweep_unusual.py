"""Valid-but-unusual inputs found by a sweep (2026-12-07), each measured with UsdSkel's own forward
kinematics (tests/measure.py), never with usdgaze's numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import usdgaze  # noqa: F401  (registers GazeMapAPI and the validators before any stage is opened)
from pxr import Sdf, Usd, UsdSkel, UsdValidation

from usdgaze import api
from usdgaze.errors import UsdGazeError
from usdgaze.review import validators

from . import measure
from . import synthetic as syn

TARGET = (1.0, 1.5, 2.0)  # metres, ahead-left of a Y-up rig facing +Z


def _without_rest(path: Path) -> None:
    layer = Sdf.Layer.FindOrOpen(str(path))
    skel = layer.GetPrimAtPath("/Character/Skel")
    skel.RemoveProperty(skel.attributes["restTransforms"])
    layer.Save()


def _joint_count(path: Path) -> int:
    """How many joints UsdSkel poses at time code 10 (0 where it cannot compute the skeleton)."""
    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/Character")), Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/Character/Skel")))
    return len(query.ComputeJointSkelTransforms(Usd.TimeCode(10.0)))


def _ours(path: Path) -> list[str]:
    registry = UsdValidation.ValidationRegistry()
    ctx = UsdValidation.ValidationContext([registry.GetOrLoadValidatorByName(n) for n in validators.names()])
    return [e.GetName() for e in ctx.Validate(Usd.Stage.Open(str(path)), Usd.PrimAllPrimsPredicate)]


def test_a_sparse_animation_without_rest_transforms_is_refused_and_flagged(tmp_path):
    """UsdSkel poses nothing of such a skeleton; apply wrote a layer over it that posed nothing
    either, and said it was written, and validate was silent."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=30, time_codes_per_second=30, joints=80, unanimated=("prop",),
                       mesh=False)
    _without_rest(rig.path)
    assert _joint_count(rig.path) == 0  # the premise, by UsdSkel itself
    with pytest.raises(UsdGazeError, match=r"/Character/Skel\.restTransforms: not authored, and /Character/Anim "
                                           r"leaves 1 of the skeleton's 80 joints out .*Prop000"):
        api.apply(rig.path, ["0.2s:30:0"], tmp_path / "gaze.usdc")
    assert not (tmp_path / "gaze.usdc").exists()
    assert "SparseWithoutRest" in _ours(rig.path)


def test_a_full_animation_without_rest_transforms_looks_where_asked(tmp_path):
    """No restTransforms is fine where the animation lists every joint (UsdSkel needs none then):
    the added eyes land on the target by UsdSkel FK and muting the layer gives the input back."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=45, time_codes_per_second=30, joints=40, eyes=False, mesh=False)
    _without_rest(rig.path)
    assert _joint_count(rig.path) == len(rig.joints)
    api.apply(rig.path, [], tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda",
              look_at=[",".join(map(str, TARGET)) + "@0.2s"])
    assert not _ours(tmp_path / "preview.usda")
    p = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton)
    fwd = measure.character_forward_skel(p, rig.leaf["thigh_l"], rig.leaf["thigh_r"])
    left, right = rig.eye_leaves
    line = measure.sight_line(p, left, right, measure.local_forward(p, left, fwd), measure.local_forward(p, right, fwd))
    to_target = np.asarray(TARGET)[None] - 0.5 * (p.position(left) + p.position(right))
    error = measure.angle_between(line, to_target / np.linalg.norm(to_target, axis=-1, keepdims=True))
    settled = p.times >= 0.8 * 30
    assert error[settled].max() < 1.0, error[settled]
    base = measure.posed(str(rig.path), rig.skeleton)
    muted = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton, mute=[str(tmp_path / "gaze.usdc")])
    assert np.array_equal(base.world, muted.world)

