"""The step's derivative by the motors' controls in closed form (``physics.controls``) against
MuJoCo's own finite differences of them (``mjd_transitionFD``), on the CMU body: feet on the ground
(contact rows pushing and not), in the air, fast, with a toe motor held at its limit; and MuJoCo's
differences kept where the closed form does not apply."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from usdgaze.physics import controls

from .test_physics_dynamics import body  # noqa: F401  (the CMU body and its reference, a module fixture)


STATES = [(400, 0.0, 0.3), (100, 0.0, 2.0), (700, 0.4, 1.0), (250, -0.01, 0.5)]
"""(reference frame, root lifted by m, velocity spread): on the ground, fast, in the air, pressed in."""


def _mujoco_differences(dyn, x, u, centered: bool | None = None):
    """MuJoCo's finite differences of the whole step (A and B) at ``x``, ``u``, in its tangent space
    (``centered``: the body's own setting where None)."""
    dyn._load(x, u, 0)
    A = np.zeros((dyn.nx, dyn.nx))
    B = np.zeros((dyn.nx, dyn.nu))
    mujoco.mjd_transitionFD(dyn.mj, dyn.data, dyn.eps, dyn.centered if centered is None else centered,
                            A, B, None, None)
    return A, B


def _state(dyn, qpos, frame, lift, speed):
    """A state off the reference's ``frame`` (root raised ``lift`` m, velocities of spread ``speed``)
    and controls, seeded by the frame."""
    rng = np.random.default_rng(frame)
    q = qpos[frame].copy()
    q[2] += lift
    return dyn.to_state(q, rng.normal(0, speed, dyn.nv)), rng.normal(0, 0.5, dyn.nu)


def _some_rows_push(dyn, x, u) -> None:
    """At ``x``, ``u`` some contact rows push and some do not: the closed forms' active set is met."""
    dyn._load(x, u, 0)
    mujoco.mj_forward(dyn.mj, dyn.data)
    pushing = np.asarray(dyn.data.efc_force) != 0
    assert pushing.any() and not pushing.all(), "rows that push and rows that do not"


@pytest.mark.parametrize("frame, lift, speed", STATES)
def test_control_columns_match_mujocos_differences(body, frame, lift, speed):
    dyn, qpos = body
    assert dyn.closed_controls
    x, u = _state(dyn, qpos, frame, lift, speed)
    limited = np.flatnonzero(dyn.mj.actuator_ctrllimited)
    assert len(limited) > 0
    u[limited[0]] = 1.5  # a toe motor beyond its range: clamped by MuJoCo, it moves nothing
    A_fd, B_fd = _mujoco_differences(dyn, x, u)
    A, B = dyn._fd(x, u, 0)
    # the positions' columns are MuJoCo's rule, bit for bit; the velocities' in closed form
    # (physics.velocity, tests/test_physics_velocity.py)
    assert np.array_equal(A[:, :dyn.nv], A_fd[:, :dyn.nv])
    assert np.abs(A - A_fd).max() < 1e-6 * np.abs(A_fd).max()
    assert np.linalg.norm(B - B_fd) / np.linalg.norm(B_fd) < 1e-6
    assert np.abs(B - B_fd).max() < 1e-6 * np.abs(B_fd).max()
    assert np.all(B[:, limited[0]] == 0.0) and np.all(B_fd[:, limited[0]] == 0.0)
    if lift <= 0.0:
        _some_rows_push(dyn, x, u)


def test_mujocos_differences_where_the_closed_form_does_not_apply(body):
    """An elliptic friction cone (a contact row can slide, in its cone zone): MuJoCo differences the controls."""
    dyn, qpos = body
    mj = dyn.mj
    rng = np.random.default_rng(1)
    x = dyn.to_state(qpos[400].copy(), rng.normal(0, 0.3, dyn.nv))
    u = rng.normal(0, 0.5, dyn.nu)
    cone = mj.opt.cone
    try:
        mj.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        dyn._load(x, u, 0)
        mujoco.mj_forward(mj, dyn.data)
        assert dyn.data.nefc > 0
        assert controls.closed_form(mj, dyn.data, u, dyn._rot_x, dyn._moments) is None
        A, B = dyn._fd(x, u, 0)
        assert np.array_equal(B, _mujoco_differences(dyn, x, u)[1])
    finally:
        mj.opt.cone = cone
    motor = ('<mujoco>{}<worldbody><body><joint name="j" type="hinge"/><geom size=".1"/></body></worldbody>'
             '<actuator><motor joint="j"/></actuator></mujoco>')
    assert controls.applies(mujoco.MjModel.from_xml_string(motor.format("")))
    # motors switched off: the controls move nothing, which MuJoCo's differences say and the rule would not
    assert not controls.applies(mujoco.MjModel.from_xml_string(motor.format('<option><flag actuation="disable"/></option>')))
    assert not controls.applies(mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint name="j" type="hinge"/><geom size=".1"/></body></worldbody>'
        '<actuator><position joint="j" kp="10"/></actuator></mujoco>'))
