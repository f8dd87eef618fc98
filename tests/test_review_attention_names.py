"""``plot`` of an ``attend`` layer on a character whose SkelRoot has a non-ASCII name (USD takes UTF-8
prim names): the attend pass names its inspection scope as a prim name (``P_rsonnage``), and the
attention plot went out as ``P_rsonnage_attention.png``, titled so, beside ``Pérsonnage_gaze.png``."""

from __future__ import annotations

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
