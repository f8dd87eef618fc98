"""Valid-but-unusual inputs found by a sweep (2026-12-07), each measured with UsdSkel's own forward
kinematics (tests/measure.py), never with usdgaze's numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import usdgaze  # noqa: F401  (registers GazeMapAPI and the validators before any stage is opened)
from pxr import Sdf, Usd, UsdSkel, UsdValidation, Vt

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



def _list_eyes_the_skeleton_lacks(rig: syn.Rig) -> list[str]:
    """Append to the animation the eye joints a fuller rig has under the head (this skeleton has none)."""
    stage = Usd.Stage.Open(str(rig.path))
    anim = UsdSkel.Animation(stage.GetPrimAtPath(rig.animation))
    eyes = [f"{rig.joint('head')}/LeftEye", f"{rig.joint('head')}/RightEye"]
    anim.GetJointsAttr().Set(Vt.TokenArray([str(j) for j in anim.GetJointsAttr().Get()] + eyes))
    rows = {"rotations": [[0.3, 0.0, 0.0, 0.954]] * 2, "translations": [[0.03, 0.08, 0.1], [-0.03, 0.08, 0.1]],
            "scales": [[1.0, 1.0, 1.0]] * 2}
    for name, extra in rows.items():
        attr = anim.GetPrim().GetAttribute(name)
        for t in attr.GetTimeSamples():
            value = attr.Get(t)
            block = np.asarray(value)
            attr.Set(type(value).FromNumpy(np.vstack([block, np.asarray(extra, dtype=block.dtype)])), t)
    stage.GetRootLayer().Save()
    return eyes


def test_added_eyes_do_not_take_the_path_of_eyes_the_animation_lists_for_a_fuller_rig(tmp_path):
    """The animation lists <head>/LeftEye and <head>/RightEye, which the skeleton lacks (UsdSkel ignores
    them); the eyes usdgaze added had those paths, so the layer's animation listed each twice (a file
    apply itself refuses: 'listed twice'). The added eyes take free names, look at the target by
    UsdSkel FK, and the listed ones are still written through."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=45, time_codes_per_second=30, joints=40, eyes=False, mesh=False)
    listed = _list_eyes_the_skeleton_lacks(rig)
    api.apply(rig.path, [], tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda",
              look_at=[",".join(map(str, TARGET)) + "@0.2s"])
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "gaze.usdc"))
    anim_joints = list(layer.GetAttributeAtPath(rig.animation + ".joints").default)
    skel_joints = list(layer.GetAttributeAtPath(rig.skeleton + ".joints").default)
    assert len(set(anim_joints)) == len(anim_joints)
    added = skel_joints[len(rig.joints):]
    assert len(added) == 2 and not set(added) & set(listed) and set(listed) <= set(anim_joints)
    p = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton)
    fwd = measure.character_forward_skel(p, rig.leaf["thigh_l"], rig.leaf["thigh_r"])
    left, right = (a.rsplit("/", 1)[-1] for a in added)
    line = measure.sight_line(p, left, right, measure.local_forward(p, left, fwd), measure.local_forward(p, right, fwd))
    to_target = np.asarray(TARGET)[None] - 0.5 * (p.position(left) + p.position(right))
    error = measure.angle_between(line, to_target / np.linalg.norm(to_target, axis=-1, keepdims=True))
    assert error[p.times >= 0.8 * 30].max() < 1.0
    api.apply(tmp_path / "preview.usda", ["0.5s:10:0"], tmp_path / "again.usdc")  # the result reads as an input
