"""The usdview Gaze menu on a real stage, through a documented stand-in of usdview's API."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Plug, Usd, UsdGeom, UsdSkel

from usdgaze import api
from usdgaze.review import usdview
from usdgaze.usd.plugin import plugin_dir

from . import measure
from .test_review_plot import CMU
from .usdview_standin import PlugRegistryStandIn, UIBuilderStandIn, UsdviewApiStandIn, install_plugin_module

SKELETON = "/root/Body/BodySkel"


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    folder = tmp_path_factory.mktemp("usdview")
    api.apply(CMU, ["2s:60:0"], folder / "g.usdc", preview=folder / "preview.usda")
    return folder


def _open(shot: Path):
    stage = Usd.Stage.Open(str(shot / "preview.usda"))
    return stage, UsdviewApiStandIn(stage)


def _head_rotation(stage, frame: float) -> np.ndarray:
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/root/Body/Animation") or
                             next(p for p in stage.Traverse() if p.IsA(UsdSkel.Animation)))
    joints = [str(j).rsplit("/", 1)[-1] for j in anim.GetJointsAttr().Get()]
    return np.asarray(anim.GetRotationsAttr().Get(frame))[joints.index("Head")]


def test_toggle_mutes_and_unmutes_the_gaze_layer(shot):
    stage, view = _open(shot)
    before = measure.sha256(shot / "preview.usda"), measure.sha256(shot / "g.usdc")
    base_head = _head_rotation(Usd.Stage.Open(str(CMU)), 600.0)
    assert not np.allclose(_head_rotation(stage, 600.0), base_head)
    usdview.toggle_gaze_layer(view)
    assert [stage.IsLayerMuted(l.identifier) for l in usdview.gaze_layers(stage)] == [True]
    assert np.array_equal(_head_rotation(stage, 600.0), base_head)  # muting gives back the input exactly
    assert "muted g.usdc" in view.status[-1]
    usdview.toggle_gaze_layer(view)
    assert not np.allclose(_head_rotation(stage, 600.0), base_head) and "unmuted" in view.status[-1]
    assert (measure.sha256(shot / "preview.usda"), measure.sha256(shot / "g.usdc")) == before


def test_select_chain_joints_marks_where_usdskel_puts_them(shot):
    stage, view = _open(shot)
    usdview.select_chain_joints(view)
    selected = view.selectedPrims
    assert len(selected) == 9  # Hips, lowerback, Chest, Chest2, lowerneck, Neck, Head, both eyes
    p = measure.posed(str(shot / "preview.usda"), SKELETON)
    for prim in selected:
        leaf = prim.GetName().split("_", 1)[1]
        xf = UsdGeom.Xformable(prim)
        for row in (0, 300, 700):
            t = float(p.times[row])
            marker = np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(t)).ExtractTranslation())
            assert np.allclose(marker, p.position(leaf)[row], atol=1e-3), (leaf, t)
    assert not stage.GetRootLayer().dirty  # only the session layer holds the markers


def test_lines_of_sight_follow_the_eyes_and_toggle_off(shot):
    stage, view = _open(shot)
    usdview.show_lines_of_sight(view)
    curve = UsdGeom.BasisCurves(stage.GetPrimAtPath(f"{usdview.LINES}/Character0"))
    assert curve
    p = measure.posed(str(shot / "preview.usda"), SKELETON)
    fwd = measure.character_forward_skel(p, "LeftHip", "RightHip")
    sight = measure.sight_line(p, "LeftEye", "RightEye", measure.local_forward(p, "LeftEye", fwd),
                               measure.local_forward(p, "RightEye", fwd))
    for row in (100, 500, 900):
        a, b = np.asarray(curve.GetPointsAttr().Get(float(p.times[row])), dtype=float)
        d = (b - a) / np.linalg.norm(b - a)
        assert measure.angle_between(d[None], sight[row][None])[0] < 0.05
        assert abs(np.linalg.norm(b - a) * UsdGeom.GetStageMetersPerUnit(stage) - 2.0) < 1e-3
    usdview.show_lines_of_sight(view)
    assert not stage.GetPrimAtPath(usdview.LINES)


def test_summary_prints_the_map_and_the_schedule(shot, capsys):
    stage, view = _open(shot)
    text = usdview.summary(view)
    assert "schedule /root/Body: --shift 2s:60:0" in text
    assert "eyeRange: yaw 44.2, up 27.7, down 47.1" in text
    assert "/root/Body: no GazeMapAPI (the built-in map is used)" in text
    assert "head=Head" in text and "leftEye=LeftEye" in text
    assert text in capsys.readouterr().out
    # A schedule on the SkelRoot is listed too (authored in the session layer only).
    from usdgaze.passes.requests import DirectiveRequest
    from usdgaze.usd.schedule import write_schedule

    stage.SetEditTarget(stage.GetSessionLayer())
    # The schedule's time codes are mapped as time samples are: a session layer authoring no
    # timeCodesPerSecond counts in USD's fallback 24 (a sample at 240 there is at 1200 on this stage).
    stage.GetSessionLayer().timeCodesPerSecond = stage.GetRootLayer().timeCodesPerSecond
    write_schedule(stage.GetPrimAtPath("/root/Body"), [DirectiveRequest("shift", 240.0, yaw=30.0)])
    assert "GazeScheduleAPI: 240:30:0" in usdview.summary(view)


def test_plugin_container_builds_the_gaze_menu_from_plug_info(shot):
    # usdview finds the container through plugInfo.json: a Python plugin whose type derives from
    # usdview's PluginContainer.
    info = json.loads("\n".join(l for l in (plugin_dir() / "plugInfo.json").read_text().splitlines()
                                if not l.startswith("#")))
    entry = next(p for p in info["Plugins"] if p["Name"] == "usdgaze.review.usdview_plugin")
    assert entry["Type"] == "python"
    assert entry["Info"]["Types"]["usdgaze.review.usdview_plugin.GazePluginContainer"]["bases"] == [
        "pxr.Usdviewq.plugin.PluginContainer"]
    assert Plug.Registry().GetPluginWithName("usdgaze.review.usdview_plugin") is not None
    install_plugin_module()
    from usdgaze.review.usdview_plugin import GazePluginContainer

    stage, view = _open(shot)
    registry, builder = PlugRegistryStandIn(), UIBuilderStandIn()
    container = GazePluginContainer()
    container.registerPlugins(registry, view)
    container.configureView(registry, builder)
    menu = builder.menus["Gaze"]
    assert [i.displayName for i in menu.items] == [
        "Toggle Gaze Layer (mute/unmute)", "Select Gaze Chain Joints", "Show/Hide Lines of Sight",
        "Print Map and Schedule"]
    menu.items[0].run(view)
    assert stage.IsLayerMuted(usdview.gaze_layers(stage)[0].identifier)
    sys.modules.pop("usdgaze.review.usdview_plugin", None)


def test_an_attend_layer_and_looks_are_toggled_and_listed(tmp_path):
    """A shot holding an ``attend`` layer: Toggle said there was no usdgaze layer (it looked for
    recorded shifts, which attend does not write) and the summary never named it; an ``apply`` layer's
    look-ats and releases were left out of the summary (it listed the shifts alone)."""
    from pxr import Sdf

    from usdgaze.console.main import main

    stage_path = CMU.parents[1] / "attend" / "two_balls.usda"
    attend, looks = tmp_path / "attend.usdc", tmp_path / "looks.usdc"
    assert main(["attend", str(stage_path), "--out", str(attend)]) == 0
    assert main(["apply", str(stage_path), "--look-at", "/Objects/BallLeft@0.5s", "--release", "1.5s",
                 "--out", str(looks)]) == 0
    for layer, said in ((attend, "objects: /Objects/BallLeft, /Objects/BallRight"),
                        (looks, "--look-at /Objects/BallLeft@0.5s --release 1.5s")):
        src = Sdf.Layer.FindOrOpen(str(stage_path))
        root = Sdf.Layer.CreateNew(str(tmp_path / f"shot_{layer.stem}.usda"))
        for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
            setattr(root, key, getattr(src, key))
        for key in ("upAxis", "metersPerUnit"):
            root.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
        root.subLayerPaths[:] = [str(layer), str(stage_path)]
        root.Save()
        stage = Usd.Stage.Open(root)
        view = UsdviewApiStandIn(stage)
        skel = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
        anim = UsdSkel.BindingAPI(skel).GetInheritedAnimationSource()
        times = anim.GetAttribute("rotations").GetTimeSamples()
        input_stage = Usd.Stage.Open(str(stage_path))
        base = input_stage.GetPrimAtPath(anim.GetPath())

        def input_joints(prim):  # the input's joints' rotations, as the stage composes them
            joints = [str(j) for j in prim.GetAttribute("joints").Get()]
            cols = [joints.index(str(j)) for j in base.GetAttribute("joints").Get()]
            return np.array([np.asarray(prim.GetAttribute("rotations").Get(t))[cols] for t in times])
        assert not np.allclose(input_joints(anim), input_joints(base))  # the override shows
        usdview.toggle_gaze_layer(view)
        assert stage.IsLayerMuted(Sdf.Layer.FindOrOpen(str(layer)).identifier)
        assert np.array_equal(input_joints(anim), input_joints(base))  # the base shows
        assert said in usdview.summary(view), usdview.summary(view)
