"""The planner's guess of the reference's torques (``mpc.Shot.tail``): inverse dynamics with no ground,
the body's weight then shared among the feet near the ground.

The guess is the warm start of each window's new last step and of the whole cold first window; with
one solver iteration a step it decides much of the control applied. It is made in two parts:

* MuJoCo's ``mj_inverse`` of the target **without contacts**. Its inverse of soft contacts makes a
  force of how deep a foot sits, not of the load it carries: at the start of ``stepping_stones.usda``
  a swinging toe inside the contact margin got hundreds of newtons and the left hip, ankle and toe
  came out at their motors' limits (the walk fell at 0.58 s in every run).
* **Then the support** (:func:`support_forces`): without contacts the weight and the root's
  acceleration sit on the root's residual, which no motor carries, so the legs' torques held up only
  the legs. A ground reaction at the feet's capsule ends replaces that residual as well as it can
  (least squares, non-negative forces in a friction pyramid), the ends higher up or moving faster
  costing more, and the joints' torques take its share: ``tau - J' f``. Measured (docs/physics-log.md,
  "The support in the warm start"): the 120 fps stones sample's first 1.5 s stands and lands every
  stone in time in 8 of 8 observation seeds (3 of 8 before, two falls), and the CMU walk's soft
  contact sinks 3.3 cm, not 4.0.
"""

from __future__ import annotations

import copy

import numpy as np

from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.measures import foot_geoms
from usdgaze.physics.shapes import half_lengths

REACH_M = 0.06  # a capsule end higher than this carries nothing (CMU 131_01's right foot floats 3.7-4.9 cm)
HEIGHT_M = 0.01  # an end this high costs twice as much to load as one on the ground
SPEED_M_S = 0.3  # as does one moving this fast
MU = 0.7  # the pyramid's slope, under the ground's friction of 1.0: no guess that slides
REGULARIZATION = 1e-3  # per (newton)^2, against the residual's (newton)^2 and (newton metre)^2
_EDGES = np.array([[MU, 0.0, 1.0], [-MU, 0.0, 1.0], [0.0, MU, 1.0], [0.0, -MU, 1.0]]).T  # 3 x 4


def inverse_dynamics(plan: MujocoBody, qpos: np.ndarray, qvel: np.ndarray, h: float) -> np.ndarray:
    """Controls ``(K, nu)`` whose torques realize the reference's accelerations (from ``qvel``'s
    differences) with no ground, less the support's share (:func:`support_forces`), clipped to the
    motors' strengths (``|u| <= 1``, the gear being a human peak torque)."""
    import mujoco

    mj = copy.copy(plan.mj)  # the planner's own model keeps its contacts
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    d = mujoco.MjData(mj)
    gear = np.abs(mj.actuator_gear[:, :3]).max(axis=1)
    ends = foot_geoms(plan.mj, plan.model)
    out = np.zeros((len(qpos), plan.nu))
    for k in range(len(qpos)):
        d.qpos[:], d.qvel[:] = qpos[k], qvel[k]
        d.qacc[:] = (qvel[min(k + 1, len(qvel) - 1)] - qvel[k]) / h
        mujoco.mj_inverse(mj, d)
        tau = d.qfrc_inverse.copy()
        tau -= support_forces(mj, d, tau, ends)
        out[k] = tau[6:] / gear
    return np.clip(out, -1.0, 1.0)


def support_forces(mj, d, tau: np.ndarray, geoms: np.ndarray) -> np.ndarray:
    """``(nv,)`` generalized forces of the ground reaction at ``geoms``' capsule ends that best carry
    the root's part of ``tau`` (a contact-free inverse at ``d``'s state; ``d``'s kinematics done):
    ``J' f`` with each end's force in the friction pyramid, none above :data:`REACH_M`."""
    import mujoco
    from scipy.optimize import nnls

    mujoco.mj_comPos(mj, d)  # mj_jac reads the bodies' com frames
    jacp = np.zeros((3, mj.nv))
    columns, weights = [], []
    for g in geoms:
        axis = d.geom_xmat[g].reshape(3, 3)[:, 2]
        half = float(half_lengths(mj, g))
        for side in (1.0, -1.0):
            end = d.geom_xpos[g] + side * half * axis - np.array([0.0, 0.0, mj.geom_size[g, 0]])
            if end[2] > REACH_M:
                continue
            mujoco.mj_jac(mj, d, jacp, None, end, int(mj.geom_bodyid[g]))
            speed = float(np.linalg.norm(jacp @ d.qvel))
            columns.append(jacp.T @ _EDGES)
            weights += [1.0 + (max(end[2], 0.0) / HEIGHT_M) ** 2 + (speed / SPEED_M_S) ** 2] * 4
    if not columns:
        return np.zeros(mj.nv)
    G = np.concatenate(columns, axis=1)  # nv x (4 per end)
    A = np.vstack([G[:6], np.diag(np.sqrt(REGULARIZATION * np.asarray(weights)))])
    try:
        c, _ = nnls(A, np.r_[tau[:6], np.zeros(len(weights))])
    except RuntimeError:  # its iteration limit (never seen): the step keeps the guess without the ground
        return np.zeros(mj.nv)
    return G @ c
