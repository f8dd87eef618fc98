"""``usdgaze plot``: what the PNGs show, checked against UsdSkel's own numbers, pixel by pixel."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pxr import Sdf, Usd, UsdSkel

from usdgaze import api
from usdgaze.console.main import main
from usdgaze.review import plotting
from usdgaze.review.composed import read_review

from . import measure

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
SHIFT_S = 2.0


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plot")
    layer = folder / "g.usdc"
    api.apply(CMU, [f"{SHIFT_S}s:60:0"], layer)
    return folder, layer


def _hex(colour: str) -> np.ndarray:
    return np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])


def _mask(png: Path, colour: str, tol: int = 40) -> np.ndarray:
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    return np.abs(rgb - _hex(colour)).sum(-1) <= tol


def composed_root(layer: Path | None, base: Path = CMU) -> Sdf.Layer:
    """[layer, base] under a root with the input's timing (else USD rescales the samples)."""
    src = Sdf.Layer.FindOrOpen(str(CMU))
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.timeCodesPerSecond, root.framesPerSecond = src.timeCodesPerSecond, src.framesPerSecond
    root.startTimeCode, root.endTimeCode = src.startTimeCode, src.endTimeCode
    for key in ("upAxis", "metersPerUnit"):  # a stage's units are its root layer's
        root.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    root.subLayerPaths = [str(layer), str(base)] if layer is not None else [str(base)]
    return root


def _head_turn_by_usd(layer: Path) -> tuple[np.ndarray, np.ndarray]:
    """Seconds since the shift and the head joint's rotation since then, from the composed
    SkelAnimation's own rotations against the input's (USD values, no usdgaze math)."""
    root = composed_root(layer)
    composed, base = Usd.Stage.Open(root), Usd.Stage.Open(str(CMU))
    anim_path = "/root/Body/Animation" if composed.GetPrimAtPath("/root/Body/Animation") else None
    anims = [p for p in composed.Traverse() if p.IsA(UsdSkel.Animation)]
    anim_path = anim_path or str(anims[0].GetPath())
    a_gaze, a_base = (UsdSkel.Animation(s.GetPrimAtPath(anim_path)) for s in (composed, base))
    joints = [str(j) for j in a_base.GetJointsAttr().Get()]
    head = next(i for i, j in enumerate(joints) if j.rsplit("/", 1)[-1] == "Head")
    times = np.array(a_base.GetRotationsAttr().GetTimeSamples())
    seconds = (times - base.GetStartTimeCode()) / base.GetTimeCodesPerSecond()

    def quats(anim):
        q = np.array([np.asarray(anim.GetRotationsAttr().Get(t))[head] for t in times], dtype=float)  # x y z w
        return q / np.linalg.norm(q, axis=1, keepdims=True)

    def mul(a, b):  # Hamilton product, (x, y, z, w)
        ax, ay, az, aw = np.moveaxis(a, -1, 0)
        bx, by, bz, bw = np.moveaxis(b, -1, 0)
        return np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                         aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], -1)

    conj = np.array([-1, -1, -1, 1.0])
    disp = mul(quats(a_gaze), quats(a_base) * conj)
    after = seconds >= SHIFT_S
    turned = mul(disp[after], disp[after][0] * conj)
    angle = np.degrees(2 * np.arccos(np.clip(np.abs(turned[:, 3]), 0, 1)))
    return seconds[after] - seconds[after][0], angle


def test_cascade_png_shows_the_head_overshooting_at_the_time_usd_says(run):
    folder, layer = run
    assert main(["plot", str(CMU), "--layer", str(layer), "--out", str(folder / "plots")]) == 0
    png = folder / "plots" / "Body_cascade.png"
    elapsed, angle = _head_turn_by_usd(layer)
    k = int(np.argmax(angle))
    peak_t, peak, final = elapsed[k], angle[k], angle[-1]
    assert peak > final + 0.5  # the head overshoots and settles back

    # Pixel mapping of that very figure (matplotlib's layout, same size and dpi as the PNG).
    fig = plotting.figures(read_review(CMU, layer))["Body_cascade"]
    fig.canvas.draw()
    ax = fig.axes[0]
    width, height = fig.canvas.get_width_height()
    assert Image.open(png).size == (width, height)

    def pixel(t, v):
        x, y = ax.transData.transform((t, v))
        return int(round(x)), int(round(height - y))

    head = _mask(png, plotting.ROLE_COLOURS[4])
    x_peak, y_peak = pixel(peak_t, peak)
    x_final, y_final = pixel(elapsed[-5], final)
    assert y_final - y_peak >= 3  # the overshoot is visible

    def top(x):
        rows = np.flatnonzero(head[:, x - 1:x + 2].any(axis=1))
        return rows.min()

    # The drawn head curve reaches the overshoot level at the peak time, and only then.
    assert abs(top(x_peak) - y_peak) <= 2
    assert abs(top(x_final) - y_final) <= 2
    x_early, _ = pixel(0.5 * peak_t, 0.0)
    assert top(x_early) > y_peak + 3
    columns = [x for x in range(pixel(0.0, 0)[0] + 2, x_final) if head[:, x].any()]
    crossing = [x for x in columns if head[: y_peak + 2, x].any()]
    assert crossing and abs(np.mean(crossing) - x_peak) <= 0.12 * (x_final - pixel(0, 0)[0])


def test_eye_plot_draws_the_limits_the_layer_records(run, tmp_path):
    folder, layer = run
    data = Sdf.Layer.FindOrOpen(str(layer)).customLayerData["usdgaze"]
    assert dict(data["eyeRange"]) == {"yaw": 44.2, "up": 27.7, "down": 47.1}  # what the pass used
    edited = tmp_path / "edited.usda"
    copy = Sdf.Layer.FindOrOpen(str(layer))
    copy.Export(str(edited))
    e = Sdf.Layer.FindOrOpen(str(edited))
    record = dict(e.customLayerData["usdgaze"])
    record["eyeRange"] = {"yaw": 33.0, "up": 20.0, "down": 35.0}
    e.customLayerData = {"usdgaze": record}
    e.Save()
    assert main(["plot", str(CMU), "--layer", str(edited), "--out", str(tmp_path / "p")]) == 0
    png = tmp_path / "p" / "Body_eyes.png"
    fig = plotting.figures(read_review(CMU, edited))["Body_eyes"]
    fig.canvas.draw()
    ax, height = fig.axes[0], fig.canvas.get_width_height()[1]
    x0, _ = ax.transData.transform((ax.get_xlim()[0], 0))
    x1, _ = ax.transData.transform((ax.get_xlim()[1], 0))
    for value, colour in ((33.0, plotting.YAW_COLOUR), (-33.0, plotting.YAW_COLOUR), (20.0, plotting.PITCH_COLOUR),
                          (-35.0, plotting.PITCH_COLOUR), (44.2, None)):
        y = int(round(height - ax.transData.transform((0, value))[1]))
        if colour is None:  # the default limit is not drawn any more
            assert not _mask(png, plotting.YAW_COLOUR, 20)[y - 1:y + 2, int(x0) + 5:int(x1) - 5].mean(axis=1).max() > 0.4
            continue
        band = _mask(png, colour, 20)[y - 1:y + 2, int(x0) + 5:int(x1) - 5]
        assert band.any(axis=0).mean() > 0.5, value  # a dashed line across the panel


def test_achieved_gaze_read_back_matches_usdskel_fk(run):
    folder, layer = run
    review = read_review(CMU, layer)
    c = review.characters[0]
    from usdgaze.review import analysis

    root = composed_root(layer)
    path = folder / "composed.usda"
    root.Export(str(path))
    p = measure.posed(str(path), c.skeleton)
    fwd = measure.character_forward_skel(p, "LeftHip", "RightHip")
    sight = measure.sight_line(p, "LeftEye", "RightEye", measure.local_forward(p, "LeftEye", fwd),
                               measure.local_forward(p, "RightEye", fwd))
    _, mine = analysis.sight(c, c.gaze)
    assert measure.angle_between(sight, mine).max() < 0.01
    speed = analysis.sight_speed(c)
    step = measure.angle_between(sight[1:], sight[:-1]) / np.diff(c.seconds)
    assert np.allclose(speed[1:-1], 0.5 * (step[1:] + step[:-1]), atol=1e-3)


def test_attention_panel_shows_which_object_the_point_of_sight_is_on(tmp_path):
    """Array-level panels for look-at and attention runs (their readers come with those passes)."""
    plt = plotting.pyplot()
    t = np.linspace(0.0, 4.0, 401)
    a = np.column_stack([np.ones_like(t), np.zeros_like(t), np.zeros_like(t)])
    b = np.column_stack([-np.ones_like(t), np.zeros_like(t), np.zeros_like(t)])
    on_a = (t < 1.5)[:, None]
    sight = np.where(on_a, a, b) + 0.01
    unc = {"ball": np.where(t < 1.5, 0.1, 0.1 + (t - 1.5)), "cup": np.where(t < 1.5, 0.1 + t, 0.2)}
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6, 4))
    plotting.panel_attention(top, bottom, t, sight, {"ball": a, "cup": b}, unc, "test")
    fig.canvas.draw()
    png = tmp_path / "att.png"
    fig.savefig(png)
    height = fig.canvas.get_width_height()[1]
    for name, colour, row in (("ball", plotting.JOINT_COLOURS[0], 0), ("cup", plotting.JOINT_COLOURS[1], 1)):
        mask = _mask(png, colour, 20)
        y = int(round(height - top.transData.transform((0, row))[1]))
        for when, expected in ((0.5, name == "ball"), (3.0, name == "cup")):
            x = int(round(top.transData.transform((when, row))[0]))
            assert mask[y - 1:y + 2, x].any() == expected, (name, when)
    plt.close(fig)


def test_target_error_panel_draws_each_target_at_its_error(tmp_path):
    plt = plotting.pyplot()
    t = np.linspace(0.0, 3.0, 301)
    errors = {"ball": np.where(t < 1.0, 30.0, 2.0), "cup": np.full_like(t, 12.0)}
    fig, ax = plt.subplots(figsize=(6, 3))
    plotting.panel_target_error(ax, t, errors, "test")
    fig.canvas.draw()
    png = tmp_path / "err.png"
    fig.savefig(png)
    height = fig.canvas.get_width_height()[1]
    for (name, err), colour in zip(errors.items(), plotting.JOINT_COLOURS):
        mask = _mask(png, colour, 20)
        for when in (0.5, 2.0):
            x, y = ax.transData.transform((when, err[np.searchsorted(t, when)]))
            y = int(round(height - y))
            assert mask[y - 2:y + 3, int(round(x))].any(), (name, when)
    plt.close(fig)


@pytest.mark.parametrize("how", ["schedule", "flags"])
def test_target_error_plot_of_a_look_matches_usdskel(tmp_path, how):
    """The look the pass was given: the SkelRoot's schedule (no flags), or --look-at, which the
    layer records (the schedule is then not what ran)."""
    from pxr import Gf, UsdGeom

    from usdgaze.passes.requests import DirectiveRequest
    from usdgaze.usd.schedule import write_schedule

    shot = tmp_path / "shot.usda"
    root = composed_root(None)
    stage = Usd.Stage.Open(root)
    UsdGeom.Xform.Define(stage, "/Ball").AddTranslateOp().Set(Gf.Vec3d(100.0, 150.0, 0.0))
    write_schedule(stage.GetPrimAtPath("/root/Body"), [DirectiveRequest("look", 241.0, target="/Ball")])
    root.Export(str(shot))
    layer = tmp_path / "g.usdc"
    if how == "schedule":
        api.apply(shot, [], layer)
    else:
        write_schedule(stage.GetPrimAtPath("/root/Body"), [DirectiveRequest("look", 1.0, target="/Ball")])
        root.Export(str(shot))  # a schedule that must not be plotted: the flags win
        api.apply(shot, [], layer, look_at=["/Ball@241"])
    assert main(["plot", str(shot), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0
    assert [look.label for look in read_review(shot, layer).characters[0].looks] == ["/Ball from 2.00 s"]
    png = tmp_path / "p" / "Body_targets.png"
    fig = plotting.figures(read_review(shot, layer))["Body_targets"]
    fig.canvas.draw()
    ax, height = fig.axes[0], fig.canvas.get_width_height()[1]

    composed = composed_root(layer, shot)
    composed.Export(str(tmp_path / "composed.usda"))
    p = measure.posed(str(tmp_path / "composed.usda"), "/root/Body/BodySkel")
    fwd = measure.character_forward_skel(p, "LeftHip", "RightHip")
    sight = measure.sight_line(p, "LeftEye", "RightEye", measure.local_forward(p, "LeftEye", fwd),
                               measure.local_forward(p, "RightEye", fwd))
    origin = 0.5 * (p.position("LeftEye") + p.position("RightEye"))
    to_ball = np.array([100.0, 150.0, 0.0]) - origin
    error = measure.angle_between(sight, to_ball / np.linalg.norm(to_ball, axis=1, keepdims=True))
    seconds = (p.times - p.times[0]) / Usd.Stage.Open(str(shot)).GetTimeCodesPerSecond()
    mask = _mask(png, plotting.JOINT_COLOURS[0], 20)
    # Rows while the eyes travel to the ball (an error near zero would lie on the axis line).
    travelling = np.flatnonzero((seconds >= 2.0) & (error > 2.0))
    assert len(travelling) >= 3, error[seconds >= 2.0][:40]
    for row in travelling[[0, len(travelling) // 2, -1]]:
        x, y = ax.transData.transform((seconds[row], error[row]))
        x, y = int(round(x)), int(round(height - y))
        assert mask[y - 2:y + 3, x].any(), (row, error[row])
    x_before, _ = ax.transData.transform((1.0, 0.0))  # the look begins at 2 s: nothing drawn before
    assert not mask[:, int(x_before)].any()


def test_attention_plot_of_a_real_attend_run(tmp_path):
    """``usdgaze attend`` on the shipped two-ball stage, then ``plot``: the band shows the object
    nearest the point of sight, as the layer's own samples and USD's transforms say."""
    from pxr import UsdGeom

    stage_path = CMU.parents[1] / "attend" / "two_balls.usda"
    layer = tmp_path / "attend.usdc"
    assert main(["attend", str(stage_path), "--out", str(layer)]) == 0
    assert main(["plot", str(stage_path), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0
    review = read_review(stage_path, layer)
    name = plotting.names(review)[0]
    png = tmp_path / "p" / f"{name}_attention.png"
    fig = plotting.figures(review)[f"{name}_attention"]
    fig.canvas.draw()
    top, height = fig.axes[0], fig.canvas.get_width_height()[1]

    stage = Usd.Stage.Open(str(stage_path))
    out = Sdf.Layer.FindOrOpen(str(layer))
    sight_path = next(p for p in [s.path for s in out.rootPrims["UsdGazeAttend"].nameChildren]).AppendProperty(
        "gaze:attend:pointOfSight")
    objects = sorted(str(p.GetPath()) for p in stage.Traverse() if p.HasAPI("GazeObjectAPI"))
    assert len(objects) == 2
    times = out.ListTimeSamplesForPath(sight_path)
    tcps, start = stage.GetTimeCodesPerSecond(), stage.GetStartTimeCode()
    checked = 0
    for t in times[5::10]:
        point = np.array(out.QueryTimeSample(sight_path, t), dtype=float)
        cache = UsdGeom.XformCache(Usd.TimeCode(t))
        where = [np.array(cache.GetLocalToWorldTransform(stage.GetPrimAtPath(o)).ExtractTranslation()) for o in objects]
        nearest = int(np.argmin([np.linalg.norm(point - w) for w in where]))
        gap = abs(np.linalg.norm(point - where[0]) - np.linalg.norm(point - where[1]))
        if gap < 0.05:  # about equally near: either band may be drawn at the switch
            continue
        x = int(round(top.transData.transform(((t - start) / tcps, 0))[0]))
        for row in (0, 1):
            y = int(round(height - top.transData.transform((0, row))[1]))
            drawn = _mask(png, plotting.JOINT_COLOURS[row], 20)[y - 1:y + 2, x - 1:x + 2].any()
            assert drawn == (row == nearest), (t, row, nearest)
        checked += 1
    assert checked >= 3
    # An attend layer requests no change of the line of sight: its gaze panel drew a dashed "requested 0"
    # under the planner's glances, which read as misses of a request; it draws the change alone.
    gaze_ax = plotting.figures(review)[f"{name}_gaze"].axes[0]
    labels = [line.get_label() for line in gaze_ax.get_lines()]
    assert labels == ["yaw achieved (FK)", "pitch achieved (FK)"], labels
    assert "no shifts requested" in gaze_ax.get_title() and "requested vs" not in gaze_ax.get_title()
