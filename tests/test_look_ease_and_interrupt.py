"""Two transitions measured by UsdSkel FK on synthetic mixamo-style rigs at 24 fps.

* A look or shift with ``blend=B`` that starts where the base motion's gaze is shown eases in from it:
  the weight before any directive was taken as 1, so ``weight=0.5:blend=12`` swung the line of sight
  95% of the way to its goal in three frames and back to 50% (and ``weight=1:blend=24`` did not ease).
* A shift that interrupts another lets the given-up shift's segments coast to a stop: they had gone on
  toward the old goal (170 deg, given up for 0 after 0.4 s: the pelvis 5.7 -> 18.2 deg, then back 18
  deg in two frames, 12.2 deg in one; the head 826 deg/s in the world), and the return is timed from
  where the coast stops (the head 556 deg/s against 296 for a return from the settled 170).
"""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


def _apply(tmp_path, rig, *args):
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), *args, "--out", str(tmp_path / "gaze.usdc"), "--preview", str(preview)]) == 0
    return measure.posed(str(rig.path), rig.skeleton), measure.posed(str(preview), rig.skeleton)


def _sight(p, rig):
    left, right = rig.eye_leaves
    return measure.sight_line(p, left, right, measure.local_forward(p, left, rig.forward),
                              measure.local_forward(p, right, rig.forward))


def _ease(u):
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (u * (6.0 * u - 15.0) + 10.0)


@pytest.mark.parametrize("weight, blend", [(0.5, 12), (1.0, 24)])
def test_a_blended_look_eases_in_from_the_base_gaze(tmp_path, weight, blend):
    rig = syn.make_rig(tmp_path / "in.usda", frames=120, time_codes_per_second=24, walk_speed=0.0, mesh=False)
    base = measure.posed(str(rig.path), rig.skeleton)
    start = 24
    eyes = 0.5 * (base.position(rig.eye_leaves[0]) + base.position(rig.eye_leaves[1]))[start]
    up, fwd = base.up, base.axis(rig.leaf["head"], measure.local_forward(base, rig.leaf["head"], rig.forward))[start]
    left = np.cross(up, fwd)
    point = eyes + 2.0 * fwd + 1.2 * left / np.linalg.norm(left) + 0.3 * up
    _, new = _apply(tmp_path, rig, "--look-at", f"{','.join(f'{v:.5f}' for v in point)}@{start}:weight={weight}:blend={blend}")
    base_line, line = _sight(base, rig), _sight(new, rig)
    middle = 0.5 * (new.position(rig.eye_leaves[0]) + new.position(rig.eye_leaves[1]))
    goal = point - middle
    goal /= np.linalg.norm(goal, axis=1, keepdims=True)
    # The share of the way from the base line of sight to the goal that the line of sight has turned.
    share = measure.angle_between(line, base_line) / measure.angle_between(goal, base_line)
    t = new.times
    expected = weight * _ease((t - start) / blend)
    during = (t >= start) & (t <= start + blend + 12)
    assert np.abs(share - expected)[during].max() < 0.05, np.round(share[during], 2)
    assert share[during].max() < weight + 0.02
    assert share[t < start].max() < 1e-3


def test_an_interrupted_shift_does_not_go_on_toward_its_old_goal(tmp_path):
    rig = syn.make_rig(tmp_path / "in.usda", frames=240, time_codes_per_second=24)
    base, new = _apply(tmp_path, rig, "--shift", "48:170:0", "--shift", "58:0:0")
    pelvis = rig.leaf["pelvis"]
    moved = measure.rotation_angle_deg(new.world[:, new.index(pelvis), :3, :3], base.world[:, base.index(pelvis), :3, :3])
    after = new.times >= 58
    # At the interruption the pelvis has turned 5.7 deg; coasting takes it to 10, not 18.
    assert 4.0 < moved[new.times == 58][0] < 8.0
    assert moved[after].max() < 13.0, moved[after][:12]
    step = np.abs(np.diff(moved))
    assert step.max() < 8.0, (step.max(), new.times[1:][step.argmax()])
    head = new.world[:, new.index(rig.leaf["head"]), :3, :3]
    speed = measure.rotation_angle_deg(head[1:], head[:-1]) * rig.time_codes_per_second
    assert speed.max() < 650.0, (speed.max(), new.times[1:][speed.argmax()])
    # The return still gets there: the base motion's gaze, to the bit of the pelvis.
    assert moved[new.times >= 120].max() < 0.5


def test_a_reversal_moves_the_head_no_faster_than_a_settled_return(tmp_path):
    """A return shift that interrupts the outward one is timed from where the head's coast stops, not
    from where the gaze is at the interruption: the head still turning away at speed has that much
    further to come back (170 deg given up for 0 after 0.42 s: 556 deg/s in the world, against 296 for
    the same return from a settled 170)."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=240, time_codes_per_second=24)

    def head_peak(*shifts):
        folder = tmp_path / str(len(list(tmp_path.iterdir())))
        folder.mkdir()
        _, new = _apply(folder, rig, *[a for s in shifts for a in ("--shift", s)])
        head = new.world[:, new.index(rig.leaf["head"]), :3, :3]
        return (measure.rotation_angle_deg(head[1:], head[:-1]) * rig.time_codes_per_second).max()

    settled = head_peak("48:170:0", "168:0:0")
    reversal = head_peak("48:170:0", "58:0:0")
    assert reversal < 1.1 * settled, (reversal, settled)
