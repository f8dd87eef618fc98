"""``jointNames`` that spell each joint's path, as some DCCs write them, bind by their last element.

An audit found: with joint tokens that say nothing (``j0/j1/...``) and ``jointNames`` holding Maya's
DAG paths (``|Character|mixamorig:Hips|mixamorig:Spine|...``) or slash paths (``mixamorig:Hips/...``),
each name was read whole, so the head's was every word of the spine, no chain was found and ``apply``
refused a rig whose plain names bind. A name whose leading elements are not its ancestors' names
(``L/Hand`` under ``Arm``) is still read whole.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.core.hints import BindHints
from usdgaze.core.names import spelled_with_names
from usdgaze.passes.options import PassOptions

from . import measure
from . import synthetic as syn


def _dag(path: list[str]) -> str:
    return "|Character|" + "|".join(path)


def _slash(path: list[str]) -> str:
    return "/".join(path)


def _last_two(path: list[str]) -> str:
    return "|".join(path[-2:])


def _numbered(rig: syn.Rig, layer: Sdf.Layer) -> dict[str, str]:
    """Give the rig's Skeleton and SkelAnimation joint tokens that say nothing (``j0/j3/...``); the
    token of each joint path."""
    token = {j: "/".join(f"j{rig.joints.index('/'.join(j.split('/')[:k]))}" for k in range(1, j.count("/") + 2))
             for j in rig.joints}
    for prim in (rig.skeleton, rig.animation):
        spec = layer.GetAttributeAtPath(f"{prim}.joints")
        spec.default = [token[str(j)] for j in spec.default]
    return token


def _held_change(tmp_path, rig: syn.Rig, token: dict[str, str], report) -> np.ndarray:
    """The line of sight's change (yaw, pitch) by UsdSkel FK of the preview, over the frames after the
    shift settled."""
    leaf = lambda key: token[rig.joint(key)].rsplit("/", 1)[-1]  # noqa: E731
    base = measure.posed(str(rig.path), rig.skeleton)
    new = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton)
    change, _, _ = measure.gaze_change(base, new, rig.forward, leaf("head"), (leaf("eye_l"), leaf("eye_r")))
    s = report.characters[0].result.shift_timing[0]
    hold = base.times >= rig.start_time + (s["time_s"] + s["duration"]) * rig.time_codes_per_second + 1
    assert hold.sum() > 30
    return change[hold]


@pytest.mark.parametrize("spell", [_dag, _slash, _last_two])
def test_path_spelled_joint_names_bind_and_hold_the_request_by_usdskel_fk(tmp_path, spell):
    rig = syn.make_rig(tmp_path / "in.usda", frames=90, mesh=False, time_codes_per_second=30)
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    names = list(layer.GetAttributeAtPath(f"{rig.skeleton}.jointNames").default)
    own = dict(zip(rig.joints, names))
    token = _numbered(rig, layer)
    chain_names = {j: [own["/".join(j.split("/")[:k])] for k in range(1, j.count("/") + 2)] for j in rig.joints}
    layer.GetAttributeAtPath(f"{rig.skeleton}.jointNames").default = [spell(chain_names[j]) for j in rig.joints]
    layer.Save()

    report = api.apply(rig.path, ["0.5s:40:0"], tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda")
    chain = report.characters[0].chain
    assert chain["head"] == [token[rig.joint("head")]] and chain["pelvis"] == [token[rig.joint("pelvis")]]
    assert np.abs(_held_change(tmp_path, rig, token, report) - [40.0, 0.0]).max() <= 0.5


def test_a_name_whose_leading_elements_are_not_its_ancestors_is_read_whole():
    joints = ["a", "a/b", "a/b/c"]
    parents = [-1, 0, 1]
    assert spelled_with_names(joints, parents, ["Hips", "Arm", "L/Hand"]) == ["Hips", "Hips/Arm", "Hips/Arm/L_Hand"]
    assert spelled_with_names(joints, parents, ["|grp|Hips", "Hips|Arm", "Arm|Hand"]) == ["Hips", "Hips/Arm", "Hips/Arm/Hand"]


def test_a_binding_by_token_on_a_rig_bound_by_its_joint_names(tmp_path):
    """A rig whose tokens say nothing binds by its jointNames; a ``--bind`` naming a joint by its token
    (``head=j5``, as ``usdgaze inspect`` lists the joints) was looked for among the names alone, and
    the rig that bound without it was refused with it ('no pelvis above head j5')."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=90, mesh=False, time_codes_per_second=30)
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    token = _numbered(rig, layer)
    layer.Save()
    head, neck = token[rig.joint("head")], token[rig.joint("neck")]
    for role, joint in (("head", head.rsplit("/", 1)[-1]), ("neck", neck), ("head", "mixamorig:Head")):
        options = PassOptions(binding=BindHints(bindings=((role, (joint,)),)))
        report = api.apply(rig.path, ["0.5s:40:0"], tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda",
                           options=options)
        chain = report.characters[0].chain
        assert chain["head"] == [head] and chain["neck"] == [neck], (role, joint, chain)
        assert np.abs(_held_change(tmp_path, rig, token, report) - [40.0, 0.0]).max() <= 0.5
