"""The review commands read back every directive ``apply`` records, and place them on the stage's time.

A sweep found: a layer made with ``:weight=`` could not be plotted or previewed (exit 2) and
``validate`` flagged it; the requested line ignored releases and looks (a release's 0 drawn as the
last shift's 60, a 60 deg miss that was not there); a layer over a re-exported take of another length
crashed ``plot`` and ``preview`` (exit 1); a shot that ``--sublayer-into`` brings the input in 100
time codes late was flagged by ``validate`` and crashed ``plot``.
"""

from __future__ import annotations

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
