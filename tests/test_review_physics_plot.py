"""``usdgaze plot`` of a layer ``attend --physics`` wrote: ``NAME_physics.png``, the simulated shot's
per-step measures against time, checked against the layer's ``customLayerData`` read with pxr.

The layer comes from the real pass: CMU 131_01's first 0.3 s at h 0.03, with a sphere flying through
the chest (an obstacle the body touches mid-shot: a problem with its time), simulated once (~3 s).
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image
from pxr import Sdf, Vt

from usdgaze.console.main import main
from usdgaze.review import plotting
from usdgaze.review.composed import read_review

from . import measure
from .obstacle_stages import add_objects
from .test_physics_pass import SKEL, excerpt

PANELS = 6  # pelvis, joints, feet, heading, drift, obstacles


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    folder = tmp_path_factory.mktemp("physics_plot")
    src = excerpt(folder / "in.usda", 0.3)
    posed = measure.posed(str(src), SKEL)
    chest = posed.world[0, posed.index("Chest2"), 3, :3]
    lay = Sdf.Layer.FindOrOpen(str(src))
    path = [chest + np.array([0.6, 0, 0]), chest - np.array([0.6, 0, 0])]  # through the chest at 0.15 s
    add_objects(src, "obstacle", "Obstacle", [path], 0.1, times=[lay.startTimeCode, lay.endTimeCode], seen=False)
    layer = folder / "sim.usda"
    assert main(["attend", str(src), "--physics", "--timestep", "0.03", "--retry-iterations", "0",
                 "--out", str(layer)]) == 0
    record = Sdf.Layer.FindOrOpen(str(layer)).customLayerData["usdgaze:physics"][SKEL]
    return folder, src, layer, record


def _lines(ax) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {ln.get_label(): (np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float))
            for ln in ax.get_lines()}


def test_plot_writes_one_physics_png_per_simulated_character(shot, tmp_path):
    folder, src, layer, record = shot
    out = tmp_path / "p"
    assert main(["plot", str(src), "--layer", str(layer), "--out", str(out)]) == 0
    # CMU has no eyes and a physics pass adds none: no line of sight to draw (this crashed before).
    assert sorted(p.name for p in out.iterdir()) == ["Body_physics.png"]
    png = out / "Body_physics.png"
    assert png.stat().st_size > 30_000
    assert Image.open(png).size == (1000, int(round(100 * (1.2 + 2.1 * PANELS))))


def test_drawn_series_are_the_layers_own_measures(shot):
    folder, src, layer, record = shot
    frames = {k: np.array(list(v), dtype=float) for k, v in record["frames"].items()}
    fig = plotting.figures(read_review(src, layer))["Body_physics"]
    axes = fig.axes
    assert len(axes) == PANELS
    # The stage starts at the take's first sample: the record's seconds are seconds from the stage start.
    t = frames["seconds"]
    assert t[0] == 0.0 and np.allclose(np.diff(t), 0.03)
    expected = [  # (panel, curve label, record key, scale, bar)
        (0, "pelvis height", "pelvisRatio", 100.0, 80.0), (1, "mean joint error", "jointErrorDeg", 1.0, None),
        (2, "written foot", "footBelowGroundM", 100.0, 2.0),
        (2, "simulation's soft contact", "contactDepthM", 100.0, 2.0),
        (3, "heading error", "headingErrorDeg", 1.0, 30.0), (4, "root drift", "rootDriftM", 100.0, None),
        (5, "clearance", "obstacles.clearanceM", 100.0, 0.0),
    ]
    for panel, label, key, scale, bar in expected:
        lines = _lines(axes[panel])
        x, y = lines[label]
        assert np.allclose(x, t, rtol=0, atol=1e-9), label
        assert np.allclose(y, scale * frames[key], equal_nan=True, rtol=0, atol=1e-12), label
        bars = [v[1][0] for k, v in lines.items() if k.startswith(("fall", "a problem:", "a touch"))]
        assert bars == ([] if bar is None else [bar]), label
    assert np.isnan(frames["obstacles.clearanceM"][0]) and np.nanmin(frames["obstacles.clearanceM"]) < -0.05
    assert "obstacles.proximity" in frames  # the planner's term: not drawn
    assert all("proximity" not in ln.get_label() for ax in axes for ln in ax.get_lines())
    plotting.pyplot().close(fig)


def test_the_reports_problem_is_marked_when_the_obstacle_is_first_touched(shot, tmp_path):
    folder, src, layer, record = shot
    problems = list(record["problems"])
    assert len(problems) == 1 and problems[0].startswith("touched an obstacle at ")
    clearance = np.array(list(record["frames"]["obstacles.clearanceM"]), dtype=float)
    first = float(record["frames"]["seconds"][int(np.flatnonzero(np.nan_to_num(clearance, nan=1.0) < 0)[0])])
    assert 0.03 < first < 0.27  # mid-shot
    fig = plotting.figures(read_review(src, layer))["Body_physics"]
    for ax in fig.axes:
        x, _ = _lines(ax)["a problem's time"]
        assert np.allclose(x, first, atol=0.005)
    assert problems[0] in fig._suptitle.get_text().replace("\n", " ")
    fig.canvas.draw()
    png = tmp_path / "physics.png"
    fig.savefig(png)
    ax, height = fig.axes[-1], fig.canvas.get_width_height()[1]
    x = int(round(ax.transData.transform((first, 0))[0]))
    top, bottom = (int(round(height - ax.transData.transform((0, v))[1])) for v in ax.get_ylim()[::-1])
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    red = np.abs(rgb - np.array([0xd6, 0x27, 0x28])).sum(-1) <= 60
    assert red[top:bottom, x - 1:x + 2].any(axis=1).mean() > 0.1  # a dotted red line down the panel
    away = int(round(ax.transData.transform((first + 0.1, 0))[0]))
    assert not red[top:bottom, away - 1:away + 2].any()
    plotting.pyplot().close(fig)


def test_the_measures_follow_a_layer_sublayered_later(shot, tmp_path):
    """A shot that brings input and layer in 24 time codes (0.2 s) later: the measures move with the
    animation, as the gaze plots' requests do."""
    folder, src, layer, record = shot
    tcps = Sdf.Layer.FindOrOpen(str(src)).timeCodesPerSecond
    shot_layer = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    base = Sdf.Layer.FindOrOpen(str(src))
    for key in ("timeCodesPerSecond", "framesPerSecond", "startTimeCode", "endTimeCode", "upAxis", "metersPerUnit"):
        shot_layer.pseudoRoot.SetInfo(key, base.pseudoRoot.GetInfo(key))
    shot_layer.subLayerPaths[:] = [str(layer), str(src)]
    shot_layer.subLayerOffsets[0] = shot_layer.subLayerOffsets[1] = Sdf.LayerOffset(0.2 * tcps)
    shot_layer.Save()
    c = read_review(tmp_path / "shot.usda", layer).characters[0]
    assert np.allclose(c.physics.seconds, np.array(list(record["frames"]["seconds"])) + 0.2)
    assert c.seconds[0] == pytest.approx(0.2)


@pytest.mark.parametrize("edit, key", [
    (lambda f: f.update(pelvisRatio=Vt.DoubleArray(list(f["pelvisRatio"])[:-1])),
     '["frames"]["pelvisRatio"] holds 10 values for 11'),
    (lambda f: f.pop("seconds"), '["frames"]["seconds"] is missing'),
    (lambda f: f.update({"obstacles.clearanceM": "near"}), '["frames"]["obstacles.clearanceM"] is not a list'),
])
def test_a_malformed_physics_record_is_one_line_naming_the_layer_and_key(shot, tmp_path, capsys, edit, key):
    folder, src, layer, record = shot
    bad = tmp_path / "bad.usda"
    Sdf.Layer.FindOrOpen(str(layer)).Export(str(bad))
    copy = Sdf.Layer.FindOrOpen(str(bad))
    custom = dict(copy.customLayerData)
    physics = {k: dict(v) for k, v in custom["usdgaze:physics"].items()}
    frames = dict(physics[SKEL]["frames"])
    edit(frames)
    physics[SKEL]["frames"] = frames
    custom["usdgaze:physics"] = physics
    copy.customLayerData = custom
    copy.Save()
    del copy  # the command reads the file anew
    capsys.readouterr()
    assert main(["plot", str(src), "--layer", str(bad), "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith(f"usdgaze: error: {bad}: ")
    assert f'customLayerData["usdgaze:physics"]["{SKEL}"]{key}' in err
    assert not (tmp_path / "p").exists() or not any((tmp_path / "p").iterdir())


def test_panels_of_each_task_kind_carry_their_bar():
    """The stones' and the catch's panels (their shots take minutes; the keys are the pass's)."""
    from usdgaze.review import physics_plots
    from usdgaze.review.physics_record import PhysicsMeasures

    t = np.arange(4) * 0.03
    m = PhysicsMeasures(SKEL, t, {"stones.left.stoneDistanceM": np.array([np.nan, 0.01, 0.02, np.nan]),
                                  "stones.right.stoneDistanceM": np.full(4, np.nan),
                                  "catch.handToBallM": np.array([0.5, 0.3, 0.12, 0.2]),
                                  "catch2.handToBallM": np.array([0.5, 0.3, 0.05, 0.2]), "catch.weight": np.ones(4)})
    panels = {p.key: p for p in physics_plots.physics_panels(m)}
    assert list(panels) == ["stones", "catch", "catch2"]
    assert [c.label for c in panels["stones"].curves] == ["left toe to its stone", "right toe to its stone"]
    assert (panels["stones"].limit, panels["catch"].limit, panels["catch2"].limit) == (5.0, 10.0, 10.0)
    assert np.allclose(panels["catch2"].curves[0].values, [50, 30, 5, 20])


def test_problem_times_are_the_times_the_pass_names():
    from usdgaze.review.physics_plots import physics_figure
    from usdgaze.review.physics_record import PhysicsMeasures, problem_times

    said = ["fell at 0.42 s (pelvis below 80% of the reference)", "LeftToe 6.0 cm from its stone over 1.37-1.50 s",
            "a foot 2.3 cm below the ground at 1.50 s (over 2 cm on 3 step(s))",
            "RightToe not down on Stone4 within 0.3 s of 1.20 s (the reference's contact)",
            "catch /Ball: the hand came no nearer than 12 cm to the ball"]
    assert problem_times(said) == [(0.42, 0.42), (1.37, 1.50), (1.50, 1.50), (1.20, 1.20)]
    assert physics_figure(plotting.pyplot(), PhysicsMeasures(SKEL, np.arange(3) * 0.03, {}), "x") is None


def test_a_preview_of_an_eyeless_physics_layer_draws_the_heads_line(shot, tmp_path):
    """CMU has no eyes and the physics pass adds none: the preview draws where the head looks
    (it stopped with an internal error, exit 1, before)."""
    folder, src, layer, record = shot
    gif = tmp_path / "p.gif"
    assert main(["preview", str(src), "--layer", str(layer), "--out", str(gif)]) == 0
    frames = Sdf.Layer.FindOrOpen(str(src))
    assert Image.open(gif).n_frames == int(frames.endTimeCode - frames.startTimeCode) // 5 + 1 or Image.open(gif).n_frames >= 2
