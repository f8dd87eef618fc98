"""The MuJoCo body as a planner part: coordinates, one step, and its derivatives.

The derivatives (MuJoCo's finite-difference transition matrices mapped to the state's minimal
coordinates) are checked against central differences of the part's own ``step`` in those
coordinates, with the feet on the ground and in the air, at a turned base (large rotation vectors,
where the SO(3) Jacobians matter).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdgaze.physics import build, retarget
from usdgaze.physics.dynamics import MujocoBody

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


@pytest.fixture(scope="module")
def body():
    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    return MujocoBody(model, h=0.02), retarget.to_qpos(model, ref)


def _central(f, x, eps=1e-6):
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = eps
        cols.append((f(x + e) - f(x - e)) / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("where", ["ground", "air", "turned"])
def test_linearization_matches_central_differences_of_the_step(body, where):
    dyn, qpos = body
    rng = np.random.default_rng(3)
    q = qpos[400].copy()
    if where == "air":
        q[2] += 0.4
    if where == "turned":  # base turned 160 degrees from the anchor: rotation vector of norm ~2.8
        turn = Rotation.from_euler("z", 160, degrees=True) * Rotation.from_quat(np.roll(q[3:7], -1))
        q[3:7] = np.roll(turn.as_quat(), 1)
        q[2] += 0.4
    x = dyn.to_state(q, rng.normal(0, 0.3, dyn.nv))
    u = rng.normal(0, 0.1, dyn.nu)
    A, B = dyn.linearize(x, u, 0)
    An = _central(lambda z: dyn.step(z, u, 0), x)
    Bn = _central(lambda v: dyn.step(x, v, 0), u)
    assert A.shape == (dyn.nx, dyn.nx) and B.shape == (dyn.nx, dyn.nu)
    assert np.linalg.norm(A - An) / np.linalg.norm(An) < 1e-4
    assert np.linalg.norm(B - Bn) / np.linalg.norm(Bn) < 1e-4
    # The rotation blocks really are nonlinear here: identity Jacobians would be far off.
    if where == "turned":
        assert np.abs(x[3:6]).max() > 1.0


def test_state_round_trips_and_step_is_mujocos_semi_implicit_euler(body):
    dyn, qpos = body
    assert dyn.mj.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER and dyn.mj.opt.timestep == 0.02
    rng = np.random.default_rng(5)
    qv = rng.normal(0, 0.5, dyn.nv)
    x = dyn.to_state(qpos[200], qv)
    assert x.shape == (2 * dyn.nv,)
    q2, v2 = dyn.to_mujoco(x)
    d = mujoco.MjData(dyn.mj)
    d.qpos[:], d.qvel[:] = qpos[200], qv
    mujoco.mj_kinematics(dyn.mj, d)
    xpos = d.xpos.copy()
    d.qpos[:] = q2
    mujoco.mj_kinematics(dyn.mj, d)
    assert np.abs(d.xpos - xpos).max() < 1e-9 and np.array_equal(v2, qv)
    # One step: the new positions follow from the new velocities (q' = q (+) h qdot').
    u = rng.normal(0, 0.2, dyn.nu)
    xn = dyn.step(x, u, 0)
    qn, vn = dyn.to_mujoco(xn)
    expect = q2.copy()
    mujoco.mj_integratePos(dyn.mj, expect, vn, 0.02)
    assert np.abs(qn - expect).max() < 1e-9
    assert not np.allclose(vn, qv)


def test_head_pose_jacobian_matches_central_differences(body):
    """What the eye and belief parts read from the body: the eyes' midpoint and head axes."""
    dyn, qpos = body
    q = qpos[300].copy()
    turn = Rotation.from_euler("z", 120, degrees=True) * Rotation.from_quat(np.roll(q[3:7], -1))
    q[3:7] = np.roll(turn.as_quat(), 1)
    x = dyn.to_state(q)
    p, R = dyn.head_pose(x, 0)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.linalg.det(R) > 0
    assert abs(R[2, 2]) > 0.8  # the head's up is near the world's up in a walk
    dp, dR = dyn.head_pose_jacobian(x, 0)
    num_p = _central(lambda z: dyn.head_pose(z, 0)[0], x)
    num_R = _central(lambda z: dyn.head_pose(z, 0)[1].ravel(), x)
    assert np.linalg.norm(dp - num_p) / np.linalg.norm(num_p) < 1e-5
    assert np.linalg.norm(dR.reshape(9, -1) - num_R) / np.linalg.norm(num_R) < 1e-5
