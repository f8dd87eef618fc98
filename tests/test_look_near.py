"""A look-at target that passes through the head (2 cm from the eyes' midpoint): it is let go as it
comes nearer than the eyes' near point (10 cm), so no eye turns faster than a saccade while it crosses
(pursuit followed its direction through the back of the head: an eye swung 55 deg in one frame, 3,300
deg/s), and the gaze's return to the base turns no eye from one limit of its range to the other (the
held point, near and behind the head, swung the wanted direction through the back of the head: an eye
swapped +44.2 for -44.2 deg in one frame), and the body makes no turn toward where it goes."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


def test_a_target_through_the_head_flips_no_eye(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", mesh=False, frames=200, time_codes_per_second=60)
    base = measure.posed(str(rig.path), rig.skeleton)
    left, right = rig.eye_leaves
    mid = 0.5 * (base.position(left) + base.position(right))
    stage = Usd.Stage.Open(str(rig.path))
    op = UsdGeom.Xform.Define(stage, "/World/Through").AddTranslateOp()
    for t, m in zip(base.times, mid):  # from 1.5 m ahead, through the head at 1.5 s, on behind
        s = t / rig.time_codes_per_second
        op.Set(Gf.Vec3d(*(m + rig.left * 0.02 + rig.forward * (1.5 - 1.0 * s))), float(t))
    stage.GetRootLayer().Save()

    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--look-at", "/World/Through@0.3s", "--out", str(tmp_path / "gaze.usdc"),
                 "--preview", str(preview)]) == 0
    warning = capsys.readouterr().err
    let_go_s = float(warning.split("out of reach (nearer than the eyes' near point, 10 cm) at ")[1].split(" s")[0])
    new = measure.posed(str(preview), rig.skeleton)
    # Let go before it reaches the near point: 10 cm ahead of the eyes at 1.4 s, 1 m/s.
    assert 1.3 < let_go_s < 1.45
    for eye in (left, right):
        yaw, pitch = measure.eye_in_head(new, rig.leaf["head"], eye, rig.forward, rig.left, rig.up)
        d = np.column_stack([np.cos(np.radians(pitch)) * np.sin(np.radians(yaw)), np.sin(np.radians(pitch)),
                             np.cos(np.radians(pitch)) * np.cos(np.radians(yaw))])
        speed = measure.angle_between(d[1:], d[:-1]) * rig.time_codes_per_second
        assert speed.max() < 800.0, (eye, speed.max())  # the seed's saccade cap, over the whole shot
    # The body is not sent toward where the target goes once out of reach: the planner, aiming where it
    # would be at the end of a shift, started a 150 deg turn 0.2 s before the let-go (the head 6.4 deg
    # off the base motion's, then back).
    head = rig.leaf["head"]
    off = measure.angle_between(new.axis(head, measure.local_forward(new, head, rig.forward)),
                                base.axis(head, measure.local_forward(base, head, rig.forward)))
    crossing = (new.times >= 1.1 * rig.time_codes_per_second) & (new.times <= 2.0 * rig.time_codes_per_second)
    assert off[crossing].max() < 3.0, off[crossing].max()


def test_a_target_out_of_reach_at_its_own_start_leaves_the_gaze_alone(tmp_path, capsys):
    """Let go at once (3 m straight behind): the line of sight moved on the directive's frame alone,
    by (0.75, 1.37) deg, the eyes held one frame on where the base looked the frame before."""
    rig = syn.make_rig(tmp_path / "in.usda", mesh=False, frames=120, time_codes_per_second=60)
    base = measure.posed(str(rig.path), rig.skeleton)
    left, right = rig.eye_leaves
    eyes = 0.5 * (base.position(left) + base.position(right))[30]
    stage = Usd.Stage.Open(str(rig.path))
    UsdGeom.Xform.Define(stage, "/World/Behind").AddTranslateOp().Set(Gf.Vec3d(*(eyes - 3.0 * rig.forward)))
    stage.GetRootLayer().Save()
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--look-at", "/World/Behind@0.5s", "--out", str(tmp_path / "gaze.usdc"),
                 "--preview", str(preview)]) == 0
    assert "out of reach (behind the character) at 0.5 s" in capsys.readouterr().err
    change, _, _ = measure.gaze_change(base, measure.posed(str(preview), rig.skeleton), rig.forward,
                                       head=rig.leaf["head"], eyes=(left, right))
    assert np.abs(change).max() < 0.01, np.abs(change).max(axis=0)
