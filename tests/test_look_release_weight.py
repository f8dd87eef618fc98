"""A release after a partial look or shift (weight < 1) is a gaze shift from what was shown back to
the base motion's gaze. The release's weight key was 1, so on its first frame the gaze jumped to the
full look (a look at weight 0 showed the base gaze until then and jumped 44.5 deg in one frame, the
eyes at 2,745 deg/s, the head at 1,334 deg/s) and the release ran back from there. Measured by
UsdSkel FK on a standing synthetic rig."""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


@pytest.mark.parametrize("look, weight", [("1.5,1.6,2", 0.0), ("1.5,1.6,2", 0.5), (None, 0.5)])
def test_a_release_after_a_partial_gaze_starts_where_the_gaze_is(tmp_path, look, weight):
    rig = syn.make_rig(tmp_path / "in.usda", mesh=False, frames=200, time_codes_per_second=60, walk_speed=0.0)
    first = (["--look-at", f"{look}@40:weight={weight}"] if look else ["--shift", f"40:40:0:weight={weight}"])
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), *first, "--release", "120", "--out", str(tmp_path / "gaze.usdc"),
                 "--preview", str(preview)]) == 0
    base = measure.posed(str(rig.path), rig.skeleton)
    new = measure.posed(str(preview), rig.skeleton)
    change, _, line = measure.gaze_change(base, new, rig.forward, head=rig.leaf["head"], eyes=rig.eye_leaves)
    left = rig.eye_leaves[0]
    eye = new.axis(left, measure.local_forward(new, left, rig.forward))
    eye_speed = measure.angle_between(eye[1:], eye[:-1]) * rig.time_codes_per_second
    head = new.world[:, new.index(rig.leaf["head"]), :3, :3]
    head_speed = measure.rotation_angle_deg(head[1:], head[:-1]) * rig.time_codes_per_second
    assert eye_speed.max() < 800.0, (eye_speed.max(), new.times[1:][eye_speed.argmax()])
    assert head_speed.max() < 300.0, (head_speed.max(), new.times[1:][head_speed.argmax()])
    # Just before the release the gaze shows the weighted look; the release leaves from there.
    step = np.linalg.norm(np.diff(change, axis=0), axis=1)
    assert step[(new.times[1:] >= 118) & (new.times[1:] <= 124)].max() < 6.0
    # And the release ends on the base motion's gaze.
    assert np.abs(change[new.times > 170]).max() < 0.5
