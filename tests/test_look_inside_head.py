"""A look-at target inside the character's own head is let go, not chased by turns of the body.

An audit found: a point where a standing character's head joint is (11 cm behind the eyes, a prop
placed on the head, say) was taken for a target behind the character within reach: the planner asked
for 150 deg turns and cut each short a few frames later as the bobbing head carried the point across
the eyes' 10 cm near point, three times in 2 s; the line of sight dipped 5.6 deg and came back, under
three warnings. A point inside the head turns with it: no turn brings it into view.
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


def _warnings(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("usdgaze: warning:")]


def test_a_target_at_the_head_joint_leaves_the_gaze_alone(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=120, mesh=False, walk_speed=0.0)
    base = measure.posed(str(rig.path), rig.skeleton)
    head = base.position(rig.leaf["head"])[30]
    stage = Usd.Stage.Open(str(rig.path))
    UsdGeom.Xform.Define(stage, "/World/Hat").AddTranslateOp().Set(Gf.Vec3d(*head))
    stage.GetRootLayer().Save()

    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--look-at", "/World/Hat@0.5s", "--out", str(tmp_path / "gaze.usda"),
                 "--preview", str(preview)]) == 0
    said = _warnings(capsys)
    assert len(said) == 1 and "out of reach (inside the character's head) at 0.5 s" in said[0], said

    new = measure.posed(str(preview), rig.skeleton)
    change, _, _ = measure.gaze_change(base, new, rig.forward, rig.leaf["head"], rig.eye_leaves)
    assert np.abs(change).max() < 0.5, np.abs(change).max()  # the base motion's gaze throughout
    h = rig.leaf["head"]
    off = measure.angle_between(new.axis(h, measure.local_forward(new, h, rig.forward)),
                                base.axis(h, measure.local_forward(base, h, rig.forward)))
    assert off.max() < 0.01, off.max()  # and no turn of the body toward it
