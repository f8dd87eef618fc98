"""A step's derivative by the velocities in closed form, and by the positions in one batch of steps.

MuJoCo's ``mjd_transitionFD`` steps the model once per velocity and once per position (on the CMU
body ~2 x 54 constraint solves; a velocity step skips the positions' stages but still solves the
constraints, so it costs about as much). The velocity columns have the closed form of the controls'
(``physics.controls``): at the solver's optimum ``H qacc = qfrc_smooth(v) + Ja^T Da aref_a`` with
``H = M + Ja^T Da Ja`` over the rows that push, and per row ``aref = -b (J v) - k i (pos - margin)``
(``efc_KBIP``: only ``b`` meets the velocity; ``D``, ``k`` and the impedance ``i`` are the
positions'), so ``d qacc / d v = H^-1 (d qfrc_smooth / d v - Ja^T Da diag(b_a) Ja)``.
``d qfrc_smooth / d v`` (the Coriolis forces', the joints' damping, any velocity-dependent passive or
actuator force) is MuJoCo's own analytic ``qDeriv``, the one its implicit integrator makes
(``mj_implicit`` on a copy of the model set to ``implicit``, the only integrator that keeps the
Coriolis term). The Euler step then damps implicitly, ``qacc' = (M + hB)^-1 M qacc``, with the
explicit damping force ``-B v`` already in ``qacc``, and ``qvel' = qvel + h qacc'`` adds the identity
(``controls.next_state``). Against MuJoCo's differences on the CMU body, on the ground and in the
air: ~2e-8 relative (forward differences' own error), ~5e-9 against centred ones.

The position columns stay finite differences, MuJoCo's rule (``mjd_stepFD``): each dof nudged by
``mj_integratePos``, one full step from the input's warm start, the next states differenced by
``mj_differentiatePos``; the steps run as one ``mujoco.rollout`` call, which releases the GIL for all
of them (a Python loop of ``mj_step`` would hold it between steps), bit for bit MuJoCo's columns.
On the CMU body's planner steps this linearization takes ~22-27% less CPU than ``mjd_transitionFD``'s
(e.g. 3.7 against 4.8 ms a step, the controls' closed form in both).
"""

from __future__ import annotations

import numpy as np

from usdgaze.physics import controls


def applies(mj) -> bool:
    """Whether :func:`columns` and :func:`position_columns` cover the model: ``controls.applies``, no
    fluid forces (their velocity derivative is not checked here), and no mocap bodies or equalities
    (``mujoco.rollout`` sets those to the model's defaults, where MuJoCo's differences keep the data's)."""
    return bool(controls.applies(mj) and mj.opt.density == 0 and mj.opt.viscosity == 0
                and mj.nmocap == 0 and mj.neq == 0)


def implicit_twin(mj):
    """A copy of ``mj`` whose ``mj_implicit`` makes the full ``qDeriv`` (Coriolis included)."""
    import copy

    import mujoco

    twin = copy.copy(mj)
    twin.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT
    return twin


def smooth_derivative(twin, d) -> np.ndarray:
    """``(nv, nv)``: ``d qfrc_smooth / d qvel`` at ``d`` after ``mj_forward``. This runs the implicit
    step on ``d`` (its state moves on): read what else is needed first."""
    import mujoco

    mujoco.mj_implicit(twin, d)
    out = np.zeros((twin.nv, twin.nv))
    mujoco.mju_sparse2dense(out, d.qDeriv, twin.D_rownnz, twin.D_rowadr, twin.D_colind)
    return out


def columns(mj, twin, d, rot_x: np.ndarray, force: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(2nv, nv)`` velocity columns and ``(2nv, nu)`` control columns of the step's transition, from
    ``d`` after ``mj_forward`` at the step's state and controls (``controls.closed_form``'s arguments;
    ``twin`` :func:`implicit_twin`). None where the constraints are of a kind not covered. Leaves
    ``d`` stepped (:func:`smooth_derivative`)."""
    got = controls.system(mj, d)
    if got is None:
        return None
    M, H, Ja, active = got
    nu = mj.nu
    b = np.asarray(d.efc_KBIP).reshape(-1, 4)[active, 1]  # aref's velocity gain per pushing row
    drag = (Ja.T * (np.asarray(d.efc_D)[active] * b)) @ Ja
    force = controls.clamped(mj, np.asarray(d.ctrl), force)
    qvel = np.asarray(d.qvel).copy()  # the step's: smooth_derivative moves d on
    acc = np.asarray(d.qacc).copy()
    both = controls.damped(mj, M, H, np.hstack([force, smooth_derivative(twin, d) - drag]), acc)
    d.qvel[:] = qvel
    rows = controls.next_state(mj, d, both, rot_x, velocities=True)
    return rows[:, nu:], rows[:, :nu]


def position_columns(mj, d, eps: float, centered: bool) -> np.ndarray:
    """``(2nv, nv)``: the next state's tangent by each dof's position, MuJoCo's finite differences
    (forward, or centred) from ``d`` loaded at the step's input (state, controls, forces, time and
    warm start, not yet stepped)."""
    import mujoco
    from mujoco import rollout

    S = mujoco.mjtState
    nq, nv = mj.nq, mj.nv
    spec, inputs = S.mjSTATE_FULLPHYSICS, S.mjSTATE_CTRL | S.mjSTATE_QFRC_APPLIED | S.mjSTATE_XFRC_APPLIED
    q0 = mujoco.mj_stateSize(mj, S.mjSTATE_TIME)  # where qpos, then qvel, sit in the state vector
    state = np.zeros(mujoco.mj_stateSize(mj, spec))
    mujoco.mj_getState(mj, d, state, spec)
    held = np.zeros(mujoco.mj_stateSize(mj, inputs))
    mujoco.mj_getState(mj, d, held, inputs)
    # rows: forward, the unperturbed step then +eps per dof; centred, +eps and -eps per dof
    starts = np.tile(state, (2 * nv if centered else nv + 1, 1))
    e = np.zeros(nv)
    for i in range(nv):
        e[i] = 1.0
        for j, sign in enumerate((1.0, -1.0) if centered else (1.0,)):
            row = 2 * i + j if centered else i + 1
            mujoco.mj_integratePos(mj, starts[row, q0:q0 + nq], e, sign * eps)
        e[i] = 0.0
    warm = np.asarray(d.qacc_warmstart).copy()[None]
    out = rollout.rollout(mj, d, starts, held[None, None], control_spec=inputs, nstep=1, initial_warmstart=warm)[0][:, 0]
    qs, vs = out[:, q0:q0 + nq], out[:, q0 + nq:q0 + nq + nv]
    A = np.zeros((2 * nv, nv))
    dq = np.zeros(nv)
    for i in range(nv):
        lo, hi = (2 * i + 1, 2 * i) if centered else (0, i + 1)
        mujoco.mj_differentiatePos(mj, dq, (2 if centered else 1) * eps, qs[lo], qs[hi])
        A[:nv, i] = dq
    lo, hi = (slice(1, None, 2), slice(0, None, 2)) if centered else (slice(0, 1), slice(1, None))
    A[nv:] = ((vs[hi] - vs[lo]) * (1 / ((2 if centered else 1) * eps))).T  # MuJoCo's (x2 - x1) * (1/h)
    return A
