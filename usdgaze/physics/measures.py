"""What a simulated shot is measured by, on MuJoCo states: joint and heading errors against the
reference, a run that blew up, and how deep the feet are in the ground."""

from __future__ import annotations

import numpy as np

from usdgaze.physics.model import BodyModel
from usdgaze.physics.shapes import half_lengths


def joint_errors_deg(model: BodyModel, qpos: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Mean joint-angle error per frame over the ball and hinge joints, degrees."""
    from usdgaze.physics.retarget import _xyzw
    from usdgaze.core import rotations as rot

    qadr, _ = model.layout()
    errs = []
    for b, kind in enumerate(model.kind):
        a = qadr[b]
        if kind == "ball":
            errs.append(rot.angle(rot.relative(_xyzw(qpos[:, a:a + 4]), _xyzw(ref[:, a:a + 4]))))
        elif kind == "hinge":
            errs.append(np.abs((qpos[:, a] - ref[:, a] + np.pi) % (2 * np.pi) - np.pi))
    return np.degrees(np.mean(errs, axis=0))


def heading_errors_deg(qpos: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """How far the simulated base has turned about the vertical from the reference's, per frame, in
    degrees (the twist about model Z of ``q_sim q_ref^-1``; the joint errors do not see the base)."""
    w1, v1 = qpos[:, 3], qpos[:, 4:7]  # MuJoCo's w, x, y, z
    w2, v2 = ref[:, 3], -ref[:, 4:7]  # the reference's inverse
    w = w1 * w2 - np.sum(v1 * v2, axis=1)
    z = w1 * v2[:, 2] + w2 * v1[:, 2] + v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0]
    twist = 2.0 * np.arctan2(z, w)
    return np.degrees(np.abs((twist + np.pi) % (2 * np.pi) - np.pi))


def blown_up(qpos: np.ndarray, qvel: np.ndarray, ref: np.ndarray, height: float) -> bool:
    """A finite state no body reaches (MuJoCo's step can run away without a NaN): the base more than
    three heights from the reference's, or faster than 50 m/s, or a joint spinning at 500 rad/s."""
    return bool(np.linalg.norm(qpos[:3] - ref[:3]) > 3.0 * height or np.linalg.norm(qvel[:3]) > 50.0
                or np.abs(qvel[3:]).max(initial=0.0) > 500.0)


def bottom_point(mj, d, g: int) -> np.ndarray:
    """The lowest point of a capsule or sphere geom (world)."""
    axis = d.geom_xmat[g].reshape(3, 3)[:, 2]
    half = half_lengths(mj, g)
    end = d.geom_xpos[g] - np.sign(axis[2]) * half * axis
    return end - np.array([0.0, 0.0, mj.geom_size[g, 0]])


def foot_geoms(mj, model: BodyModel) -> np.ndarray:
    """The geoms of the feet and their toes (every body whose role is a foot), in MuJoCo's order."""
    return np.flatnonzero(np.isin(mj.geom_bodyid - 1, [b for b, r in enumerate(model.role) if r == "foot"]))


def lowest_z(mj, d, geoms: np.ndarray) -> float:
    """The height of the lowest point of the given capsule and sphere geoms (inf for none): the z of
    :func:`bottom_point`, bit for bit (``sign(a) half a`` is ``|a| half``), for all of them at once."""
    geoms = np.asarray(geoms, dtype=int)
    if not len(geoms):
        return np.inf
    half = half_lengths(mj, geoms)
    z = d.geom_xpos[geoms, 2] - np.abs(d.geom_xmat[geoms, 8]) * half - mj.geom_size[geoms, 0]
    return float(z.min())


def foot_depth(mj, d, geoms: np.ndarray) -> float:
    """How far the lowest point of the given capsule geoms is below the ground (0 if above)."""
    return max(0.0, -lowest_z(mj, d, geoms))


def lowest_zs(mj, qpos: np.ndarray, geoms: np.ndarray) -> np.ndarray:
    """(K,) :func:`lowest_z` at each state of ``qpos``."""
    import mujoco

    d = mujoco.MjData(mj)
    out = np.zeros(len(qpos))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(mj, d)
        out[k] = lowest_z(mj, d, geoms)
    return out


def foot_depths(mj, qpos: np.ndarray, geoms: np.ndarray) -> np.ndarray:
    """(K,) :func:`foot_depth` at each state of ``qpos``."""
    depth = -lowest_zs(mj, qpos, geoms)
    return np.where(depth > 0.0, depth, 0.0)  # as max(0.0, depth): a -0.0 or a NaN is 0.0


def start_lift(mj, d, qpos0: np.ndarray) -> float:
    """How far to raise the first state so that no geom starts in the ground: a reference whose first
    frame puts a foot (with the model's sole) below the floor would otherwise start with MuJoCo's soft
    contact pushing it out at once, and the shot's report would open with that depth."""
    import mujoco

    d.qpos[:] = qpos0
    mujoco.mj_kinematics(mj, d)
    geoms = np.flatnonzero(mj.geom_bodyid > 0)
    return foot_depth(mj, d, geoms)
