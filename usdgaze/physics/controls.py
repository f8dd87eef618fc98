"""A step's derivative by the motors' controls in closed form: MuJoCo's finite differences of them
took about a quarter of ``mjd_transitionFD`` on the CMU body (48 controls, each a constraint solve:
~1.7 ms of ~7 ms a step), and the answer is a few linear solves (~0.35 ms).

A motor on a joint adds ``moment^T ctrl`` to the generalized forces. At the constraint solver's
optimum ``M qacc = f + J^T force``, with ``force = -D (J qacc - aref)`` on the constraint rows that
push (a unilateral row that does not push is inactive) and ``aref`` independent of the forces, so
``d qacc / d f = (M + J_a^T D_a J_a)^-1`` (the implicit function theorem; the Newton solver's own
Hessian). MuJoCo's Euler step then damps joints implicitly, ``qacc' = (M + h B)^-1 M qacc`` (B the
joints' damping), ``qvel' = qvel + h qacc'``, and ``qpos'`` integrates ``h qvel'``: on a ball (and the
free joint's rotation) its tangent moves by ``h Jr(h w') dw'``, ``Jr`` the right Jacobian of SO(3).
Measured against MuJoCo's forward differences on the CMU body, on the ground and in the air: a
relative difference of ~1e-9 (their own error). ``physics.velocity`` adds the velocities' columns
to the same solves (:func:`system`, :func:`damped`, :func:`next_state`).

Only where that holds: Euler, joint motors of fixed gain without bias, activation or force limits
(none disabled),
and constraint rows that are joint limits or frictionless or pyramidal contacts (a row pushes or it
does not); :func:`closed_form` says ``None`` otherwise and the caller differences the controls.
"""

from __future__ import annotations

import numpy as np


def applies(mj) -> bool:
    """Whether the model's motors and integrator are of the kind :func:`closed_form` differentiates."""
    import mujoco

    T, G, B, D = mujoco.mjtTrn, mujoco.mjtGain, mujoco.mjtBias, mujoco.mjtDyn
    off = mj.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_ACTUATION or getattr(mj.opt, "disableactuator", 0)
    return bool(mj.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER and mj.opt.noslip_iterations == 0 and not off
                and mj.na == 0 and mj.nu > 0
                and np.all(mj.actuator_trntype == T.mjTRN_JOINT) and np.all(mj.actuator_gaintype == G.mjGAIN_FIXED)
                and np.all(mj.actuator_biastype == B.mjBIAS_NONE) and np.all(mj.actuator_dyntype == D.mjDYN_NONE)
                and not np.any(mj.actuator_forcelimited))


_KINDS = None


def _pushing_rows(d) -> np.ndarray | None:
    """The constraint rows that push (their mask), or None where a row of another kind (an equality,
    friction loss, an elliptic cone) could be in a linear or cone zone this rule does not cover."""
    global _KINDS
    if _KINDS is None:
        import mujoco

        C = mujoco.mjtConstraint
        kinds = np.zeros(max(int(c) for c in C.__members__.values()) + 1, dtype=bool)
        kinds[[int(C.mjCNSTR_LIMIT_JOINT), int(C.mjCNSTR_LIMIT_TENDON), int(C.mjCNSTR_CONTACT_FRICTIONLESS),
               int(C.mjCNSTR_CONTACT_PYRAMIDAL)]] = True
        _KINDS = kinds
    if not _KINDS[np.asarray(d.efc_type)].all():
        return None
    return np.asarray(d.efc_force) != 0.0


def moments(mj) -> np.ndarray:
    """``(nv, nu)``: the generalized force of each motor's unit control (its gear on its joint's dofs;
    a joint transmission's does not change with the state)."""
    import mujoco

    d = mujoco.MjData(mj)
    mujoco.mj_forward(mj, d)
    moment = np.zeros((mj.nu, mj.nv))
    mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
    return (moment * mj.actuator_gainprm[:, 0][:, None]).T.copy()


def system(mj, d) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """``(M, H, Ja, active)`` at ``d`` after ``mj_forward``: the mass matrix, the constraint solver's
    Hessian ``M + Ja^T Da Ja``, the Jacobian rows that push (``(0, nv)`` if none) and their mask over
    the constraint rows. None where this step's constraints are of a kind the rule does not cover."""
    import mujoco

    active = _pushing_rows(d)
    if active is None:
        return None
    nv = mj.nv
    M = np.zeros((nv, nv))
    mujoco.mj_fullM(mj, d, M)
    H = M.copy()
    Ja = np.zeros((0, nv))
    if active.any():
        J = np.zeros((d.nefc, nv))
        if mujoco.mj_isSparse(mj):
            mujoco.mju_sparse2dense(J, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
        else:
            J[:] = np.asarray(d.efc_J).reshape(d.nefc, nv)
        Ja = J[active]
        H += (Ja.T * d.efc_D[active]) @ Ja
    return M, H, Ja, active


def _inverse_times(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A^-1 X`` for a symmetric positive definite ``A``: its inverse by one Cholesky factorization
    (LAPACK potrf/potri, the upper triangle) times ``X`` (BLAS symm, which reads that triangle): at
    nv ~54 and ~100 columns a third of numpy's ``solve`` (its triangular solves dominate). numpy's
    ``solve`` where ``A`` is not numerically positive definite."""
    from scipy.linalg import blas, lapack

    c, info = lapack.dpotrf(A, lower=False, clean=False)
    if info == 0:
        inv, info = lapack.dpotri(c, lower=False)
    if info != 0:
        return np.linalg.solve(A, X)
    return blas.dsymm(1.0, inv, X, side=0, lower=0)


def damped(mj, M: np.ndarray, H: np.ndarray, forces: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """``(nv, k + 1)``: ``E H^-1 forces`` and ``E acc``, ``H`` the constraint solver's Hessian and
    ``E = (M + hB)^-1 M = I - h (M + hB)^-1 B`` the Euler step's implicit joint damping of an
    acceleration (``B`` the joints' damping; ``I`` where MuJoCo integrates explicitly)."""
    import mujoco

    X = np.column_stack([_inverse_times(H, forces), acc])
    B = np.asarray(mj.dof_damping)
    if mj.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP or not np.any(B > 0):
        return X
    h = mj.opt.timestep
    return X - h * _inverse_times(M + h * np.diag(B), B[:, None] * X)


def next_state(mj, d, both: np.ndarray, rot_x: np.ndarray, velocities: bool = False) -> np.ndarray:
    """``(2nv, k)``: the next state's tangent (positions, then velocities) by ``k`` inputs, from
    ``both`` (:func:`damped`): their columns of the damped acceleration ``qacc'``, then the step's
    own. ``velocities``: the last ``nv`` inputs are the velocities themselves (``qvel' = qvel + h
    qacc'``: their identity added)."""
    h, nv = mj.opt.timestep, mj.nv
    k = both.shape[1] - 1
    out = np.empty((2 * nv, k))
    dv = out[nv:]
    np.multiply(both[:, :-1], h, out=dv)
    if velocities:
        dv[:, k - nv:] += np.eye(nv)
    v_next = np.asarray(d.qvel) + h * both[:, -1]
    from usdgaze.physics.dynamics import _jr

    np.multiply(dv, h, out=out[:nv])
    # a ball's (and the base's) tangent moves by h Jr(h w') dw'
    out[rot_x] = h * np.matmul(_jr(h * v_next[rot_x], inverse=False), dv[rot_x])
    return out


def clamped(mj, ctrl: np.ndarray, force: np.ndarray) -> np.ndarray:
    """``force`` (:func:`moments`) with the columns of controls MuJoCo clamps at or over their range's
    end zeroed: forward differences there move nothing."""
    import mujoco

    lo, hi = mj.actuator_ctrlrange[:, 0], mj.actuator_ctrlrange[:, 1]
    at_end = mj.actuator_ctrllimited.astype(bool) & ((ctrl >= hi) | (ctrl < lo))
    if at_end.any() and not mj.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL:
        return force * ~at_end
    return force


def closed_form(mj, d, ctrl: np.ndarray, rot_x: np.ndarray, force: np.ndarray) -> np.ndarray | None:
    """``(2nv, nu)``: the next state's tangent (position rows, then velocity) by the controls, from
    ``d`` after ``mj_forward`` at the step's state and ``ctrl``; ``rot_x`` ``(blocks, 3)`` the dof
    indices of the rotation blocks (free joint's and balls'), ``force`` :func:`moments`. None where
    this step's constraints are of a kind the rule does not cover."""
    got = system(mj, d)
    if got is None:
        return None
    M, H, _, _ = got
    return next_state(mj, d, damped(mj, M, H, clamped(mj, ctrl, force), np.asarray(d.qacc)), rot_x)
