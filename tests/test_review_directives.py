"""The review commands read back every directive ``apply`` records, and place them on the stage's time.

A sweep found: a layer made with ``:weight=`` could not be plotted or previewed (exit 2) and
``validate`` flagged it; the requested line ignored releases and looks (a release's 0 drawn as the
last shift's 60, a 60 deg miss that was not there); a layer over a re-exported take of another length
crashed ``plot`` and ``preview`` (exit 1); a shot that ``--sublayer-into`` brings the input in 100
time codes late was flagged by ``validate`` and crashed ``plot``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Sdf

from usdgaze.console.main import main
from usdgaze.review import analysis
from usdgaze.review.composed import read_review

from . import synthetic as syn


def test_weighted_shifts_releases_and_looks_are_read_back(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=120, mesh=False, walk_speed=0.0)
    layer = tmp_path / "g.usdc"
    assert main(["apply", str(rig.path), "--look-at", "1,1.6,2@10", "--shift", "40:30:0:weight=0.5",
                 "--release", "70", "--out", str(layer)]) == 0
    review = read_review(str(rig.path), str(layer))
    tcps = rig.time_codes_per_second
    times = [t for t, _, _ in review.shifts]
    assert np.allclose(times, [10 / tcps, 40 / tcps, 70 / tcps])
    assert np.isnan(review.shifts[0][1]) and review.shifts[1][1:] == (15.0, 0.0) and review.shifts[2][1:] == (0.0, 0.0)
    c = review.characters[0]
    steps = analysis.requested_steps(c.seconds, review.shifts)
    assert np.all(steps[c.seconds >= 70 / tcps] == 0.0)
    assert np.isnan(steps[(c.seconds >= 10 / tcps) & (c.seconds < 40 / tcps)]).all()
    capsys.readouterr()
    assert main(["plot", str(rig.path), "--layer", str(layer), "--out", str(tmp_path / "plots")]) == 0
    assert main(["validate", str(rig.path), "--layer", str(layer)]) == 0


def test_a_layer_for_another_take_is_refused_in_one_line(tmp_path, capsys):
    long = syn.make_rig(tmp_path / "long.usda", frames=120, mesh=False)
    short = syn.make_rig(tmp_path / "short.usda", frames=60, mesh=False)
    layer = tmp_path / "g.usdc"
    assert main(["apply", str(long.path), "--shift", "10:30:0", "--out", str(layer)]) == 0
    capsys.readouterr()
    for command in (["plot", "--out", str(tmp_path / "p")], ["preview", "--out", str(tmp_path / "p.png")]):
        assert main([command[0], str(short.path), "--layer", str(layer), *command[1:]]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "are not the input's (60 at time codes 0..59)" in err[0], err
    assert not (tmp_path / "p").exists() and not (tmp_path / "p.png").exists()



def test_validate_calls_a_layer_for_another_take_what_plot_calls_it(tmp_path, capsys):
    """``plot`` and ``preview`` refuse a layer made for a longer take; ``validate --layer`` of the same
    pair printed nothing and exited 0."""
    long = syn.make_rig(tmp_path / "long.usda", frames=120, mesh=False)
    short = syn.make_rig(tmp_path / "short.usda", frames=60, mesh=False)
    layer = tmp_path / "g.usdc"
    assert main(["apply", str(long.path), "--shift", "10:30:0", "--out", str(layer)]) == 0
    assert main(["validate", str(long.path), "--layer", str(layer)]) == 0  # over its own take: clean
    capsys.readouterr()
    assert main(["validate", str(short.path), "--layer", str(layer)]) == 3
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and "OtherTake" in out[0] and "0..119, the input below it 0..59" in out[0], out


def test_a_shot_that_sublayers_the_input_late_is_reviewed_on_its_own_time(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=120, mesh=False, time_codes_per_second=60)
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths.append("./in.usda")
    shot.subLayerOffsets[0] = Sdf.LayerOffset(100, 1)
    shot.timeCodesPerSecond, shot.startTimeCode, shot.endTimeCode = 60, 100, 219
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    shot.defaultPrim = "Character"
    shot.Save()
    layer = tmp_path / "g.usdc"
    assert main(["apply", str(rig.path), "--shift", "0.5s:40:0", "--shift", "60:-20:0", "--out", str(layer),
                 "--sublayer-into", str(tmp_path / "shot.usda")]) == 0
    review = read_review(str(tmp_path / "shot.usda"), str(layer))
    # 0.5 s from the input's start and its time code 60 play at shot codes 130 and 160: 0.5 s and 1 s.
    assert np.allclose([t for t, _, _ in review.shifts], [0.5, 1.0])
    assert len(review.characters[0].seconds) == 120
    capsys.readouterr()
    assert main(["validate", str(tmp_path / "shot.usda")]) == 0
    assert main(["plot", str(tmp_path / "shot.usda"), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0


def test_a_character_the_layer_does_not_touch_is_not_read(tmp_path, capsys):
    from pxr import Usd, UsdGeom

    rig = syn.make_rig(tmp_path / "base.usda", frames=60, mesh=False)
    broken = syn.make_rig(tmp_path / "broken.usda", frames=60, mesh=False)
    layer = Sdf.Layer.FindOrOpen(str(broken.path))
    attr = layer.GetAttributeAtPath(Sdf.Path(broken.skeleton).AppendProperty("restTransforms"))
    attr.default = attr.default[:3]  # 3 entries for its 20-odd joints: read, it is refused
    layer.Save()
    stage = Usd.Stage.CreateNew(str(tmp_path / "two.usda"))
    stage.SetStartTimeCode(0), stage.SetEndTimeCode(59), stage.SetTimeCodesPerSecond(rig.time_codes_per_second)
    UsdGeom.SetStageUpAxis(stage, "Y"), UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.DefinePrim("/World/A").GetReferences().AddReference("./base.usda", "/Character")
    stage.DefinePrim("/World/D").GetReferences().AddReference("./broken.usda", "/Character")
    stage.GetRootLayer().defaultPrim = "World"
    stage.Save()
    gaze = tmp_path / "g.usda"
    assert main(["apply", str(tmp_path / "two.usda"), "--skel-root", "/World/A", "--shift", "10:30:0", "--out", str(gaze)]) == 0
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "two.usda"), "--layer", str(gaze), "--out", str(tmp_path / "p")]) == 0
    assert sorted(p.name for p in (tmp_path / "p").iterdir())[0].startswith("A_")
    assert main(["plot", str(tmp_path / "two.usda"), "--layer", str(gaze), "--skel-root", "/World/D",
                 "--out", str(tmp_path / "q")]) == 2  # named, it is read and refused


MAP = Path(__file__).resolve().parents[1] / "sample_stages" / "shared_map" / "gaze_map.usda"


def _scheduled_pair(tmp_path: Path, schedules: dict) -> Path:
    """/A and /B side by side (24 per second, 60 frames), each with the shared map and its own
    GazeScheduleAPI of shifts ``schedules[name] = (time code, yaw, pitch)``, authored with pxr alone."""
    from pxr import Gf, Usd, Vt

    import usdgaze  # noqa: F401  (registers the schemas)

    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    for k, name in enumerate(schedules):
        rig = syn.make_rig(tmp_path / f"{name}.usda", frames=60, time_codes_per_second=24.0, mesh=False,
                           walk_speed=0.0, root_path=f"/{name}", seed=k)
        Sdf.CopySpec(Sdf.Layer.FindOrOpen(str(rig.path)), f"/{name}", shot, f"/{name}")
        spec = shot.GetPrimAtPath(f"/{name}")
        Sdf.AttributeSpec(spec, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(2.0 * k, 0, 0)
        Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:translate"])
        spec.inheritPathList.Prepend("/Map")
    shot.timeCodesPerSecond = shot.framesPerSecond = 24.0
    shot.startTimeCode, shot.endTimeCode = 0.0, 59.0
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    shot.defaultPrim = "A"
    Sdf.PrimSpec(shot.pseudoRoot, "Map", Sdf.SpecifierClass).referenceList.Prepend(Sdf.Reference(str(MAP), "/GazeMap"))
    shot.Save()
    stage = Usd.Stage.Open(shot)
    for name, (time, yaw, pitch) in schedules.items():
        prim = stage.GetPrimAtPath(f"/{name}")
        prim.ApplyAPI("GazeScheduleAPI")
        for attr, type_name, value in (("time", Sdf.ValueTypeNames.DoubleArray, [time]),
                                       ("kind", Sdf.ValueTypeNames.TokenArray, ["shift"]),
                                       ("yaw", Sdf.ValueTypeNames.FloatArray, [yaw]),
                                       ("pitch", Sdf.ValueTypeNames.FloatArray, [pitch])):
            prim.CreateAttribute(f"gaze:schedule:{attr}", type_name, False, Sdf.VariabilityUniform).Set(value)
    stage.Save()
    return tmp_path / "shot.usda"


def test_each_character_is_plotted_against_its_own_schedule(tmp_path):
    """Two characters of one layer, each with its own schedule: every character's plots drew the first
    character's requests (B's gaze panel asked for A's 40 deg at 0.5 s while B turned -50 at 1.25 s)."""
    from usdgaze.review import plotting

    from . import measure

    schedules = {"A": (12.0, 40.0, 0.0), "B": (30.0, -50.0, 10.0)}
    shot = _scheduled_pair(tmp_path, schedules)
    layer = tmp_path / "g.usdc"
    assert main(["apply", str(shot), "--out", str(layer)]) == 0
    composed = Sdf.Layer.CreateNew(str(tmp_path / "composed.usda"))
    composed.timeCodesPerSecond = composed.framesPerSecond = 24.0
    composed.startTimeCode, composed.endTimeCode = 0.0, 59.0
    composed.pseudoRoot.SetInfo("upAxis", "Y")
    composed.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    composed.subLayerPaths[:] = [str(layer), str(shot)]
    composed.Save()

    review = read_review(str(shot), str(layer))
    drawn = plotting.figures(review)
    for name, (time, yaw, pitch) in schedules.items():
        # What the composed result reaches, by UsdSkel's FK: the request this character was given.
        skeleton = f"/{name}/Skel"
        base, new = measure.posed(str(shot), skeleton), measure.posed(composed.realPath, skeleton)
        fwd = measure.character_forward_skel(base, "mixamorig_LeftUpLeg", "mixamorig_RightUpLeg")
        change, _, _ = measure.gaze_change(base, new, fwd, "mixamorig_Head", ("mixamorig_LeftEye", "mixamorig_RightEye"))
        assert np.abs(change[-1] - (yaw, pitch)).max() < 0.5, (name, change[-1])
        ax = drawn[f"{name}_gaze"].axes[0]
        lines = {line.get_label(): line for line in ax.get_lines()}
        for label, want in (("yaw requested", yaw), ("pitch requested", pitch)):
            x, y = lines[label].get_xdata(), lines[label].get_ydata()
            assert y[-1] == want, (name, label, y[-1])
            assert np.all(y[x < time / 24.0] == 0.0) and np.all(y[x >= time / 24.0] == want), (name, label)
        assert f"to yaw {yaw:g}, pitch {pitch:g}" in drawn[f"{name}_cascade"].axes[0].get_title(), name
    for fig in drawn.values():
        plotting.pyplot().close(fig)


def test_a_skel_root_the_layer_does_not_animate_is_named_in_one_line(tmp_path, capsys):
    """``plot --skel-root /B`` of a layer made for /A said the layer overrode nothing of the input and
    asked whether it was a usdgaze layer at all."""
    shot = _scheduled_pair(tmp_path, {"A": (12.0, 40.0, 0.0), "B": (30.0, -50.0, 10.0)})
    layer = tmp_path / "a.usdc"
    assert main(["apply", str(shot), "--skel-root", "/A", "--shift", "10:30:0", "--out", str(layer)]) == 0
    capsys.readouterr()
    for command in (["plot", "--out", str(tmp_path / "p")], ["preview", "--out", str(tmp_path / "p.png")]):
        assert main([command[0], str(shot), "--layer", str(layer), "--skel-root", "/B", *command[1:]]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--skel-root /B" in err[0] and "it animates /A" in err[0], err
    assert not (tmp_path / "p").exists() and not (tmp_path / "p.png").exists()
