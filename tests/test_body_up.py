"""Which skeleton axis a neutral pose stands along, by its legs (``character_frame.body_up``): built
joint by joint here, so the answer is known without the code under test."""

from __future__ import annotations

import numpy as np

from usdgaze.core.character_frame import body_up

JOINTS = ["Hips", "Hips/Spine", "Hips/Spine/Head", "Hips/pelvis_L", "Hips/pelvis_R",
          "Hips/LeftUpLeg", "Hips/LeftUpLeg/LeftLeg", "Hips/LeftUpLeg/LeftLeg/LeftFoot",
          "Hips/RightUpLeg", "Hips/RightUpLeg/RightLeg", "Hips/RightUpLeg/RightLeg/RightFoot"]


def _pose(down: np.ndarray, up: np.ndarray, left: np.ndarray = np.array([1.0, 0, 0])) -> np.ndarray:
    """A standing biped (legs 0.9 m straight along ``down``, spine along ``up``) as 4x4 transforms
    with the translation in the last column; Rigify-like pelvis helpers beside the hips, leaves."""
    hips = np.array([0.0, 0.0, 0.0])
    at = {"Hips": hips, "Hips/Spine": hips + 0.3 * up, "Hips/Spine/Head": hips + 0.7 * up,
          "Hips/pelvis_L": hips + 0.1 * left, "Hips/pelvis_R": hips - 0.1 * left}
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        thigh = hips + s * 0.1 * left
        at[f"Hips/{side}UpLeg"] = thigh
        at[f"Hips/{side}UpLeg/{side}Leg"] = thigh + 0.45 * down
        at[f"Hips/{side}UpLeg/{side}Leg/{side}Foot"] = thigh + 0.9 * down
    out = np.tile(np.eye(4), (len(JOINTS), 1, 1))
    for i, j in enumerate(JOINTS):
        out[i, :3, 3] = at[j]
    return out


def test_standing_along_y_z_and_minus_z():
    for up in (np.array([0, 1.0, 0]), np.array([0, 0, 1.0]), np.array([0, 0, -1.0])):
        assert np.array_equal(body_up(JOINTS, _pose(-up, up)), up)


def test_legs_turned_within_the_bound_still_say_the_axis_and_past_it_nothing():
    tilted = np.array([0.0, -np.cos(np.radians(20)), np.sin(np.radians(20))])  # 20 deg off -Y
    assert np.array_equal(body_up(JOINTS, _pose(tilted, np.array([0, 1.0, 0]))), [0, 1.0, 0])
    seated = np.array([0.0, -1.0, 1.0]) / np.sqrt(2)  # 45 deg from -Y and +Z: says nothing
    assert body_up(JOINTS, _pose(seated, np.array([0, 1.0, 0]))) is None


def test_no_sided_chains_say_nothing():
    plain = ["Hips", "Hips/Spine", "Hips/Spine/Head"]
    assert body_up(plain, np.tile(np.eye(4), (3, 1, 1))) is None
