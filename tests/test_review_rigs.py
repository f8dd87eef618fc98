"""Review commands (``plot``, ``preview``) on rigs and stages other than the samples.

- A rig that mirrors a joint off the gaze chain by a negative scale (a hand, an eye): ``apply``
  takes it, and ``plot``/``preview`` of its layer used to stop with exit 1 (an internal error,
  "non-positive determinant ... in a rotation matrix") while reading the rest pose.
- Several characters whose clips differ in length: ``preview`` used to draw every character at the
  first one's sample rows, so a longer first character made it exit 1 (IndexError) and a shorter one
  cut the others' animation short.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageSequence
from pxr import Gf, Sdf, Vt

from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review import analysis
from usdgaze.review.composed import read_review

from . import measure, rig_extras
from . import synthetic as syn

MAP = Path(__file__).resolve().parents[1] / "sample_stages" / "shared_map" / "gaze_map.usda"


def test_plot_and_preview_of_a_rig_with_a_mirrored_hand(tmp_path):
    rig = syn.make_rig(tmp_path / "rig.usda", convention="mixamo", meters_per_unit=0.01, frames=20,
                       mesh=False, walk_speed=0.0, time_codes_per_second=30.0)
    rig_extras.mirror_joint(rig.path, rig.skeleton, rig.animation, rig.leaf["hand_r"])
    layer = tmp_path / "g.usda"
    api.apply(str(rig.path), ["0.1s:30:0"], layer, preview=str(tmp_path / "p.usda"))

    assert main(["plot", str(rig.path), "--layer", str(layer), "--out", str(tmp_path / "plots")]) == 0
    assert (tmp_path / "plots" / "Character_gaze.png").is_file()
    assert main(["preview", str(rig.path), "--layer", str(layer), "--out", str(tmp_path / "p.gif"),
                 "--size", "96"]) == 0
    # What the plot draws is what UsdSkel's FK gives on the composed result.
    review = read_review(str(rig.path), str(layer))
    achieved = analysis.achieved_change(review.characters[0])
    base = measure.posed(str(rig.path), rig.skeleton)
    new = measure.posed(str(tmp_path / "p.usda"), rig.skeleton)
    fwd = measure.character_forward_skel(base, rig.leaf["thigh_l"], rig.leaf["thigh_r"])
    change, _, _ = measure.gaze_change(base, new, fwd, rig.leaf["head"], (rig.leaf["eye_l"], rig.leaf["eye_r"]))
    assert np.abs(measure.wrap(achieved - change)).max() < 0.01


def _two_characters(tmp_path: Path, frames_a: int, frames_b: int) -> Path:
    """/A and /B (``frames_a``/``frames_b`` samples at 30 per second) side by side, sharing the sample map."""
    for name, frames, x in (("A", frames_a, -1.0), ("B", frames_b, 1.0)):
        syn.make_rig(tmp_path / f"{name}.usda", convention="mixamo", frames=frames, mesh=False, walk_speed=0.0,
                     time_codes_per_second=30.0, root_path=f"/{name}")
        syn.edit(tmp_path / f"{name}.usda", lambda layer, x=x, name=name: _offset(layer, f"/{name}", x))
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.timeCodesPerSecond = shot.framesPerSecond = 30.0
    shot.startTimeCode, shot.endTimeCode = 0.0, float(max(frames_a, frames_b) - 1)
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    shot.subLayerPaths[:] = ["A.usda", "B.usda"]
    cls = Sdf.PrimSpec(shot.pseudoRoot, "Map", Sdf.SpecifierClass)
    cls.referenceList.Prepend(Sdf.Reference(str(MAP), "/GazeMap"))
    for name in ("A", "B"):
        over = Sdf.PrimSpec(shot.pseudoRoot, name, Sdf.SpecifierOver)
        over.inheritPathList.Prepend("/Map")
    shot.Save()
    return tmp_path / "shot.usda"


def _offset(layer: Sdf.Layer, root: str, x: float) -> None:
    spec = layer.GetPrimAtPath(root)
    Sdf.AttributeSpec(spec, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(x, 0, 0)
    Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:translate"])


def _gif_frames(path: Path) -> int:
    return sum(1 for _ in ImageSequence.Iterator(Image.open(path)))


def test_preview_draws_characters_of_different_lengths_over_the_whole_shot(tmp_path):
    for long_first in (True, False):
        folder = tmp_path / ("long_first" if long_first else "short_first")
        folder.mkdir()
        frames = (16, 10) if long_first else (10, 16)
        shot = _two_characters(folder, *frames)
        layer = folder / "g.usda"
        report = api.apply(str(shot), ["0.1s:30:0"], layer)
        assert len(report.characters) == 2
        out = folder / "p.gif"
        assert main(["preview", str(shot), "--layer", str(layer), "--out", str(out), "--size", "96",
                     "--fps", "30", "--sheet", str(folder / "s.png"), "--sheet-count", "4"]) == 0
        # 30 output frames per second over the longer clip (16 samples at 30 per second), whichever
        # character comes first.
        assert _gif_frames(out) == 16


def test_validate_reads_the_skeleton_arrays_a_layer_adding_eyes_writes(tmp_path, capsys):
    """The override of a rig without eyes writes the Skeleton's joints, bind and rest transforms: a short
    or NaN one passed validate (exit 0) while plot, preview and apply refused the stage."""
    from pathlib import Path

    import numpy as np
    from usdgaze.console.main import main

    cmu = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_02.usdc"
    out = tmp_path / "gaze.usda"
    assert main(["apply", str(cmu), "--shift", "1s:30:0", "--out", str(out)]) == 0
    assert main(["validate", str(cmu), "--layer", str(out)]) == 0
    layer = Sdf.Layer.FindOrOpen(str(out))
    bind = layer.GetAttributeAtPath("/root/Body/BodySkel.bindTransforms")
    bind.default = Vt.Matrix4dArray(list(bind.default)[:-1])
    rest = layer.GetAttributeAtPath("/root/Body/BodySkel.restTransforms")
    broken = np.array(rest.default)
    broken[3, 0, 0] = np.nan
    rest.default = Vt.Matrix4dArray.FromNumpy(broken)
    layer.Save()
    capsys.readouterr()
    assert main(["validate", str(cmu), "--layer", str(out)]) == 3
    said = capsys.readouterr().out
    n = len(layer.GetAttributeAtPath("/root/Body/BodySkel.joints").default)
    assert f"bindTransforms: {n - 1} entries, expected {n} (one per joint)" in said, said
    assert "restTransforms: NaN or infinite values" in said, said


def test_preview_of_a_character_lying_down(tmp_path, capsys):
    """A rig laid on its back by its parent's transform (a character in bed): ``apply`` and ``plot``
    took it, ``preview`` stopped with exit 1 (an internal error: it sized the figure by the head's
    height above the floor, ~0, so no bone was short enough to draw and the camera framed nothing)."""
    from usdgaze.review import render

    rig = syn.make_rig(tmp_path / "rig.usda", frames=24, time_codes_per_second=24.0, mesh=False, walk_speed=0.0,
                       root_path="/Bed/Character")

    def lay_down(layer):
        spec = layer.GetPrimAtPath("/Bed")
        Sdf.AttributeSpec(spec, "xformOp:rotateX", Sdf.ValueTypeNames.Float).default = -90.0
        Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:rotateX"])
        layer.defaultPrim = "Bed"
    syn.edit(rig.path, lay_down)
    base = measure.posed(str(rig.path), rig.skeleton)
    spine = base.position(rig.leaf["head"]) - base.position(rig.leaf["pelvis"])
    assert np.abs(spine[:, 1]).max() < 0.1 * np.linalg.norm(spine, axis=1).min()  # lying: the spine is level

    layer = tmp_path / "g.usda"
    assert main(["apply", str(rig.path), "--shift", "0.2s:30:0", "--out", str(layer)]) == 0
    size, count = 120, 4
    sheet = tmp_path / "s.png"
    capsys.readouterr()
    assert main(["preview", str(rig.path), "--layer", str(layer), "--out", str(sheet), "--size", str(size),
                 "--sheet-count", str(count)]) == 0, capsys.readouterr().err
    rgb = np.asarray(Image.open(sheet).convert("RGB")).astype(int)

    def near(colours):
        return np.any([np.abs(rgb - np.array(c)).sum(-1) <= 6 for c in colours], axis=0)

    bodies = near([render.shade(b, k / render.SHADES) for b in (render.BASE_BODY, render.GAZE_BODY)
                   for k in range(render.SHADES + 1)])
    h = size + render.LABEL_H
    for i in range(count):
        for panel in range(2):  # base and gaze, side by side; four tiles in a row
            x0 = i * 2 * size + panel * size
            tile = bodies[render.LABEL_H:h, x0 + 2:x0 + size - 2]
            assert tile.sum() > 300, (i, panel, tile.sum())  # a figure is drawn in every panel


def test_plot_of_a_one_frame_clip_shows_its_values(tmp_path):
    """A still (one frame): ``plot`` wrote its panels empty, every curve a line of one point, which
    matplotlib does not draw; the requested 30 deg and the eye angles at that frame were not seen."""
    from usdgaze.review import plotting

    rig = syn.make_rig(tmp_path / "still.usda", frames=1, time_codes_per_second=24.0, mesh=False, walk_speed=0.0)
    layer = tmp_path / "g.usda"
    assert main(["apply", str(rig.path), "--shift", "0:30:0", "--out", str(layer)]) == 0
    assert main(["plot", str(rig.path), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0
    png = tmp_path / "p" / "Character_gaze.png"
    fig = plotting.figures(read_review(str(rig.path), str(layer)))["Character_gaze"]
    fig.canvas.draw()
    ax, height = fig.axes[0], fig.canvas.get_width_height()[1]
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    yaw = np.abs(rgb - np.array([int(plotting.YAW_COLOUR[i:i + 2], 16) for i in (1, 3, 5)])).sum(-1) <= 40
    x, y = ax.transData.transform((0.0, 30.0))  # the yaw asked for, at the one frame
    x, y = int(round(x)), int(round(height - y))
    assert yaw[y - 2:y + 3, x - 2:x + 3].any()
