"""The physics shot's own measures of failure, on states made up for them: a body that turns away from
the reference's heading (the joint errors, joint by joint, cannot see it), a finite state no body
reaches (MuJoCo can run away without a NaN), hinge errors wrapped to a half turn."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc


def _wxyz(r: Rotation) -> np.ndarray:
    x, y, z, w = r.as_quat().T
    return np.column_stack([w, x, y, z])


def _states(yaw_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference bases tilted at random, and the same turned about the vertical by ``yaw_deg``."""
    n = len(yaw_deg)
    tilt = Rotation.from_rotvec(np.random.default_rng(0).normal(scale=0.3, size=(n, 3)))
    ref = np.zeros((n, 7))
    ref[:, 2] = 1.0
    ref[:, 3:7] = _wxyz(tilt)
    sim = ref.copy()
    sim[:, 3:7] = _wxyz(Rotation.from_euler("z", yaw_deg[:, None], degrees=True) * tilt)
    return sim, ref


def test_heading_error_is_the_turn_about_the_vertical():
    yaw = np.array([0.0, 5.0, -40.0, 179.0, 181.0, 300.0, -725.0])
    sim, ref = _states(yaw)
    want = np.abs((yaw + 180.0) % 360.0 - 180.0)
    assert np.allclose(mpc.heading_errors_deg(sim, ref), want, atol=1e-9)


def test_a_body_turned_away_is_a_problem_of_the_shot():
    yaw = np.linspace(0.0, 95.0, 20)
    sim, ref = _states(yaw)
    result = mpc.Result(seconds=np.arange(20) * 0.02, qpos=sim, ref_qpos=ref, ctrl=np.zeros((19, 0)),
                        pelvis_ratio=np.ones(20), joint_error_deg=np.zeros(20), foot_below_ground_m=np.zeros(20),
                        solve_costs=[], fell_at=None)
    (problem,) = physics_pass.heading_problems(result)
    over = int(np.sum(yaw > physics_pass.HEADING_TOLERANCE_DEG))
    assert problem == f"turned 95 deg away from the reference's heading by 0.38 s (over 30 deg on {over} step(s))"
    result.qpos = ref
    assert physics_pass.heading_problems(result) == []


def test_a_state_no_body_reaches_is_blown_up():
    ref = np.zeros(10)
    ref[2] = 1.0
    still = np.zeros(9)
    assert not mpc.blown_up(ref, still, ref, 1.75)
    far = ref.copy()
    far[0] = 6.0
    assert mpc.blown_up(far, still, ref, 1.75)
    fast = still.copy()
    fast[1] = 60.0
    assert mpc.blown_up(ref, fast, ref, 1.75)
    spinning = still.copy()
    spinning[7] = 600.0
    assert mpc.blown_up(ref, spinning, ref, 1.75)
