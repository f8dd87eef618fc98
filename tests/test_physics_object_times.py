"""The coupled physics pass (``attend --physics`` with objects) reads the objects at its own steps'
times: from the clip's first frame, as it simulates, not from the stage's start. A clip at time code
1001 in a stage starting at 1 saw its ball where it was 41.7 s before the shot (USD holds the first
sample there): a ball thrown during the shot stood still. Checked against USD's own transform."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from pxr import Usd, UsdGeom

from usdgaze.passes.visuomotor import _things
from usdgaze.usd.objects import object_prims
from usdgaze.usd.skelio import read_clip, skeletons_under

from .test_attend_rhythm import _jumping_ball


def test_objects_are_read_from_the_clips_first_frame(tmp_path):
    scene, rig = _jumping_ball(tmp_path, 24.0, 1001.0, stage_start=1.0)
    stage = Usd.Stage.Open(str(scene))
    root = stage.GetPrimAtPath(rig.skel_root)
    clip = read_clip(stage, skeletons_under(root)[0], root, str(scene))
    h, steps = 0.02, 101  # the clip's 2 s
    model = SimpleNamespace(to_model=np.eye(3))  # the stage's axes and metres as they are
    got = _things(root, clip, str(scene), object_prims(stage, str(scene), None), model, steps, h)[0].positions
    xf = UsdGeom.Xformable(stage.GetPrimAtPath("/Objects/Ball"))
    codes = 1001.0 + 24.0 * h * np.arange(steps)
    want = np.array([np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(float(c))))[3, :3] for c in codes])
    assert np.abs(got - want).max() < 1e-9
