"""Eyes hung under a face joint (``Head/FaceRoot/LeftEye``) whose animated rotation relative to the head
differs from its bind-pose relation: the eye range and aim are the head's, measured by UsdSkel FK.

Measured in the eye's parent (the turned face joint) instead of the head, the range was shifted by the
turn: a face joint turned 25 deg to the left held the eyes 25 deg short of a target on the right (it
missed by 9.2 deg on the synthetic walk), and let them turn 25 deg past their range on the left. Eye
axes and the head's frame come from the bind pose (tests/measure.py); nothing here calls usdgaze's math.
"""

from __future__ import annotations

import numpy as np
import pytest

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api

from . import measure, rig_extras
from . import synthetic as syn

RATE, FRAMES, LOOK_S = 24.0, 96, 0.5
LIMITS = (44.2, 27.7, 47.1)  # the README's eye range: yaw +-, up, down (Eom et al.)


def _look(tmp_path, turn_deg: float | None, yaw_rad: float, dist_m: float, turn_axis=None, scale=(1.0, 1.0, 1.0)):
    """A synthetic walk, its eyes under a face joint turned ``turn_deg`` from its bind relation (None: no
    face joint), looking at a point ``dist_m`` ahead ``yaw_rad`` to the left; the FK before and after."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=FRAMES, time_codes_per_second=RATE, mesh=False)
    if turn_deg is not None:
        rig_extras.insert_face_root(rig, turn_deg, turn_axis, scale=scale)
    base = measure.posed(str(rig.path), rig.skeleton)
    look = int(LOOK_S * RATE)
    target = (base.position(rig.leaf["head"])[look] + 0.3 * rig.up
              + dist_m * (np.cos(yaw_rad) * rig.forward + np.sin(yaw_rad) * rig.left))
    preview = tmp_path / "preview.usda"
    api.apply(rig.path, [], tmp_path / "gaze.usdc", preview=preview,
              look_at=[",".join(f"{v:.6f}" for v in target) + f"@{LOOK_S}s"])
    return rig, target, measure.posed(str(preview), rig.skeleton)


def _misses(rig, target, new) -> dict[str, np.ndarray]:
    """Per eye, degrees between its line of sight (its bind-pose forward axis) and the target, per frame."""
    out = {}
    for eye in rig.eye_leaves:
        out[eye] = measure.eye_miss_deg(new, eye, rig.forward, target)
    return out


def _eye_in_head(rig, new) -> np.ndarray:
    """(yaw, pitch) of both eyes in the head's bind-pose frame by FK, ``(eye, F, 2)``."""
    return np.stack([np.column_stack(measure.eye_in_head(new, rig.leaf["head"], eye, rig.forward, rig.left, rig.up))
                     for eye in rig.eye_leaves])


@pytest.mark.parametrize("turn_deg, axis, scale", [
    (25.0, None, (1.0, 1.0, 1.0)),  # a yaw toward the left, the target on the right
    (-25.0, None, (1.0, 1.0, 1.0)),
    (22.0, (1.0, 0.3, 0.0), (1.0, 1.0, 1.0)),  # mostly a pitch
    (25.0, None, (1.0, 1.3, 0.8)),  # the face joint squashed too: its frame is no rotation of the head's
])
def test_a_turned_face_joint_keeps_the_eyes_on_a_reachable_target(tmp_path, turn_deg, axis, scale):
    rig, target, new = _look(tmp_path, turn_deg, -0.8, 12.0, axis, scale)
    seconds = (new.times - rig.start_time) / RATE
    looking = seconds >= LOOK_S + 0.8
    for eye, miss in _misses(rig, target, new).items():
        assert miss[looking].max() < 1.0, (eye, miss[looking].max())
    angles = _eye_in_head(rig, new)
    assert np.abs(angles[..., 0]).max() <= LIMITS[0] + 0.1
    assert angles[..., 1].max() <= LIMITS[1] + 0.1 and angles[..., 1].min() >= -LIMITS[2] - 0.1


def test_the_range_is_the_heads_when_the_target_passes_out_of_it(tmp_path):
    """The walk passes a point to its left: the eyes end at their range, as the head's frame has it
    (measured in the face joint turned 25 deg to the left, they turned 25 deg further)."""
    rig, _, new = _look(tmp_path, 25.0, 1.3, 2.0)
    yaw = _eye_in_head(rig, new)[..., 0]
    assert yaw.max() > LIMITS[0] - 1.0  # the range is reached ...
    assert yaw.max() <= LIMITS[0] + 0.1  # ... and not passed


def test_an_unturned_face_joint_aims_as_the_head_alone(tmp_path):
    """A face joint animated as in the bind pose changes nothing the eyes do: the same lines of sight as
    the rig without it, to within float32 rounding."""
    plain = _look(tmp_path / "plain", None, -0.8, 12.0)
    face = _look(tmp_path / "face", 0.0, -0.8, 12.0)
    for eye in plain[0].eye_leaves:
        a = plain[2].axis(eye, measure.local_forward(plain[2], eye, plain[0].forward))
        b = face[2].axis(eye, measure.local_forward(face[2], eye, face[0].forward))
        assert measure.angle_between(a, b).max() < 1e-3


def test_attend_aims_eyes_under_a_turned_face_joint(tmp_path):
    """``attend`` writes the eyes' turns in their parent's frame as moved: it read only the head's
    ancestors and stopped on the face joint (an internal error, exit 1)."""
    from usdgaze.console.main import main

    from . import attend_support as sup

    rig = syn.make_rig(tmp_path / "in.usda", frames=72, time_codes_per_second=RATE, mesh=False)
    rig_extras.insert_face_root(rig, 25.0)
    start = measure.posed(str(rig.path), rig.skeleton).position(rig.leaf["head"])[0]
    ball = start + 4.0 * (np.cos(-0.6) * rig.forward + np.sin(-0.6) * rig.left)
    scene = sup.over(tmp_path / "scene.usda", rig.path)
    sup.still_ball(scene, "/Objects/Ball", ball, 0.1)
    scene.Save()
    assert main(["attend", str(tmp_path / "scene.usda"), "--out", str(tmp_path / "att.usda")]) == 0
    new = measure.posed(str(sup.compose(tmp_path, tmp_path / "scene.usda", tmp_path / "att.usda")), rig.skeleton)
    misses = _misses(rig, ball, new)
    for eye, miss in misses.items():  # 0.25 s to 1.7 s, while the ball is ahead
        assert np.median(miss[6:40]) < 1.0, (eye, np.median(miss[6:40]))
    angles = _eye_in_head(rig, new)
    assert np.abs(angles[..., 0]).max() <= 50.1  # attend's own clamp, in the head's frame
