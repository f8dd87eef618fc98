"""The step's derivative by the velocities in closed form and by the positions in one batch of steps
(``physics.velocity``) against MuJoCo's own finite differences of the whole step
(``mjd_transitionFD``, forward and centred), on the CMU body: feet on the ground (contact rows
pushing and not), in the air, fast, pushed; and MuJoCo's differences kept where the rule does not
apply.

The bound: MuJoCo's differences carry an absolute error (~1e-8 of the matrix's largest element
forward, ~3e-9 centred, measured), so an element near zero can differ from them by much more than
1e-6 of itself (up to ~7e-5 on elements ~1e-3 of the largest); each element is held to 1e-6 of the
largest, and the whole matrix to 1e-6 relative (measured ~1e-8 forward, ~3e-9 centred).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from usdgaze.physics import velocity

from .test_physics_controls import STATES, _mujoco_differences, _some_rows_push, _state
from .test_physics_dynamics import body  # noqa: F401  (the CMU body and its reference, a module fixture)


def _close(A, A_fd):
    assert np.linalg.norm(A - A_fd) / np.linalg.norm(A_fd) < 1e-6
    assert np.abs(A - A_fd).max() < 1e-6 * np.abs(A_fd).max()


@pytest.mark.parametrize("centered", [False, True])
@pytest.mark.parametrize("frame, lift, speed", STATES)
def test_state_columns_match_mujocos_differences(body, frame, lift, speed, centered):
    dyn, qpos = body
    assert dyn._twin is not None
    x, u = _state(dyn, qpos, frame, lift, speed)
    was = dyn.centered
    try:
        dyn.centered = centered
        A_fd, B_fd = _mujoco_differences(dyn, x, u, centered)
        A, B = dyn._fd(x, u, 0)
    finally:
        dyn.centered = was
    nv = dyn.nv
    assert np.array_equal(A[:, :nv], A_fd[:, :nv])  # the positions' columns: MuJoCo's rule, bit for bit
    _close(A[:, nv:], A_fd[:, nv:])
    _close(B, B_fd)
    if lift <= 0.0:
        _some_rows_push(dyn, x, u)


def test_pushed_body_and_the_coriolis_term(body):
    """An applied force (a push) reaches the batch of position steps; and the Coriolis forces'
    derivative is needed: the implicit-fast twin, which leaves it out, misses the bound."""
    dyn, qpos = body
    x, u = _state(dyn, qpos, 400, 0.0, 1.5)
    push = np.zeros((dyn.mj.nbody, 6))
    push[1, :3] = (150.0, 40.0, 0.0)
    forces, twin = dyn.forces, dyn._twin
    try:
        dyn.forces = lambda k: push
        A_fd, _ = _mujoco_differences(dyn, x, u, False)
        A, _ = dyn._fd(x, u, 0)
        assert np.array_equal(A[:, :dyn.nv], A_fd[:, :dyn.nv])
        _close(A[:, dyn.nv:], A_fd[:, dyn.nv:])
        fast = velocity.implicit_twin(dyn.mj)
        fast.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        dyn._twin = fast
        A, _ = dyn._fd(x, u, 0)
        assert np.abs(A - A_fd).max() > 1e-4 * np.abs(A_fd).max()
    finally:
        dyn.forces, dyn._twin = forces, twin


def test_mujocos_differences_where_the_rule_does_not_apply(body):
    """An elliptic friction cone (a contact row can slide, in its cone zone): MuJoCo differences the
    whole step; models with fluid forces, mocap bodies or equalities are not covered."""
    dyn, qpos = body
    mj = dyn.mj
    x, u = _state(dyn, qpos, 400, 0.0, 0.3)
    cone = mj.opt.cone
    try:
        mj.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        dyn._load(x, u, 0)
        mujoco.mj_forward(mj, dyn.data)
        assert dyn.data.nefc > 0
        assert velocity.columns(mj, dyn._twin, dyn.data, dyn._rot_x, dyn._moments) is None
        A, B = dyn._fd(x, u, 0)
        A_fd, B_fd = _mujoco_differences(dyn, x, u, dyn.centered)
        assert np.array_equal(A, A_fd) and np.array_equal(B, B_fd)
    finally:
        mj.opt.cone = cone
    scene = ('<mujoco>{}<worldbody>{}<body><joint name="j" type="hinge"/><geom size=".1"/></body></worldbody>'
             '<actuator><motor joint="j"/></actuator></mujoco>')
    assert velocity.applies(mujoco.MjModel.from_xml_string(scene.format("", "")))
    assert not velocity.applies(mujoco.MjModel.from_xml_string(scene.format('<option density="1.2"/>', "")))
    assert not velocity.applies(mujoco.MjModel.from_xml_string(
        scene.format("", '<body mocap="true" pos="1 0 0"><geom size=".1" contype="0" conaffinity="0"/></body>')))
