"""``usdgaze preview``: the drawn head and line of sight turn by the angles UsdSkel's FK gives; the
contact sheet differs from the base exactly where the gaze changed; GIF and MP4 hold every frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pxr import Gf, Usd, UsdGeom

from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review import preview as pv
from usdgaze.review import render
from usdgaze.review.composed import composed_stage, read_review

from . import measure
from .test_review_plot import CMU, composed_root

SHIFT_S = 3.0
SKELETON = "/root/Body/BodySkel"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("preview")
    layer = folder / "g.usdc"
    api.apply(CMU, [f"{SHIFT_S}s:60:0"], layer)
    root = composed_root(layer)
    root.Export(str(folder / "composed.usda"))
    return folder, layer


def _fk(folder: Path):
    """UsdSkel's world transforms of the composed result, with the head and eye axes at rest."""
    p = measure.posed(str(folder / "composed.usda"), SKELETON)
    fwd = measure.character_forward_skel(p, "LeftHip", "RightHip")
    head = p.axis("Head", measure.local_forward(p, "Head", fwd))
    sight = measure.sight_line(p, "LeftEye", "RightEye", measure.local_forward(p, "LeftEye", fwd),
                               measure.local_forward(p, "RightEye", fwd))
    return p, head, sight


def _drawn_angle(panel: np.ndarray, colour) -> float:
    """Image angle (deg, counter-clockwise, x right) of the line drawn in ``colour``, pointing to its
    tip (the end carrying a dot: more pixels past the midpoint)."""
    ys, xs = np.nonzero(np.all(panel == np.array(colour), axis=-1))
    assert len(xs) > 30, "line not drawn"
    pts = np.column_stack([xs, -ys]).astype(float)
    centred = pts - pts.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    s = centred @ axis
    if s.mean() - 0.5 * (s.min() + s.max()) < 0:  # the dot at the tip pulls the mean toward it
        axis = -axis
    return float(np.degrees(np.arctan2(axis[1], axis[0])))


def test_top_view_head_and_line_of_sight_turn_by_the_fk_angles(run):
    folder, layer = run
    p, head, sight = _fk(folder)
    seconds = (p.times - p.times[0]) / 120.00479955795427
    rows = [int(np.searchsorted(seconds, SHIFT_S - 0.3)), int(np.searchsorted(seconds, SHIFT_S + 2.0))]
    review = read_review(CMU, layer)
    stage, _ = composed_stage(CMU, layer)
    opts = pv.PreviewOptions(camera="top", layout="side-by-side", size=360)
    scene = pv.build_scene(review, opts, stage, times=review.characters[0].seconds[rows])
    frames = [np.asarray(scene.frame(i).convert("RGB"))[render.LABEL_H:, opts.size:] for i in range(2)]

    def azimuth(d):  # seen from above (Y up: x right, -z up the screen as the camera is fixed)
        return measure.az_el(d, p.up)[:, 0]

    for colour, direction in ((render.NOSE, head), (render.GAZE_SIGHT, sight)):
        drawn = [_drawn_angle(f, colour) for f in frames]
        fk = azimuth(direction[rows])
        turn_drawn = measure.wrap(np.array([drawn[1] - drawn[0]]))[0]
        turn_fk = measure.wrap(np.array([fk[1] - fk[0]]))[0]
        print(colour, turn_drawn, turn_fk)
        assert abs(turn_fk) > 5.0  # it turned (the shift, on top of the walk's own turning)
        assert abs(turn_drawn - turn_fk) < 2.5, (colour, turn_drawn, turn_fk)


def test_contact_sheet_panels_differ_from_the_base_only_where_the_gaze_changed(run, tmp_path):
    folder, layer = run
    sheet = tmp_path / "sheet.png"
    assert main(["preview", str(CMU), "--layer", str(layer), "--out", str(sheet), "--camera", "side",
                 "--size", "200", "--sheet-count", "8"]) == 0
    image = np.asarray(Image.open(sheet).convert("RGB"))
    cols, size = 4, 200
    h = size + render.LABEL_H
    seconds = np.linspace(0.0, read_review(CMU, layer).characters[0].seconds[-1], 8)
    for i, t in enumerate(seconds):
        r, c = divmod(i, cols)
        tile = image[r * h + render.LABEL_H:(r + 1) * h - 1, c * 2 * size:(c + 1) * 2 * size]
        # Where each panel has ink (the bodies are drawn in different colours, base grey, gaze orange).
        ink = ~np.all((tile == render.BACKGROUND) | (tile == render.GRID), axis=-1)
        changed = (ink[:, 1:size - 1] != ink[:, size + 1:2 * size - 1]).mean()  # inside the tile borders
        if t < SHIFT_S:
            assert changed < 0.002, (t, changed)  # identical figures before the shift
        elif t > SHIFT_S + 1.0:
            assert changed > 0.01, (t, changed)  # the turned head and line of sight show


def test_gif_and_mp4_hold_every_frame_and_leave_inputs_alone(run, tmp_path):
    import imageio.v3 as iio

    folder, layer = run
    before = {f: (measure.sha256(f), f.stat().st_mode) for f in (CMU, layer)}
    gif, mp4 = tmp_path / "p.gif", tmp_path / "p.mp4"
    for out in (gif, mp4):
        assert main(["preview", str(CMU), "--layer", str(layer), "--out", str(out), "--fps", "6",
                     "--size", "96", "--layout", "overlay"]) == 0
    duration = read_review(CMU, layer).characters[0].seconds[-1]
    expected = int(np.floor(duration * 6 + 1e-6)) + 1
    frames = iio.imread(gif, index=None)
    assert len(frames) == expected
    video = iio.imread(mp4, index=None, plugin="FFMPEG")
    assert len(video) == expected and video.shape[1:3] == (96 + render.LABEL_H, 96)
    k = int(SHIFT_S * 6) - 2
    assert np.any(frames[k] != frames[-1])  # it moves
    assert {f: (measure.sha256(f), f.stat().st_mode) for f in (CMU, layer)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.gif", "p.mp4"]  # nothing left behind


def test_camera_prim_projects_the_head_where_a_pinhole_says(run, tmp_path):
    folder, layer = run
    stage_path = tmp_path / "shot.usda"
    root = composed_root(None)
    stage = Usd.Stage.Open(root)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, 100.0, 600.0))
    cam.GetFocalLengthAttr().Set(35.0)
    cam.GetHorizontalApertureAttr().Set(36.0)
    cam.GetVerticalApertureAttr().Set(36.0)
    root.Export(str(stage_path))
    review = read_review(stage_path, layer)
    composed, _ = composed_stage(stage_path, layer)
    size = 200
    opts = pv.PreviewOptions(camera="/Cam", layout="overlay", size=size)
    c = review.characters[0]
    rows = [10, 400]
    scene = pv.build_scene(review, opts, composed, times=c.seconds[rows])
    p = measure.posed(str(folder / "composed.usda"), SKELETON)
    for i, row in enumerate(rows):
        x, y, z = p.position("Head")[row] - np.array([0.0, 100.0, 600.0])  # camera looks down -Z
        f = 35.0 / 36.0 * size  # focal length over aperture, in pixels
        expected = np.array([size / 2 + f * x / -z, size / 2 - f * y / -z])
        drawn = scene.projected[0][1].joints[i, c.chain.head, :2]  # gaze figure
        assert np.allclose(drawn, expected, atol=1.0), (drawn, expected)
        panel = np.asarray(scene.frame(i).convert("RGB"))[render.LABEL_H:]
        u, v = np.round(expected).astype(int)
        assert (np.abs(panel[v - 2:v + 3, u - 2:u + 3].astype(int) - np.array(render.BACKGROUND)).sum(-1) > 30).any()


def test_bad_preview_requests_are_one_line(run, tmp_path):
    folder, layer = run
    for extra, expected in ((["--out", str(tmp_path / "x.avi")], "must end in"),
                            (["--out", str(tmp_path / "x.gif"), "--camera", "/Nope"], "no Camera prim"),
                            (["--out", str(tmp_path / "x.gif"), "--fps", "0"], "--fps")):
        assert main(["preview", str(CMU), "--layer", str(layer), *extra]) == 2
    assert not any(tmp_path.iterdir())


def test_a_camera_facing_away_draws_no_figure_and_a_nan_camera_is_one_line(run, tmp_path, capsys):
    """Points behind a camera prim were divided by their negative depth and drawn mirrored, upside
    down; a camera with a NaN translate crashed (exit 1) after a dozen USD warnings."""
    folder, layer = run
    stage_path = tmp_path / "shot.usda"
    root = composed_root(None)
    stage = Usd.Stage.Open(root)
    UsdGeom.Camera.Define(stage, "/Away").AddTranslateOp().Set(Gf.Vec3d(0.0, 100.0, -600.0))  # looks down -Z, away
    UsdGeom.Camera.Define(stage, "/Broken").AddTranslateOp().Set(Gf.Vec3d(float("nan"), 100.0, 600.0))
    root.Export(str(stage_path))
    review = read_review(stage_path, layer)
    composed, _ = composed_stage(stage_path, layer)
    scene = pv.build_scene(review, pv.PreviewOptions(camera="/Away", layout="overlay", size=200), composed,
                           times=review.characters[0].seconds[[10, 400]])
    for i in range(2):
        assert np.isnan(scene.projected[0][1].joints[i, :, :2]).all()
        panel = np.asarray(scene.frame(i).convert("RGB"))[render.LABEL_H:].astype(int)
        body = [np.abs(panel - np.array(c)).sum(-1) <= 30 for c in (render.BASE_BODY, render.GAZE_BODY)]
        assert not np.any(body)
    capsys.readouterr()
    assert main(["preview", str(stage_path), "--layer", str(layer), "--out", str(tmp_path / "x.png"),
                 "--camera", "/Broken"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not finite" in err[0], err
    assert not (tmp_path / "x.png").exists()


def test_an_odd_size_mp4_and_a_gif_faster_than_gifs_play(run, tmp_path, capsys):
    """H.264's 4:2:0 needs even sizes (``--size 65`` failed in ffmpeg, six lines of its output); a GIF
    at 240 fps had 0 cs delays (played at ~10 fps): refused above 50."""
    import imageio.v3 as iio

    folder, layer = run
    mp4 = tmp_path / "odd.mp4"
    assert main(["preview", str(CMU), "--layer", str(layer), "--out", str(mp4), "--fps", "4", "--size", "65",
                 "--layout", "overlay"]) == 0
    video = iio.imread(mp4, index=None, plugin="FFMPEG")
    assert video.shape[1] % 2 == 0 and video.shape[2] % 2 == 0 and video.shape[2] == 66
    capsys.readouterr()
    assert main(["preview", str(CMU), "--layer", str(layer), "--out", str(tmp_path / "fast.gif"), "--fps", "60"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "at most 50 frames per second" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["odd.mp4"]
