"""``plot`` of an ``attend`` layer on a character whose SkelRoot has a non-ASCII name (USD takes UTF-8
prim names): the attend pass names its inspection scope as a prim name (``P_rsonnage``), and the
attention plot went out as ``P_rsonnage_attention.png``, titled so, beside ``Pérsonnage_gaze.png``; and
of characters whose paths spell one scope name (``/A_B``, ``/A/B``), whose attention files took each
other's names or overwrote one another."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom

from usdgaze.console.main import main

from . import synthetic as syn


def test_the_attention_plot_names_the_character_as_its_other_plots_do(tmp_path):
    rig = syn.make_rig(tmp_path / "in.usda", frames=48, time_codes_per_second=24, mesh=False, root_path="/Pérsonnage")
    stage = Usd.Stage.Open(str(rig.path))
    for name, x in (("Left", 1.0), ("Right", -1.0)):
        ball = UsdGeom.Sphere.Define(stage, f"/Ball{name}")
        ball.AddTranslateOp().Set(Gf.Vec3d(x, 1.5, 2.0))
    stage.Save()
    layer, plots = tmp_path / "attend.usdc", tmp_path / "plots"
    assert main(["attend", str(rig.path), "--objects", "/BallLeft,/BallRight", "--out", str(layer)]) == 0
    assert main(["plot", str(rig.path), "--layer", str(layer), "--out", str(plots)]) == 0
    written = sorted(p.name for p in plots.iterdir())
    assert written == sorted(f"Pérsonnage_{kind}.png" for kind in ("gaze", "eyes", "speed", "attention")), written


# /A_B and /A/B spell the same scope name (A_B); /X/A_B_2 spells what attend made of the second (A_B_2).
ROOTS = {"/A_B": ((0.0, 0.0, 0.0), 0.0), "/A/B": ((3.0, 0.0, 0.0), 180.0), "/X/A_B_2": ((-3.0, 0.0, 0.0), 180.0)}
PLOT_NAMES = {"/A_B": "A_B", "/A/B": "B", "/X/A_B_2": "A_B_2"}  # each SkelRoot's name: no two repeat


def _three_characters(tmp_path):
    """Three characters whose paths spell colliding scope names, looking different ways: /A_B at a ball
    1 m before its eyes, the two others turned away from it (it is behind them)."""
    from pxr import Sdf

    from .test_attend_two_characters import _add_ball, _stage
    from . import measure

    names = tuple(r.strip("/") for r in ROOTS)
    stage, rig = _stage(tmp_path, names=names, place=tuple(at for at, _ in ROOTS.values()))
    layer = Sdf.Layer.FindOrOpen(str(stage))
    for root, (_, turn) in ROOTS.items():
        layer.GetPrimAtPath(root).attributes["xformOp:rotateY"].default = turn
    layer.Save()
    p = measure.posed(str(stage), "/A_B/Skel")
    _add_ball(stage, 0.5 * (p.position(rig.leaf["eye_l"])[0] + p.position(rig.leaf["eye_r"])[0]) + [0.0, 0.0, 1.0])
    return stage, rig


def test_each_characters_attention_has_its_own_file_named_as_its_other_plots(tmp_path, monkeypatch):
    """attend names its scopes A_B, A_B_2 and X_A_B_2 here; plot named an attention file by the scope:
    /A/B's went out as A_B_attention.png (/A_B's name), and /A_B's and /X/A_B_2's both as
    A_B_2_attention.png, one overwriting the other. Each file now holds its own character's point of
    sight: it lies on that character's line of sight by UsdSkel FK of the written layer."""
    from usdgaze.review import plotting

    from . import measure
    from .attend_support import compose

    stage, rig = _three_characters(tmp_path)
    layer, plots = tmp_path / "attend.usda", tmp_path / "plots"
    assert main(["attend", str(stage), "--out", str(layer), "--window", "0.3"]) == 0
    drawn: dict[str, list] = {}
    panel = plotting.panel_attention

    def record(top, bottom, seconds, point_of_sight, objects, uncertainty, title):
        drawn.setdefault(title, []).append(np.asarray(point_of_sight, dtype=float))
        panel(top, bottom, seconds, point_of_sight, objects, uncertainty, title)

    monkeypatch.setattr(plotting, "panel_attention", record)
    assert main(["plot", str(stage), "--layer", str(layer), "--out", str(plots)]) == 0
    attention = sorted(p.name for p in plots.iterdir() if p.name.endswith("_attention.png"))
    assert attention == sorted(f"{n}_attention.png" for n in PLOT_NAMES.values())
    assert sorted(drawn) == sorted(PLOT_NAMES.values()) and all(len(v) == 1 for v in drawn.values())
    composed = compose(tmp_path, stage, layer)
    eye_l, eye_r = rig.leaf["eye_l"], rig.leaf["eye_r"]
    sights = {}
    for root in ROOTS:
        g = measure.posed(str(composed), f"{root}/Skel")
        line = measure.sight_line(g, eye_l, eye_r, measure.local_forward(g, eye_l, rig.forward),
                                  measure.local_forward(g, eye_r, rig.forward))
        sights[root] = (0.5 * (g.position(eye_l) + g.position(eye_r)), line)
    for root, name in PLOT_NAMES.items():
        (point,) = drawn[name]
        for other, (eyes, line) in sights.items():
            to = point - eyes
            off = measure.angle_between(line, to / np.linalg.norm(to, axis=1, keepdims=True))
            if other == root:  # on its own line of sight
                assert np.median(off) < 2.0, (root, off)
            else:  # and off the others' (the check tells the characters apart)
                assert np.median(off) > 20.0, (root, other, off)
    # A layer written before the scopes recorded their character: one file per scope still, none lost.
    from pxr import Sdf

    written = Sdf.Layer.FindOrOpen(str(layer))
    for scope in written.GetPrimAtPath("/UsdGazeAttend").nameChildren:
        scope.RemoveProperty(scope.properties["gaze:attend:character"])
    written.Save()
    assert main(["plot", str(stage), "--layer", str(layer), "--out", str(tmp_path / "older")]) == 0
    assert len([p for p in (tmp_path / "older").iterdir() if p.name.endswith("_attention.png")]) == 3
