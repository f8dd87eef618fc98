"""``usdgaze validate`` says what ``apply``, ``plot`` and ``preview`` refuse: a layer made for another
take (its animation named for that take), an animation array left unauthored, a joint token that is no
path. Each is one error line on real stages built here; what they accept stays clean."""

from __future__ import annotations

from pathlib import Path

import pytest
from pxr import Usd, UsdSkel

from usdgaze import api
from usdgaze.console.main import main

from . import synthetic as syn

ROOT = Path(__file__).resolve().parents[1]
TAKE_1, TAKE_2 = (ROOT / "sample_stages" / "cmu" / f"cmu_131_0{k}.usdc" for k in (1, 2))


def test_a_layer_for_another_take_with_its_own_animation_name_is_flagged_as_plot_refuses_it(tmp_path, capsys):
    layer = tmp_path / "L.usdc"
    api.apply(TAKE_1, ["2s:30:0"], layer)
    capsys.readouterr()
    assert main(["plot", str(TAKE_2), "--layer", str(layer), "--out", str(tmp_path / "p.png")]) == 2
    assert "overrides no SkelAnimation of" in capsys.readouterr().err
    assert main(["validate", str(TAKE_2), "--layer", str(layer)]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    assert line.startswith(f"{TAKE_2}:/: error: L.usdc: overrides no SkelAnimation of {TAKE_2};"), line
    assert line.endswith("(usdgaze.review.validators:GazeLayerSchedule.OtherTake)") and "anon:" not in line
    assert main(["validate", str(TAKE_1), "--layer", str(layer)]) == 0  # over its own take: clean
    assert capsys.readouterr() == ("", "")


def _rig(tmp_path: Path, name: str) -> tuple[syn.Rig, Usd.Stage]:
    r = syn.make_rig(tmp_path / f"{name}.usda", frames=20, mesh=False)
    return r, Usd.Stage.Open(str(r.path))


def _refused_by_apply_and_validate(r: syn.Rig, stage: Usd.Stage, capsys) -> tuple[str, list[str]]:
    """(apply's one-line refusal, validate's lines), after saving ``stage``: apply exits 2, validate 3."""
    stage.GetRootLayer().Save()
    capsys.readouterr()
    assert main(["apply", str(r.path), "--shift", "0.1s:20:0", "--out", str(r.path.with_suffix(".out.usdc"))]) == 2
    (refusal,) = capsys.readouterr().err.strip().splitlines()
    assert main(["validate", str(r.path)]) == 3
    return refusal, capsys.readouterr().out.splitlines()


@pytest.mark.parametrize("removed", [("translations", "scales"), ("scales",)])
def test_an_animation_without_translations_or_scales_is_flagged_as_apply_refuses_it(tmp_path, capsys, removed):
    r, stage = _rig(tmp_path, "anim")
    anim = UsdSkel.Animation(stage.GetPrimAtPath(r.animation))
    for name in removed:
        anim.GetPrim().RemoveProperty(name)
    assert len(UsdSkel.Cache().GetAnimQuery(anim).ComputeJointLocalTransforms(1.0)) == 0  # UsdSkel poses nothing
    refusal, lines = _refused_by_apply_and_validate(r, stage, capsys)
    assert f"{r.animation}.{removed[0]}: not authored (" in refusal
    why = refusal.split(": not authored ", 1)[1]
    assert lines == [f"{r.path}:{r.animation}.{name}: error: {name}: not authored {why} "
                     "(usdgaze.review.validators:AnimationArrays.NotAuthored)" for name in sorted(removed)]


@pytest.mark.parametrize("bad", ["mixamorig:Hips", "Spine.001"])
def test_ill_formed_joint_tokens_are_flagged_as_apply_refuses_them(tmp_path, capsys, bad):
    r, stage = _rig(tmp_path, "joints")
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(r.skeleton))
    joints = [str(j) for j in skel.GetJointsAttr().Get()]
    k = 0 if ":" in bad else 1  # a root ('mixamorig:Hips'), or a child ('Hips/Spine.001')
    old = joints[k]
    new = bad if k == 0 else f"{old.rsplit('/', 1)[0]}/{bad}"
    renamed = [new + j[len(old):] if j == old or j.startswith(old + "/") else j for j in joints]
    skel.GetJointsAttr().Set(renamed)
    anim = UsdSkel.Animation(stage.GetPrimAtPath(r.animation))
    anim.GetJointsAttr().Set([renamed[joints.index(j)] if j in joints else j for j in anim.GetJointsAttr().Get()])
    refusal, (line,) = _refused_by_apply_and_validate(r, stage, capsys)
    problem = refusal.split(f"{r.skeleton}.joints: ", 1)[1]
    assert problem.startswith(f"'{new}' is not a valid joint path")
    below = sum(1 for j in renamed if j == new or j.startswith(new + "/"))
    assert line == (f"{r.path}:{r.skeleton}.joints: error: joints: {problem}; {below} of the skeleton's {len(joints)} "
                    "joints are ill-formed (usdgaze.review.validators:SkeletonArrays.IllFormedJoint)")


def test_scales_authored_as_a_default_only_stay_clean_for_apply_and_validate(tmp_path, capsys):
    r, stage = _rig(tmp_path, "still_scales")
    scales = UsdSkel.Animation(stage.GetPrimAtPath(r.animation)).GetScalesAttr()
    value = scales.Get(scales.GetTimeSamples()[0])
    scales.Clear()
    scales.Set(value)
    stage.GetRootLayer().Save()
    assert scales.GetNumTimeSamples() == 0 and scales.HasAuthoredValue()
    capsys.readouterr()
    assert main(["apply", str(r.path), "--shift", "0.1s:20:0", "--out", str(tmp_path / "out.usdc")]) == 0
    capsys.readouterr()
    assert main(["validate", str(r.path), "--only-usdgaze"]) == 0
    assert capsys.readouterr().out == ""
