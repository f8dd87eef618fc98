"""The saccade rhythm of ``usdgaze attend`` on the written layer (UsdSkel FK): in every recharge window
(200-400 ms of each 400 ms, counted from the clip's first frame) the eyes turn in the head at most at
the pursuit speed, 100 deg/s, at any frame rate and wherever the clip starts.

A ball that jumps 70 deg from side to side every 0.3 s keeps asking for saccades, so a window whose
bound is wrong shows. Windows are found from the frame times with a tolerance: t = 1.0 s is the start
of a recharge window even though 1.0 % 0.4 is 0.19999999999999996 in floating point.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn
from .attend_support import compose, over

SPEED_TOL = 1.02  # frame sampling of linear interpolation between planner steps never adds speed


def _jumping_ball(tmp: Path, tcps: float, start: float, stage_start: float | None = None, seconds: float = 2.0,
                  near: float = 2.0) -> tuple[Path, syn.Rig]:
    """A standing rig and a ball 2 m from its eyes, 35 deg left then right (``near`` m away), switching
    every 0.3 s (from the clip's first frame); the stage starts at ``stage_start`` (default: that frame)."""
    frames = int(round(seconds * tcps)) + 1
    rig = syn.make_rig(tmp / "in.usda", frames=frames, time_codes_per_second=tcps, start_time=start,
                       mesh=False, walk_speed=0.0)
    p = measure.posed(str(rig.path), rig.skeleton)
    s2w = p.skel_to_world[:3, :3]
    eyes = 0.5 * (p.position(rig.leaf["eye_l"])[0] + p.position(rig.leaf["eye_r"])[0])
    fwd, left = (v @ s2w / np.linalg.norm(v @ s2w) for v in (rig.forward, rig.left))
    layer = over(tmp / "scene.usda", rig.path)
    if stage_start is not None:
        layer.startTimeCode = stage_start
    stage = Usd.Stage.Open(layer)
    ball = UsdGeom.Sphere.Define(stage, "/Objects/Ball")
    ball.GetPrim().SetMetadata("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    op = ball.AddTranslateOp()
    for s in np.arange(0.0, seconds + 1e-9, 0.25 / tcps):  # four samples a frame: the jumps are sharp
        a, d = (np.radians(35.0), 2.0) if int(s / 0.3) % 2 == 0 else (np.radians(-35.0), near)
        op.Set(Gf.Vec3d(*(eyes + d * (np.cos(a) * fwd + np.sin(a) * left))), Usd.TimeCode(start + s * tcps))
    layer.Save()
    return tmp / "scene.usda", rig


def _eye_in_head_speed(stage: Path, rig: syn.Rig, tcps: float) -> tuple[np.ndarray, np.ndarray]:
    """Frame times (s from the first frame) and the eye-in-head speeds between frames, deg/s: the
    cyclopean line of sight's, then each eye's, ``(3, F - 1)``."""
    p = measure.posed(str(stage), rig.skeleton)
    eye_l, eye_r, head = rig.leaf["eye_l"], rig.leaf["eye_r"], rig.leaf["head"]
    fwd = rig.forward
    lines = [measure.sight_line(p, eye_l, eye_r, measure.local_forward(p, eye_l, fwd),
                                measure.local_forward(p, eye_r, fwd)),
             *(p.axis(e, measure.local_forward(p, e, fwd)) for e in (eye_l, eye_r))]
    axes = [p.axis(head, measure.local_forward(p, head, a)) for a in (fwd, rig.left, rig.up)]
    secs = (p.times - p.times[0]) / tcps
    speeds = []
    for v in lines:
        d = np.stack([(v * a).sum(-1) for a in axes], -1)  # the line in the head's frame
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        speeds.append(np.degrees(np.arccos(np.clip((d[1:] * d[:-1]).sum(-1), -1, 1))) / np.diff(secs))
    return secs, np.array(speeds)


@pytest.mark.parametrize("tcps, start, stage_start, near", [(24.0, 0.0, None, 2.0), (60.0, 1001.0, None, 2.0),
                                                            (24.0, 1001.0, 1.0, 2.0), (30.0, 0.0, None, 0.5)])
def test_no_saccade_in_a_recharge_window(tmp_path, capsys, tcps, start, stage_start, near):
    """The third case: a clip at 1001 in a stage that starts at 1 (a DCC's default range). Its windows
    count from the clip's first frame, and the 41.7 s before the clip are not planned. The last: the
    ball also jumps from 2 m to 0.5 m, so each eye turns by the vergence too (one eye moved at 160
    deg/s in a recharge window at 30 fps before each eye was held to the window's bound)."""
    scene, rig = _jumping_ball(tmp_path, tcps, start, stage_start, near=near)
    out = tmp_path / "gaze.usda"
    capsys.readouterr()
    assert main(["attend", str(scene), "--out", str(out), "--window", "0.4", "--json"]) == 0
    planner = json.loads(capsys.readouterr().out)["planner"]
    assert planner["steps"] <= 2.0 / planner["h"] + 1  # the clip's 2 s, not the stage's time before it
    secs, speed = _eye_in_head_speed(compose(tmp_path, scene, out), rig, tcps)
    period = np.floor((secs + 1e-6) / 0.4)
    phase = secs - 0.4 * period
    a = phase[:-1]
    recharge = (a >= 0.2 - 1e-6) & (period[:-1] == period[1:])  # both frames inside one recharge window
    assert recharge.sum() > 10 and speed[0].max() > 300  # the ball asks for saccades
    for line in speed:  # the cyclopean line of sight, the left eye, the right eye
        worst = int(np.argmax(np.where(recharge, line, 0)))
        assert line[recharge].max() <= 100 * SPEED_TOL, (secs[worst], line[worst])
