"""``attend --physics`` refuses a shot's bad task inputs before any simulation, and reads a catch the
shot's own layer authors over an asset's (tests/bad_cases_sweep4.py has the refusals' builders;
docs/bad-inputs.md their lines)."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)

from . import bad_cases_sweep4 as sweep4
from .bad_common import run_inprocess


def test_second_characters_bad_push_refused_before_any_simulation(tmp_path, monkeypatch):
    """Two characters, the second's push on a joint it lacks: the first was simulated before (one
    call of the simulation), and nothing is now."""
    from usdgaze.physics import mpc, visuomotor

    calls = []

    def counted(*args, **kwargs):
        calls.append(1)
        raise AssertionError("simulated before the shots were checked")

    monkeypatch.setattr(mpc, "simulate", counted)
    monkeypatch.setattr(visuomotor, "simulate", counted)
    argv = sweep4.b_physics_second_character_bad_push(tmp_path)
    code, _, err = run_inprocess(argv, tmp_path)
    assert code == 2, err
    assert err.strip().splitlines() == [err.strip()]
    assert "/B.usdgaze:physics:pushJoint: 'NoSuchJoint' is not a simulated joint of /B/Skel" in err
    assert calls == []
    assert not (tmp_path / "gaze.usdc").exists()


@pytest.mark.parametrize("builder", [sweep4.b_physics_on_a_platform_with_objects,
                                     sweep4.b_physics_catch_outside_the_reference])
def test_refused_before_any_simulation(tmp_path, monkeypatch, builder):
    """The coupled loop's refusals come before it runs (it ran 0.2 s of a drop before)."""
    from usdgaze.physics import visuomotor

    monkeypatch.setattr(visuomotor, "simulate", lambda *a, **k: pytest.fail("simulated"))
    code, _, err = run_inprocess(builder(tmp_path), tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err


def test_catch_authored_over_the_asset_in_the_shot_is_read(tmp_path):
    """An explicit catch on the SkelRoot in the shot's layer hides the asset's target outside the
    reference: it is read (the ball the shot names), not refused."""
    from usdgaze.passes import visuomotor

    argv = sweep4.b_physics_catch_outside_the_reference(tmp_path)
    shot = Sdf.Layer.FindOrOpen(argv[1])
    sweep4._catch(shot, "/Character")
    shot.Save()
    stage = Usd.Stage.Open(argv[1])
    prims, paths, catches = visuomotor.read_scene(stage.GetPrimAtPath("/Character"), argv[1])
    assert paths == [sweep4.BALL] and catches == [0]


def _late_shot(d, push: bool):
    """The rig's animation at time codes 100-189 in a stage from 0, the shot to 118 (0.3 s); ``push``:
    1500 N forward at the chest over 103-109."""
    from .bad_common import rig

    r = rig(d, "in.usda", start_time=100.0)
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    layer.Reload(force=True)
    layer.startTimeCode, layer.endTimeCode = 0.0, 118.0
    if push:
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
        force = Sdf.AttributeSpec(root, "usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3)
        layer.SetTimeSample(force.path, 103.0, (0.0, 0.0, 1500.0))
        layer.SetTimeSample(force.path, 109.0, (0.0, 0.0, 0.0))
    layer.Save()
    out = d / "gaze.usdc"
    code, _, err = run_inprocess(["attend", str(r.path), "--physics", "--out", str(out), "--retry-iterations", "0"], d)
    assert code == 0, err
    from . import catch_stages, measure

    stage = catch_stages.composed(r.path, out, d / "composed.usda")
    return measure.posed(str(stage), r.skeleton).position(r.leaf["pelvis"])


def test_push_acts_when_the_animation_starts_after_the_stage(tmp_path):
    """A push is timed from the clip's first frame, where the simulation starts: timed from the
    stage's start it came 1.7 s late here, past the 0.3 s shot, and the pushed layer was the unpushed
    one bit for bit (the report still said 1 push). By UsdSkel FK the pushed hips are up to 32 cm from
    the unpushed ones (0 before)."""
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    pushed, still = _late_shot(tmp_path / "a", True), _late_shot(tmp_path / "b", False)
    assert np.abs(pushed - still).max() > 0.10


@pytest.mark.parametrize("kind", ["", "moving", "ballistic"])
def test_ball_to_catch_not_ballistic_is_warned(tmp_path, kind):
    """A ball to catch whose gaze:object:kind is not 'ballistic' (the schema's fallback is '') is
    predicted in a straight line: the palm came 30 cm from a seeded throw's ball, against 4.5 cm as
    'ballistic' (one run each, h 0.03), with nothing said of why. Now a warning names the attribute."""
    from .bad_common import edited

    def author(layer, r):
        sweep4._ball(layer)
        Sdf.AttributeSpec(layer.GetPrimAtPath(sweep4.BALL), "gaze:object:kind", Sdf.ValueTypeNames.Token).default = kind
        sweep4._catch(layer, r.skel_root)
        layer.startTimeCode, layer.endTimeCode = 0.0, 2.0  # a short shot: the warning is of the input
    src = edited(tmp_path, author)
    code, _, err = run_inprocess(["attend", str(src), "--physics", "--out", str(tmp_path / "gaze.usdc"),
                                  "--retry-iterations", "0"], tmp_path)
    assert code == 0, err
    said = [line for line in err.splitlines() if "gaze:object:kind" in line]
    expected = (f"usdgaze: warning: {src}:{sweep4.BALL}.gaze:object:kind: '{kind}' on a ball /Character is to catch: "
                "its path is predicted without gravity, in a straight line; author 'ballistic' for a thrown ball")
    assert said == ([] if kind == "ballistic" else [expected])
