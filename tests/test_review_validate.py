"""usdgaze's UsdValidation validators: each catches its malformation, all pass on the sample stages,
they load through the plugin path in a process that never imports usdgaze, and ``usdgaze validate``
reports like a linter."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdValidation, Vt

from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review import validators
from usdgaze.usd.plugin import plugin_dir

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = [ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc", ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc",
           ROOT / "sample_stages" / "shared_map" / "crowd.usda", ROOT / "sample_stages" / "shared_map" / "gaze_map.usda",
           *sorted((ROOT / "sample_stages" / "attend").glob("*.usd*"))]
CROWD = SAMPLES[2]
MAP_PRIM = "/Crowd/CrowdA/Body"


def _ours(stage) -> list:
    registry = UsdValidation.ValidationRegistry()
    ctx = UsdValidation.ValidationContext([registry.GetOrLoadValidatorByName(n) for n in validators.names()])
    return [(e.GetValidator().GetMetadata().name.split(":")[1], e.GetName(),
             str(e.GetSites()[0].GetProperty().GetPath() if e.GetSites()[0].IsProperty() else e.GetSites()[0].GetPrim().GetPath()),
             e.GetMessage()) for e in ctx.Validate(stage, Usd.PrimAllPrimsPredicate)]


def test_animation_validator_reports_each_kind_of_bad_sample_of_each_array(tmp_path):
    """Read from the one layer that holds the samples and checked as one array (a Get and a norm per
    sample took 12 s on a 200-character crowd): per array, each kind of bad sample with its first time."""
    from . import synthetic as syn

    r = syn.make_rig(tmp_path / "in.usda", frames=20, mesh=False)
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    rotations, translations = (Sdf.Path(r.animation).AppendProperty(n) for n in ("rotations", "translations"))
    for t, q in ((9, Gf.Quatf(float("nan"), 0, 0, 0)), (7, Gf.Quatf(2, 0, 0, 0))):
        v = list(layer.QueryTimeSample(rotations, t))
        v[1] = q
        layer.SetTimeSample(rotations, t, Vt.QuatfArray(v))
    layer.SetTimeSample(translations, 4, Vt.Vec3fArray(list(layer.QueryTimeSample(translations, 4))[:-1]))
    layer.Save()
    found = {(s.rsplit(".", 1)[1], e): m for _, e, s, m in _ours(Usd.Stage.Open(str(r.path)))}
    assert set(found) == {("rotations", "NotUnit"), ("rotations", "NotFinite"), ("translations", "Length")}
    assert "rotations: not unit quaternions at time 7; 1 of 20 samples" in found["rotations", "NotUnit"]
    assert "rotations: NaN or infinite values at time 9; 1 of 20 samples" in found["rotations", "NotFinite"]
    assert f"translations: {len(r.anim_joints) - 1} entries at time 4" in found["translations", "Length"]


def test_instances_of_one_broken_asset_are_each_reported_and_a_fixed_layer_is_clean_next_run(tmp_path):
    """A crowd's instances share their asset's samples, checked once a run: each instance still gets
    its own error, one that lists fewer joints gets its own length check, and a run after the layer
    is fixed in memory sees the fix."""
    from usdgaze.review import validation

    from . import synthetic as syn

    r = syn.make_rig(tmp_path / "rig.usda", frames=12, mesh=False)
    rig = Sdf.Layer.FindOrOpen(str(r.path))
    rotations = Sdf.Path(r.animation).AppendProperty("rotations")
    good = rig.QueryTimeSample(rotations, 3)
    v = list(good)
    v[2] = Gf.Quatf(float("nan"), 0, 0, 0)
    rig.SetTimeSample(rotations, 3, Vt.QuatfArray(v))
    rig.Save()
    root = r.skel_root
    joints = r.anim_joints
    shorter = ", ".join(f'"{j}"' for j in joints[:-1])
    anim = r.animation[len(root):]
    crowd = tmp_path / "crowd.usda"
    crowd.write_text("#usda 1.0\n(\n    timeCodesPerSecond = 60\n)\n" + "".join(  # the rig's: times map as they are
        f'def "C{i}" (prepend references = @./rig.usda@<{root}>)\n{{\n' +
        (f'    over "{anim.strip("/")}"\n    {{\n        uniform token[] joints = [{shorter}]\n    }}\n' if i == 3 else "") + "}\n"
        for i in range(4)))
    found = [p for p in validation.run(crowd, only_usdgaze=True) if p["validator"].endswith("AnimationArrays")]
    by_site = {}
    for p in found:
        by_site.setdefault(p["site"], {})[p["error"]] = p["message"]
    for i in range(3):
        (error, message), = by_site[f"/C{i}{anim}.rotations"].items()
        assert error == "NotFinite" and "at time 3" in message
    c3 = by_site[f"/C3{anim}.rotations"]  # every sample one entry too long; the NaN one is still NaN
    assert set(c3) == {"Length", "NotFinite"}
    assert f"{len(joints)} entries at time 0, expected {len(joints) - 1}" in c3["Length"] and "at time 3" in c3["NotFinite"]
    assert len(found) >= 4
    rig.SetTimeSample(rotations, 3, good)  # fixed in memory: the next run reads it anew
    again = [p for p in validation.run(crowd, only_usdgaze=True)
             if p["validator"].endswith("AnimationArrays") and not p["site"].startswith("/C3")]
    assert again == []


@pytest.mark.parametrize("path", SAMPLES, ids=lambda p: p.name)
def test_every_validator_passes_on_the_sample_stages(path):
    assert _ours(Usd.Stage.Open(str(path))) == []


def _crowd():
    stage = Usd.Stage.Open(str(CROWD))
    stage.SetEditTarget(stage.GetSessionLayer())  # malformations go into the session layer only
    return stage, stage.GetPrimAtPath(MAP_PRIM)


def _set(prim, name, value):
    prim.GetAttribute(name).Set(value)


def _quat_array(prim, name, scale_first):
    q = np.array(prim.GetAttribute(name).Get(), dtype=np.float32)
    q[0] *= scale_first
    return Vt.QuatfArray.FromNumpy(q)


MALFORMED = {
    "GazeMapArrays": (lambda p: _set(p, "gaze:examples:pitch", Vt.FloatArray([0.0, 1.0])), "Length", "gaze:examples:pitch"),
    "GazeMapRanges": (lambda p: _set(p, "gaze:examples:overshoot", Vt.FloatArray(
        [1.5] + list(p.GetAttribute("gaze:examples:overshoot").Get())[1:])), "Range", "gaze:examples:overshoot"),
    "GazeMapUnitQuaternions": (lambda p: _set(p, "gaze:examples:neckOffset", _quat_array(p, "gaze:examples:neckOffset", 1.2)),
                               "NotUnit", "gaze:examples:neckOffset"),
    "GazeMapRoleJoints": (lambda p: _set(p, "gaze:binding:head", Vt.TokenArray(["Hips/Nope"])), "UnknownJoint",
                          "gaze:binding:head"),
}


@pytest.mark.parametrize("name", sorted(MALFORMED))
def test_each_map_validator_catches_its_malformation(name):
    stage, prim = _crowd()
    assert _ours(stage) == []
    if name == "GazeMapRoleJoints":  # the crowd's map binds nothing explicitly; bind one joint that exists
        _set(prim, "gaze:binding:neck", Vt.TokenArray(["Hips/lowerback/Chest/Chest2/lowerneck"]))
        assert _ours(stage) == []
    malform, error, attr = MALFORMED[name]
    malform(prim)
    found = _ours(stage)
    assert [(v, e, s) for v, e, s, _ in found] == [(name, error, f"{MAP_PRIM}.{attr}")], found


def test_animation_validator_catches_a_short_rotations_array(tmp_path):
    stage = Usd.Stage.Open(str(SAMPLES[0]))
    stage.GetSessionLayer().timeCodesPerSecond = stage.GetTimeCodesPerSecond()  # samples keep their times
    stage.SetEditTarget(stage.GetSessionLayer())
    anim = next(p for p in stage.Traverse() if p.GetTypeName() == "SkelAnimation")
    rotations = anim.GetAttribute("rotations")
    t = rotations.GetTimeSamples()[5]
    rotations.Set(Vt.QuatfArray(list(rotations.Get(t))[:-1]), t)
    found = _ours(stage)
    assert [(v, e) for v, e, _, _ in found] == [("AnimationArrays", "Length")]
    assert f"at time {t:g}" in found[0][3]


def test_validators_load_through_the_plugin_path_without_importing_usdgaze(tmp_path):
    bad = tmp_path / "bad_map.usda"
    layer = Sdf.Layer.FindOrOpen(str(SAMPLES[3]))
    layer.Export(str(bad))
    code = f"""
import sys
from pxr import Usd, UsdValidation
r = UsdValidation.ValidationRegistry()
v = r.GetOrLoadValidatorByName("usdgaze.review.validators:GazeMapRanges")
stage = Usd.Stage.Open({str(bad)!r})
prim = stage.GetDefaultPrim()
prim.GetAttribute("gaze:examples:pitch").Set([120.0] + list(prim.GetAttribute("gaze:examples:pitch").Get())[1:])
print([e.GetName() for e in UsdValidation.ValidationContext([v]).Validate(stage, Usd.PrimAllPrimsPredicate)])
print("usdgaze imported first:", "usdgaze" in sys.modules and sys.modules.get("__main__") is None)
"""
    env = dict(os.environ, PXR_PLUGINPATH_NAME=str(plugin_dir()))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == "['Range']"
    # And in a process that imports usdgaze (no PXR_PLUGINPATH_NAME): the import registers them.
    env.pop("PXR_PLUGINPATH_NAME")
    proc = subprocess.run([sys.executable, "-c", "import usdgaze\n" + code], env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == "['Range']"


def test_validate_is_silent_on_a_clean_result_and_lints_a_bad_one(tmp_path, capsys):
    preview = tmp_path / "preview.usda"
    api.apply(SAMPLES[0], ["2s:60:0"], tmp_path / "g.usdc", preview=preview)
    capsys.readouterr()
    assert main(["validate", str(preview)]) == 0
    assert main(["validate", str(SAMPLES[0]), "--layer", str(tmp_path / "g.usdc")]) == 0
    assert capsys.readouterr() == ("", "")
    assert main(["validate", str(preview), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == []  # printed nothing: no JSON for a reader to parse

    # A malformed copy of the map file: two problems, one line each, exit 3 (bad input stays 2).
    bad = tmp_path / "bad.usda"
    stage = Usd.Stage.Open(str(SAMPLES[3]))
    prim = stage.GetDefaultPrim()
    prim.GetAttribute("gaze:examples:yaw").Set(Vt.FloatArray([500.0] + list(prim.GetAttribute("gaze:examples:yaw").Get())[1:]))
    prim.GetAttribute("gaze:binding:forward").Set(Gf.Vec3f(0, 0, 1))
    prim.GetAttribute("gaze:examples:duration").Set(Vt.FloatArray([1.0]))
    stage.GetRootLayer().Export(str(bad))
    assert main(["validate", str(bad), "--only-usdgaze"]) == 3
    lines = capsys.readouterr().out.splitlines()
    assert lines == [
        f"{bad}:/GazeMap.gaze:examples:duration: error: gaze:examples:duration: 1 entries, expected 55 (one per example) "
        "(usdgaze.review.validators:GazeMapArrays.Length)",
        f"{bad}:/GazeMap.gaze:examples:yaw: error: gaze:examples:yaw: example 0 is 500 deg, expected in [-180, 180] deg "
        "(usdgaze.review.validators:GazeMapRanges.Range)",
    ]
    assert main(["validate", str(bad), "--json"]) == 3
    records = json.loads(capsys.readouterr().out)
    assert {(r["validator"], r["error"]) for r in records} >= {
        ("usdgaze.review.validators:GazeMapArrays", "Length"), ("usdgaze.review.validators:GazeMapRanges", "Range")}
    assert main(["validate", str(tmp_path / "missing.usda")]) == 2


def test_the_override_alone_names_the_inputs_default_prim_and_says_to_validate_it_over_the_input(tmp_path, capsys):
    layer = tmp_path / "g.usdc"
    api.apply(SAMPLES[0], ["2s:60:0"], layer)
    assert Sdf.Layer.FindOrOpen(str(layer)).defaultPrim == Sdf.Layer.FindOrOpen(str(SAMPLES[0])).defaultPrim == "root"
    capsys.readouterr()
    assert main(["validate", str(layer)]) == 3
    (line,) = capsys.readouterr().out.splitlines()  # no MissingDefaultPrim: one line, with what to do
    assert "names /root/Body, which this stage only overrides (no def)" in line
    assert f"usdgaze validate INPUT --layer {layer.name}" in line and "MissingCharacter" in line


def test_validate_with_a_layer_names_the_input_not_its_in_memory_root(tmp_path, capsys):
    """An input without a defaultPrim, validated with --layer: USD's StageMetadataChecker names the
    stage's root layer, which is the in-memory one composing input and layer (``<anon:0x...>``)."""
    src = tmp_path / "in.usda"
    stage = Usd.Stage.Open(str(SAMPLES[0]))
    stage.GetRootLayer().Export(str(src))
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.ClearDefaultPrim()
    layer.Save()
    api.apply(src, ["2s:60:0"], tmp_path / "g.usdc")
    capsys.readouterr()
    assert main(["validate", str(src), "--layer", str(tmp_path / "g.usdc")]) == 3
    (line,) = [x for x in capsys.readouterr().out.splitlines() if "MissingDefaultPrim" in x]
    assert f"root layer <{src}>" in line and "anon:" not in line


def test_schedule_validator_catches_late_shifts_and_missing_characters(tmp_path):
    layer = tmp_path / "g.usda"
    api.apply(SAMPLES[0], ["2s:60:0"], layer, preview=tmp_path / "preview.usda")
    stage = Usd.Stage.Open(str(tmp_path / "preview.usda"))
    assert _ours(stage) == []
    edit = Sdf.Layer.FindOrOpen(str(layer))
    record = dict(edit.customLayerData["usdgaze"])
    record["shifts"] = ["2s:60:0", "100s:0:0"]
    record["characters"] = [*record["characters"], "/Nope"]
    edit.customLayerData = {"usdgaze": record}
    found = sorted((v, e) for v, e, _, _ in _ours(stage))
    assert found == [("GazeLayerSchedule", "MissingCharacter"), ("GazeLayerSchedule", "ShiftOutOfRange")]


def test_schedule_validator_catches_late_look_ats_and_releases(tmp_path):
    """Look-ats and releases are recorded per character (``directives``), not in ``shifts``: one made
    for a longer take starts past this one's range as a late shift does (it was not looked at)."""
    layer = tmp_path / "g.usda"
    api.apply(SAMPLES[0], [], layer, preview=tmp_path / "preview.usda", look_at=["1,1.3,-0.5@0.5s"],
              release=["6.5s"])
    stage = Usd.Stage.Open(str(tmp_path / "preview.usda"))
    assert _ours(stage) == []
    edit = Sdf.Layer.FindOrOpen(str(layer))
    record = dict(edit.customLayerData["usdgaze"])
    (root, flags), = dict(record["directives"]).items()
    record["directives"] = {root: [*flags, "--look-at 1,1.3,-0.5@100s", "--release 20000", "--release soon"]}
    edit.customLayerData = {"usdgaze": record}
    found = sorted((v, e, m.split(": ", 1)[1][:40]) for v, e, _, m in _ours(stage))
    assert [f[:2] for f in found] == [("GazeLayerSchedule", "BadDirective"), ("GazeLayerSchedule", "DirectiveOutOfRange"),
                                      ("GazeLayerSchedule", "DirectiveOutOfRange")], found
    assert "100s" in found[1][2] + found[2][2] and "20000" in found[1][2] + found[2][2]


def test_a_shift_past_the_playback_range_but_inside_the_animation_passes_both(tmp_path):
    """``apply`` takes a shift anywhere the animation has samples; the schedule validator agrees, even
    where the stage's playback range ends earlier (handles kept beyond it)."""
    shot = tmp_path / "shot.usda"
    layer = Sdf.Layer.CreateNew(str(shot))
    layer.subLayerPaths.append(str(SAMPLES[0]))
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    layer.startTimeCode, layer.endTimeCode = 1.0, 200.0  # the walk's samples run to 994
    layer.timeCodesPerSecond = layer.framesPerSecond = Usd.Stage.Open(str(SAMPLES[0])).GetTimeCodesPerSecond()
    layer.Save()
    api.apply(shot, ["600:60:0"], tmp_path / "g.usda", preview=tmp_path / "preview.usda")
    assert _ours(Usd.Stage.Open(str(tmp_path / "preview.usda"))) == []



def test_a_schedule_past_the_playback_range_but_inside_the_animation_passes(tmp_path):
    """The same for a GazeScheduleAPI on the SkelRoot: ``apply`` played its directive at 90 (the
    animation runs to 119, the playback range to 59) while ``validate`` called it out of range (exit 3)."""
    from . import synthetic as syn

    rig = syn.make_rig(tmp_path / "in.usda", frames=120, time_codes_per_second=24.0, mesh=False, walk_speed=0.0)
    syn.edit(rig.path, lambda layer: setattr(layer, "endTimeCode", 59.0))  # handles kept past the cut
    stage = Usd.Stage.Open(str(rig.path))
    prim = stage.GetPrimAtPath(rig.skel_root)
    prim.ApplyAPI("GazeScheduleAPI")
    for name, type_name, value in (("time", Sdf.ValueTypeNames.DoubleArray, [30.0, 90.0]),
                                   ("kind", Sdf.ValueTypeNames.TokenArray, ["shift", "shift"]),
                                   ("yaw", Sdf.ValueTypeNames.FloatArray, [30.0, -30.0])):
        prim.CreateAttribute(f"gaze:schedule:{name}", type_name, False, Sdf.VariabilityUniform).Set(value)
    stage.Save()
    layer = tmp_path / "g.usdc"
    assert main(["apply", str(rig.path), "--out", str(layer)]) == 0
    record = Sdf.Layer.FindOrOpen(str(layer)).customLayerData["usdgaze"]
    assert list(record["directives"][rig.skel_root]) == ["--shift 30:30:0", "--shift 90:-30:0"]  # both played
    assert main(["validate", str(rig.path)]) == 0
    assert main(["validate", str(rig.path), "--layer", str(layer)]) == 0
    # Past the animation too, it is out of range.
    prim.GetAttribute("gaze:schedule:time").Set(Vt.DoubleArray([30.0, 130.0]))
    found = [(v, e) for v, e, _, _ in _ours(stage)]
    assert found == [("GazeSchedule", "OutOfRange")], found


def _scheduled(tmp_path):
    from usdgaze.passes.requests import DirectiveRequest
    from usdgaze.usd.schedule import write_schedule

    path = tmp_path / "shot.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(100)
    root = stage.DefinePrim("/Char", "SkelRoot")
    stage.DefinePrim("/Ball", "Sphere")
    write_schedule(root, [DirectiveRequest("look", 10.0, target="/Ball"), DirectiveRequest("shift", 50.0, yaw=30.0)])
    stage.GetRootLayer().Save()
    stage = Usd.Stage.Open(str(path))
    stage.SetEditTarget(stage.GetSessionLayer())
    return stage, stage.GetPrimAtPath("/Char")


@pytest.mark.parametrize("malform, error, site", [
    (lambda p: p.GetRelationship("gaze:schedule:targets").SetTargets([Sdf.Path("/Nope")]), "MissingTarget",
     "/Char.gaze:schedule:targets"),
    (lambda p: p.GetAttribute("gaze:schedule:time").Set(Vt.DoubleArray([10.0, 500.0])), "OutOfRange",
     "/Char.gaze:schedule:time"),
    (lambda p: p.GetAttribute("gaze:schedule:kind").Set(Vt.TokenArray(["look", "stare"])), "Malformed",
     "/Char.gaze:schedule:kind"),
    (lambda p: p.GetAttribute("gaze:schedule:weight").Set(Vt.FloatArray([1.0])), "Malformed",
     "/Char.gaze:schedule:weight"),
], ids=["target", "time", "kind", "length"])
def test_schedule_validator_catches_its_malformations(tmp_path, malform, error, site):
    stage, prim = _scheduled(tmp_path)
    assert _ours(stage) == []
    malform(prim)
    found = [(v, e, s) for v, e, s, _ in _ours(stage)]
    assert found == [("GazeSchedule", error, site)], _ours(stage)


@pytest.mark.parametrize("attr, value, error", [
    ("gaze:object:importance", 0.0, "Range"), ("gaze:object:radius", -1.0, "Range"),
    ("gaze:object:kind", "bouncy", "UnknownKind")])
def test_object_validator_catches_its_malformations(attr, value, error):
    stage = Usd.Stage.Open(str(ROOT / "sample_stages" / "attend" / "two_balls.usda"))
    assert _ours(stage) == []
    stage.SetEditTarget(stage.GetSessionLayer())
    prim = next(p for p in stage.Traverse() if p.HasAPI("GazeObjectAPI"))
    prim.GetAttribute(attr).Set(value)
    assert [(v, e, s) for v, e, s, _ in _ours(stage)] == [("GazeObject", error, f"{prim.GetPath()}.{attr}")]


def test_schedule_validator_reports_every_problem_one_line_each(tmp_path, capsys):
    """Four problems authored in one schedule, four lines (the reader used to stop at the first);
    ``apply``'s reader still stops at the first of them, in the order it reads."""
    from usdgaze.errors import UsdGazeError
    from usdgaze.usd.schedule import read_schedule

    stage, prim = _scheduled(tmp_path)
    prim.GetAttribute("gaze:schedule:blend").Set(Vt.FloatArray([-1.0, 0.0]))  # entry 0
    prim.GetAttribute("gaze:schedule:kind").Set(Vt.TokenArray(["look", "stare"]))  # entry 1
    prim.GetAttribute("gaze:schedule:weight").Set(Vt.FloatArray([1.0, 1.5]))  # entry 1
    prim.GetRelationship("gaze:schedule:targets").SetTargets([Sdf.Path("/Nope")])
    found = sorted((e, s) for v, e, s, _ in _ours(stage))
    assert found == [("Malformed", "/Char.gaze:schedule:blend"), ("Malformed", "/Char.gaze:schedule:kind"),
                     ("Malformed", "/Char.gaze:schedule:weight"), ("MissingTarget", "/Char.gaze:schedule:targets")]
    with pytest.raises(UsdGazeError, match=r"x:/Char\.gaze:schedule:blend: entry 0 is -1"):
        read_schedule(prim, "x")

    bad = tmp_path / "bad.usda"
    stage.Flatten().Export(str(bad))
    capsys.readouterr()
    assert main(["validate", str(bad), "--only-usdgaze"]) == 3  # problems found; 2 is kept for bad input
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and all(line.startswith(f"{bad}:/Char.gaze:schedule:") for line in lines), lines
    assert sum("GazeSchedule.Malformed" in line for line in lines) == 3


@pytest.mark.parametrize("command", [["plot", "--out", "plots"], ["preview", "--out", "p.gif"], ["validate"]])
@pytest.mark.parametrize("own", ["cmu/cmu_131_01.usdc", "attend/standing.usdc"])
def test_a_layer_of_the_inputs_own_given_as_layer_is_named_as_such(tmp_path, capsys, command, own):
    """``--layer`` naming one of the input's own sublayers (the character's file, by tab completion) was
    taken for a --sublayer-into override and muted to show "the input": the CMU clip's layer muted
    said "the skeleton has no joints", the standing pose's that its frames were not the input's, and
    validate said nothing. It is one line naming the layer, exit 2, nothing written."""
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths[:] = [str(ROOT / "sample_stages" / "attend" / "ball_throw.usda")]
    shot.Save()
    layer = ROOT / "sample_stages" / own
    argv = [command[0], str(tmp_path / "shot.usda"), "--layer", str(layer)]
    if len(command) > 1:
        argv += [command[1], str(tmp_path / command[2])]
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"usdgaze: error: {layer}: --layer names a layer of the input's own ({tmp_path / 'shot.usda'} "
                   "composes it as a sublayer), not one usdgaze wrote; pass the override layer usdgaze wrote"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.usda"]
