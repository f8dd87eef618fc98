"""Forward kinematics over frames, vectorized: joints loop (parents first), frames are array axes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import rotations as rot


def world_matrices(local: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Skeleton-space transforms ``(F, J, 4, 4)`` from local ones (parents precede children)."""
    world = np.empty_like(local)
    for j, p in enumerate(parents):
        world[:, j] = local[:, j] if p < 0 else world[:, p] @ local[:, j]
    return world


def with_ancestors(joints, parents: np.ndarray) -> list[int]:
    """The given joints and all their ancestors, parents first."""
    out: set[int] = set()
    for j in joints:
        while j >= 0 and j not in out:
            out.add(int(j))
            j = int(parents[j])
    return sorted(out)


@dataclass
class Pose:
    """World (skeleton-space) state of a set of joints over frames."""

    rotation: dict[int, np.ndarray]
    """Unit quaternions ``(F, 4)``; exact for uniform scales."""
    linear: dict[int, np.ndarray]
    """Full 3x3 linear part ``(F, 3, 3)`` including scale, for placing children."""
    position: dict[int, np.ndarray]
    """Joint origins ``(F, 3)``."""


def forward(joints: list[int], parents: np.ndarray, local) -> Pose:
    """FK of ``joints`` (closed under ancestors, parents first); ``local(j)`` gives (t, q, s) per frame."""
    pose = Pose({}, {}, {})
    for j in joints:
        t, q, s = local(j)
        lin = rot.to_matrix(q) * s[..., None, :]
        p = int(parents[j])
        if p < 0:
            pose.rotation[j], pose.linear[j], pose.position[j] = rot.normalize(q), lin, t
        else:
            pose.rotation[j] = rot.normalize(rot.multiply(pose.rotation[p], q))
            pose.linear[j] = pose.linear[p] @ lin
            pose.position[j] = pose.position[p] + np.einsum("fij,fj->fi", pose.linear[p], t)
    return pose
