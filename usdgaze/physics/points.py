"""Body points and frames of a planner state, with their Jacobians in the state's minimal coordinates.

What the task costs read from the body (a foot's contact point and its orientation, the root): MuJoCo's
kinematics at the state's ``qpos`` and ``mj_jac`` for the derivatives. ``mj_jac`` differentiates with
respect to MuJoCo's velocity tangent; a rotation block of the state is a rotation vector, whose
tangent is ``Jr(r) dr`` (the right Jacobian of SO(3)), so those columns are multiplied by ``Jr``,
as the tracking cost does for the root-to-head vector.
"""

from __future__ import annotations

import numpy as np

from usdgaze.physics.dynamics import MujocoBody, _jr, _skew


class Points:
    """Kinematics of chosen MuJoCo bodies for one body part, on a data buffer of its own."""

    def __init__(self, dyn: MujocoBody) -> None:
        import mujoco

        self.dyn = dyn
        self.data = mujoco.MjData(dyn.mj)
        self._rot = dyn._rot[:, None] + np.arange(3)

    def pose(self, xb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body origins ``(nbody, 3)`` and frames ``(nbody, 3, 3)`` at body state ``xb``."""
        import mujoco

        self.data.qpos[:], _ = self.dyn.to_mujoco(xb)
        mujoco.mj_kinematics(self.dyn.mj, self.data)
        return self.data.xpos.copy(), self.data.xmat.reshape(-1, 3, 3).copy()

    def jacobian(self, xb: np.ndarray, body: int, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d point / d q and the body's angular Jacobian ``(3, nv)`` each, in the state's coordinates.

        Call after :meth:`pose` at the same ``xb`` (its kinematics are reused)."""
        import mujoco

        mujoco.mj_comPos(self.dyn.mj, self.data)
        nv = self.dyn.nv
        jp, jr = np.zeros((3, nv)), np.zeros((3, nv))
        mujoco.mj_jac(self.dyn.mj, self.data, jp, jr, np.asarray(point, float), body)
        maps = _jr(xb[self._rot], inverse=False)
        for b, cols in enumerate(self._rot):
            jp[:, cols] = jp[:, cols] @ maps[b]
            jr[:, cols] = jr[:, cols] @ maps[b]
        return jp, jr


def frame_jacobian(R: np.ndarray, jr: np.ndarray) -> np.ndarray:
    """d vec(R) / d q ``(9, nv)`` from the angular Jacobian: dR = [w]x R for each column of ``jr``."""
    return np.einsum("nij,jk->ikn", _skew(jr.T), R).reshape(9, -1)
