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


def _broken_override(tmp_path: Path, capsys) -> tuple[syn.Rig, Path, int]:
    """A rig, apply's layer for it, and that layer's rotations broken at the Sdf level: a short array
    at the 5th sample, NaN at the 6th and 8th (the input below it stays sound). Returns the layer's
    sample count too."""
    from pxr import Gf, Sdf, Vt

    r = syn.make_rig(tmp_path / "in.usda", frames=20, mesh=False)
    out = tmp_path / "in_gaze.usda"
    assert main(["apply", str(r.path), "--shift", "0.1s:20:0", "--out", str(out)]) == 0
    capsys.readouterr()
    layer = Sdf.Layer.FindOrOpen(str(out))
    path = Sdf.Path(r.animation).AppendProperty("rotations")
    times = layer.ListTimeSamplesForPath(path)
    layer.SetTimeSample(path, times[5], Vt.QuatfArray(list(layer.QueryTimeSample(path, times[5]))[:-2]))
    for t in (times[6], times[8]):
        v = list(layer.QueryTimeSample(path, t))
        v[0] = Gf.Quatf(float("nan"), 0, 0, 0)
        layer.SetTimeSample(path, t, Vt.QuatfArray(v))
    layer.Save()
    return r, out, len(times)


def test_each_kind_of_bad_sample_is_one_line_naming_the_layer_that_authored_it(tmp_path, capsys):
    """A wrong length at one time and NaN at two others: two lines, not the first alone; each names
    the override layer (which holds the bad samples), not the input, as FILE; apply on a stage that
    sublayers them refuses the same array."""
    r, out, count = _broken_override(tmp_path, capsys)
    n = len(r.anim_joints)
    assert main(["validate", str(r.path), "--layer", str(out), "--only-usdgaze"]) == 3
    lines = capsys.readouterr().out.splitlines()
    where = f"{out}:{r.animation}.rotations: error: rotations:"
    assert lines == [f"{where} {n - 2} entries at time {r.times[5]:g}, expected {n} (one per joint); 1 of {count} samples "
                     "(usdgaze.review.validators:AnimationArrays.Length)",
                     f"{where} NaN or infinite values at time {r.times[6]:g}; 2 of {count} samples "
                     "(usdgaze.review.validators:AnimationArrays.NotFinite)"]
    shot = tmp_path / "shot.usda"  # the same layers as a shot's sublayers: FILE is still the layer
    stage = Usd.Stage.CreateNew(str(shot))
    stage.GetRootLayer().subLayerPaths = [str(out), str(r.path)]
    for key in ("timeCodesPerSecond", "framesPerSecond", "upAxis", "metersPerUnit"):
        stage.GetRootLayer().pseudoRoot.SetInfo(key, Usd.Stage.Open(str(r.path)).GetRootLayer().pseudoRoot.GetInfo(key))
    stage.GetRootLayer().Save()
    assert main(["validate", str(shot), "--only-usdgaze"]) == 3
    assert [line.split(":", 1)[0] for line in capsys.readouterr().out.splitlines()] == [str(out), str(out)]
    assert main(["apply", str(shot), "--shift", "0.1s:20:0", "--out", str(tmp_path / "again.usdc")]) == 2
    assert f"{r.animation}.rotations: {n - 2} entries at time {r.times[5]:g}" in capsys.readouterr().err


def _wrong_typed_map(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """A map file (dump-map's) with two attributes re-authored in other types: name -> the type
    authored, as Sdf.ValueTypeNames spells it."""
    from pxr import Sdf

    from usdgaze.gaze.defaults import default_definition
    from usdgaze.usd.schema import dump_map

    path = tmp_path / "map.usda"
    dump_map(default_definition(), path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    prim = layer.GetPrimAtPath("/GazeMap")
    retyped = {"gaze:synthesis:blendSize": (Sdf.ValueTypeNames.String, "six"),
               "gaze:examples:yaw": (Sdf.ValueTypeNames.DoubleArray, list(prim.attributes["gaze:examples:yaw"].default))}
    for name, (type_name, value) in retyped.items():
        prim.RemoveProperty(prim.attributes[name])
        Sdf.AttributeSpec(prim, name, type_name, Sdf.VariabilityUniform).default = value
    layer.Save()
    return path, {name: str(type_name) for name, (type_name, _) in retyped.items()}


def test_a_wrong_typed_attribute_is_one_line_spelling_types_as_usd_does(tmp_path, capsys):
    """OpenUSD's AttributeTypeMismatch (sited on the layer, printed at '/') and usdgaze's WrongType both
    caught each attribute: one line each now, usdgaze's (prim and attribute named), the authored type
    spelled as Sdf.ValueTypeNames does, as apply's refusal spells it."""
    path, authored = _wrong_typed_map(tmp_path)
    capsys.readouterr()
    assert main(["validate", str(path)]) == 3
    lines = capsys.readouterr().out.splitlines()
    for name, type_name in authored.items():
        (line,) = [x for x in lines if name in x]
        assert line.startswith(f"{path}:/GazeMap.{name}: error: {name}: authored as {type_name}, expected "), line
        assert line.endswith("GazeMapArrays.WrongType)")
    assert not any("AttributeTypeMismatch" in x for x in lines), lines
    r = syn.make_rig(tmp_path / "rig.usda", frames=20, mesh=False)
    assert main(["apply", str(r.path), "--map", str(path), "--shift", "0.1s:20:0", "--out", str(tmp_path / "o.usdc")]) == 2
    assert f"authored as {authored['gaze:examples:yaw']}" in capsys.readouterr().err


def test_usds_type_mismatch_stays_where_usdgaze_says_nothing(tmp_path, capsys):
    """Only a duplicate is dropped: a wrong-typed attribute of another schema (a Sphere's radius
    authored as float, its schema's is double) is still USD's line."""
    from pxr import Sdf

    path = tmp_path / "ball.usda"
    layer = Sdf.Layer.CreateNew(str(path))
    layer.ImportFromString('#usda 1.0\n(\n    defaultPrim = "Ball"\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n'
                           'def Sphere "Ball"\n{\n    float radius = 2\n}\n')
    layer.Save()
    capsys.readouterr()
    assert main(["validate", str(path)]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    assert "AttributeTypeMismatch" in line and "</Ball.radius>" in line, line


def _edit_knee(r: syn.Rig, frame: int) -> float:
    """Turn the left knee (a joint no gaze chain drives) a little at one frame of the input, at the Sdf
    level, as a later edit of the take would; returns that time code."""
    from pxr import Gf, Sdf, Vt

    layer = Sdf.Layer.FindOrOpen(str(r.path))
    path = Sdf.Path(r.animation).AppendProperty("rotations")
    t = layer.ListTimeSamplesForPath(path)[frame]
    v = list(layer.QueryTimeSample(path, t))
    k = r.anim_joints.index(r.joint("knee_l"))
    v[k] = (Gf.Quatf(v[k]) * Gf.Quatf(0.9961947, 0.0871557, 0.0, 0.0)).GetNormalized()  # 10 deg more bend
    layer.SetTimeSample(path, t, Vt.QuatfArray(v))
    layer.Save()
    return t


def test_a_layer_made_before_the_input_was_edited_is_flagged_by_validate_and_plot(tmp_path, capsys):
    """apply writes every joint's rotations; composed over the edited input the layer plays the old
    knee. validate says which joint differs and when (exit 3), plot draws it with a warning saying so;
    the layer made again over the edited input is clean."""
    r = syn.make_rig(tmp_path / "in.usda", frames=24, time_codes_per_second=24, mesh=False)
    old = tmp_path / "old.usda"
    assert main(["apply", str(r.path), "--shift", "0.2s:30:0", "--out", str(old)]) == 0
    t = _edit_knee(r, 17)
    capsys.readouterr()
    assert main(["validate", str(r.path), "--layer", str(old), "--only-usdgaze"]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    assert f"old.usda: the layer was made from another version of the input: joint '{r.leaf['knee_l']}' of " \
           f"{r.animation} differs at time code {t:g} (rotations;" in line and line.endswith("GazeLayerSchedule.OtherVersion)")
    assert main(["plot", str(r.path), "--layer", str(old), "--out", str(tmp_path / "plots")]) == 0
    (warning,) = [w for w in capsys.readouterr().err.splitlines() if w.startswith("usdgaze: warning:")]
    assert f"joint '{r.leaf['knee_l']}'" in warning and f"time code {t:g}" in warning
    assert main(["apply", str(r.path), "--shift", "0.2s:30:0", "--out", str(tmp_path / "new.usda")]) == 0
    capsys.readouterr()
    assert main(["validate", str(r.path), "--layer", str(tmp_path / "new.usda"), "--only-usdgaze"]) == 0


def test_a_layer_for_another_take_of_the_same_span_is_flagged(tmp_path, capsys):
    """Same animation path, same time codes, another motion (another seed and turn): the span check
    (OtherTake) found nothing and plot drew a gaze the request never asked for."""
    a = syn.make_rig(tmp_path / "a.usda", frames=24, time_codes_per_second=24, mesh=False)
    b = syn.make_rig(tmp_path / "b.usda", frames=24, time_codes_per_second=24, mesh=False, seed=3, turn_deg_per_s=40.0)
    assert main(["apply", str(a.path), "--shift", "0.2s:30:0", "--out", str(tmp_path / "a_gaze.usda")]) == 0
    capsys.readouterr()
    assert main(["validate", str(b.path), "--layer", str(tmp_path / "a_gaze.usda"), "--only-usdgaze"]) == 3
    (line,) = capsys.readouterr().out.splitlines()
    assert "a_gaze.usda: the layer was made from another version of the input" in line


def test_layers_of_apply_attend_physics_and_batch_are_clean_over_their_input(tmp_path, capsys):
    """No joint the chain does not drive differs in what apply, attend and batch write; attend
    --physics moves every joint, so an edit of its input is not called another version (its record's
    command says what it was)."""
    from .test_attend_binding import _scene

    r = syn.make_rig(tmp_path / "in.usda", frames=12, time_codes_per_second=24, mesh=False)
    scene, _ = _scene(tmp_path, r)
    (tmp_path / "m.toml").write_text(f'[[job]]\nname = "s"\ninput = "{r.path}"\nout = "{tmp_path / "b.usdc"}"\n'
                                     'shifts = ["0.2s:30:0"]\n')
    runs = {"a.usda": (r.path, ["apply", str(r.path), "--shift", "0.2s:30:0"]),
            "t.usda": (scene, ["attend", str(scene), "--window", "0.3"]),
            "p.usda": (scene, ["attend", str(scene), "--physics", "--window", "0.1"])}
    for name, (source, argv) in runs.items():
        assert main([*argv, "--out", str(tmp_path / name)]) == 0
    assert main(["batch", str(tmp_path / "m.toml")]) == 0
    runs["b.usdc"] = (r.path, [])
    capsys.readouterr()
    for name, (source, _) in runs.items():
        assert main(["validate", str(source), "--layer", str(tmp_path / name), "--only-usdgaze"]) == 0, name
    assert capsys.readouterr().out == ""
    _edit_knee(r, 5)
    assert main(["validate", str(scene), "--layer", str(tmp_path / "p.usda"), "--only-usdgaze"]) == 0
    assert main(["validate", str(scene), "--layer", str(tmp_path / "t.usda"), "--only-usdgaze"]) == 3


def _animation_in_an_instance(d: Path) -> tuple[Path, list[str]]:
    """/Character binds the animation of /Library/Take, an instanceable copy of the character: the
    skeleton is overridable, its animation is an instance proxy. (stage, apply's extra options)."""
    from .bad_common import rig

    r = rig(d, "char.usda")
    skel, anim = r.skeleton[len(r.skel_root) + 1:], r.animation[len(r.skel_root):]
    (d / "in.usda").write_text(
        '#usda 1.0\n(\n    timeCodesPerSecond = 60\n    upAxis = "Y"\n    metersPerUnit = 1\n)\n\n'
        f'def "Character" (\n    references = @./char.usda@<{r.skel_root}>\n)\n{{\n'
        f'    over "{skel}"\n    {{\n        rel skel:animationSource = </Library/Take{anim}>\n    }}\n}}\n\n'
        f'def "Library"\n{{\n    def "Take" (\n        instanceable = true\n'
        f'        references = @./char.usda@<{r.skel_root}>\n    )\n    {{\n    }}\n}}\n')
    return d / "in.usda", ["--skel-root", "/Character"]


def _instanced_case(d: Path, case: str) -> tuple[Path, list[str]]:
    from . import bad_cases_stage as b

    if case == "animation":
        return _animation_in_an_instance(d)
    argv = getattr(b, f"b_{case}")(d)  # the catalogue's stages (docs/bad-inputs.md)
    return Path(argv[1]), []


@pytest.mark.parametrize("case", ["instanceable_skelroot", "character_inside_an_instance", "animation"])
def test_a_skeleton_or_animation_inside_an_instance_is_flagged_as_apply_refuses_it(tmp_path, capsys, case):
    """apply refuses a Skeleton (or its bound SkelAnimation) that is an instance proxy: no override can
    reach it. validate walked no instance proxy and said nothing (exit 0); now it says apply's words,
    sited where apply's line is."""
    stage, extra = _instanced_case(tmp_path, case)
    capsys.readouterr()
    assert main(["apply", str(stage), *extra, "--shift", "0.1s:20:0", "--out", str(tmp_path / "g.usdc")]) == 2
    (refusal,) = capsys.readouterr().err.strip().splitlines()
    site, problem = refusal.removeprefix(f"usdgaze: error: {stage}:").split(": ", 1)
    assert problem.startswith("is inside the instance /"), refusal
    assert not (tmp_path / "g.usdc").exists()
    assert main(["validate", str(stage), "--only-usdgaze"]) == 3
    lines = capsys.readouterr().out.splitlines()
    assert f"{stage}:{site}: error: {problem} (usdgaze.review.validators:SkeletonInstances.Instanced)" in lines, lines
    assert all(line.endswith("SkeletonInstances.Instanced)") for line in lines), lines


def test_instances_that_hold_no_character_stay_clean(tmp_path, capsys):
    """An instanceable prop beside a character apply takes is no refusal: validate stays clean."""
    r = syn.make_rig(tmp_path / "in.usda", frames=20, mesh=False)
    (tmp_path / "prop.usda").write_text('#usda 1.0\n\ndef Xform "Prop"\n{\n    def Sphere "Ball"\n    {\n    }\n}\n')
    layer = Usd.Stage.Open(str(r.path))
    prop = layer.DefinePrim("/Props/Rock")
    prop.GetReferences().AddReference("./prop.usda", "/Prop")
    prop.SetInstanceable(True)
    layer.GetRootLayer().Save()
    assert Usd.Stage.Open(str(r.path)).GetPrimAtPath("/Props/Rock/Ball").IsInstanceProxy()
    capsys.readouterr()
    assert main(["apply", str(r.path), "--shift", "0.1s:20:0", "--out", str(tmp_path / "g.usdc")]) == 0
    capsys.readouterr()
    assert main(["validate", str(r.path), "--only-usdgaze"]) == 0
    assert capsys.readouterr().out == ""


def test_the_preview_root_as_layer_is_refused_alike_by_validate_plot_and_preview(tmp_path, capsys):
    """The root ``apply --preview`` writes holds no prims: plot and preview found nothing it overrides
    and refused it, while validate composed it over the input (the input twice) and said clean. All
    three now refuse it in one line naming the override to pass; that override, and the root opened
    as the stage, stay clean."""
    r = syn.make_rig(tmp_path / "in.usda", frames=20, mesh=False)
    out, root = tmp_path / "gaze.usdc", tmp_path / "p.usda"
    assert main(["apply", str(r.path), "--shift", "0.1s:20:0", "--out", str(out), "--preview", str(root)]) == 0
    capsys.readouterr()
    said = set()
    for argv in (["validate", str(r.path), "--layer", str(root), "--only-usdgaze"],
                 ["plot", str(r.path), "--layer", str(root), "--out", str(tmp_path / "plots")],
                 ["preview", str(r.path), "--layer", str(root), "--out", str(tmp_path / "p.png")]):
        assert main(argv) == 2, argv
        (line,) = capsys.readouterr().err.splitlines()
        said.add(line)
    assert said == {f"usdgaze: error: {root}: --layer names a root --preview wrote (it sublayers the override and "
                    f"the input), not an override; pass --layer {out}, the layer apply or attend wrote with --out"}
    assert not (tmp_path / "plots").exists() and not (tmp_path / "p.png").exists()
    assert main(["validate", str(r.path), "--layer", str(out), "--only-usdgaze"]) == 0
    assert main(["validate", str(root), "--only-usdgaze"]) == 0
    assert capsys.readouterr().out == ""
