"""A still look-at target by the feet (0.5 m to the side, on the floor: about 72 deg down), past what
the body's reach (-80 deg) leaves the eyes in comfort: the body turns to it once and holds. The planner
re-planned every 0.2 s as the base head bobbed, each request's yaw another (89 -> 131 -> 102 deg: near
the vertical, azimuth degrees are few degrees of arc), the head swinging at 327 deg/s by UsdSkel FK."""

from __future__ import annotations

import numpy as np

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


def test_a_target_by_the_feet_is_held_without_re_planning_the_body(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", mesh=False, frames=96, time_codes_per_second=24, walk_speed=0.0)
    base = measure.posed(str(rig.path), rig.skeleton)
    left, right = rig.eye_leaves
    eyes = 0.5 * (base.position(left) + base.position(right))[0]
    feet = eyes - (eyes @ rig.up) * rig.up + 0.5 * rig.left  # on the floor, half a metre to the left
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--look-at", f"{feet[0]:.4f},{feet[1]:.4f},{feet[2]:.4f}@10",
                 "--out", str(tmp_path / "gaze.usdc"), "--preview", str(preview)]) == 0
    assert "misses the target" in capsys.readouterr().err  # out of the eyes' range: said
    new = measure.posed(str(preview), rig.skeleton)
    head = new.world[:, new.index(rig.leaf["head"]), :3, :3]
    speed = measure.rotation_angle_deg(head[1:], head[:-1]) * rig.time_codes_per_second
    held = new.times[1:] > 1.5 * rig.time_codes_per_second  # after the first shift's 1.46 s
    assert speed[held].max() < 200.0, speed[held].max()
