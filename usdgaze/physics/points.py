"""Body points and frames of a planner state, with their Jacobians in the state's minimal coordinates.

What the task costs read from the body (a foot's contact point and its orientation, the root, the
capsules the obstacles must not touch): MuJoCo's kinematics at the state's ``qpos`` and ``mj_jac`` for the derivatives. ``mj_jac`` differentiates with
respect to MuJoCo's velocity tangent; a rotation block of the state is a rotation vector, whose
tangent is ``Jr(r) dr`` (the right Jacobian of SO(3)), so those columns are multiplied by ``Jr``,
as the tracking cost does for the root-to-head vector.
"""

from __future__ import annotations

import numpy as np

from usdgaze.physics.dynamics import MujocoBody, _jr, _skew
from usdgaze.physics.shapes import CAPSULE, SPHERE, half_lengths


class Points:
    """Kinematics of chosen MuJoCo bodies for one body part, on a data buffer of its own."""

    def __init__(self, dyn: MujocoBody) -> None:
        import mujoco

        self.dyn = dyn
        self.data = mujoco.MjData(dyn.mj)
        self._rot = dyn._rot[:, None] + np.arange(3)

    def pose(self, xb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body origins ``(nbody, 3)`` and frames ``(nbody, 3, 3)`` at body state ``xb``."""
        self.kinematics(xb)
        return self.data.xpos.copy(), self.data.xmat.reshape(-1, 3, 3).copy()

    def kinematics(self, xb: np.ndarray) -> None:
        """MuJoCo's kinematics at body state ``xb`` on this buffer (``data``)."""
        import mujoco

        self.data.qpos[:] = self.dyn.qpos_of(xb)
        mujoco.mj_kinematics(self.dyn.mj, self.data)

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

    def body_jacobians(self, xb: np.ndarray, bodies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Translational Jacobians of the bodies' origins and their angular Jacobians, ``(n, 3, nv)``
        each, in the state's coordinates; a point ``p`` fixed on body ``b`` then has
        ``jp[b] - [p - xpos[b]]x jr[b]``. Call after :meth:`pose` at the same ``xb``."""
        import mujoco

        mujoco.mj_comPos(self.dyn.mj, self.data)
        nv = self.dyn.nv
        jp, jr = np.zeros((len(bodies), 3, nv)), np.zeros((len(bodies), 3, nv))
        for i, b in enumerate(bodies):
            mujoco.mj_jac(self.dyn.mj, self.data, jp[i], jr[i], self.data.xpos[b], int(b))
        maps = _jr(xb[self._rot], inverse=False)
        jp[:, :, self._rot] = np.einsum("nibc,bcd->nibd", jp[:, :, self._rot], maps)
        jr[:, :, self._rot] = np.einsum("nibc,bcd->nibd", jr[:, :, self._rot], maps)
        return jp, jr


class Capsules:
    """The body's collision capsules (and spheres) as segments with radii: centre ``c``, unit axis
    ``a`` and half-length ``half`` (0 for a sphere), so the geom is every point within ``radius`` of
    ``c + t a``, ``|t| <= half``."""

    def __init__(self, dyn: MujocoBody) -> None:
        mj = dyn.mj
        self.points = Points(dyn)
        self.geoms = np.array([g for g in range(mj.ngeom) if mj.geom_bodyid[g] > 0 and mj.geom_type[g] in (SPHERE, CAPSULE)])
        self.body = mj.geom_bodyid[self.geoms].astype(int)
        self.radius = mj.geom_size[self.geoms, 0].copy()
        self.half = half_lengths(mj, self.geoms)

    def segments(self, xb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres and axes ``(G, 3)`` at body state ``xb`` (kinematics left for :meth:`jacobians`)."""
        self.points.kinematics(xb)
        d = self.points.data
        return d.geom_xpos[self.geoms].copy(), d.geom_xmat[self.geoms].reshape(-1, 3, 3)[:, :, 2].copy()

    def project(self, xb: np.ndarray, geoms: np.ndarray, p: np.ndarray, vecs: np.ndarray) -> np.ndarray:
        """``vecs[i] @ d p_i / d q`` ``(n, nv)`` for world points ``p`` ``(n, 3)`` fixed on geoms
        ``geoms`` (indices into this list) and vectors ``vecs`` ``(n, 3)``: with ``J_i = jp_b - [p_i -
        x_b]x jr_b`` that is ``vecs_i jp_b + ((p_i - x_b) x vecs_i) jr_b``, one product with the bodies'
        stacked Jacobians. Call after :meth:`segments` at the same ``xb``."""
        bodies, inverse = np.unique(self.body[geoms], return_inverse=True)
        jp, jr = self.points.body_jacobians(xb, bodies)
        arm = p - self.points.data.xpos[bodies][inverse]
        w = np.zeros((len(p), len(bodies), 6))
        rows = np.arange(len(p))
        w[rows, inverse, :3] = vecs
        w[rows, inverse, 3:] = np.cross(arm, vecs)
        return w.reshape(len(p), -1) @ np.concatenate([jp, jr], axis=1).reshape(-1, jp.shape[2])


def frame_jacobian(R: np.ndarray, jr: np.ndarray) -> np.ndarray:
    """d vec(R) / d q ``(9, nv)`` from the angular Jacobian: dR = [w]x R for each column of ``jr``."""
    return np.einsum("nij,jk->ikn", _skew(jr.T), R).reshape(9, -1)
