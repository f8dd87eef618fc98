"""Forward kinematics over frames, vectorized: joints loop (parents first), frames are array axes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot


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
    """Full 3x3 linear part ``(F, 3, 3)`` including scale; empty when every scale is 1."""
    position: dict[int, np.ndarray]
    """Joint origins ``(F, 3)``."""

    def place(self, j: int, offset: np.ndarray) -> np.ndarray:
        """World position of a point given in joint ``j``'s local frame (e.g. a child's translation)."""
        if j in self.linear:
            return self.position[j] + np.einsum("fij,fj->fi", self.linear[j], offset)
        return self.position[j] + rot.rotate(self.rotation[j], offset)


def forward(joints: list[int], parents: np.ndarray, local, rotations: dict[int, np.ndarray] | None = None,
            positions: bool = True, scaled_by: list[int] | None = None) -> Pose:
    """FK of ``joints`` (closed under ancestors, parents first); ``local(j)`` gives (t, q, s) per frame.

    With all scales exactly 1 (mocap, most rigs) positions come from quaternions alone; otherwise
    full 3x3 linear parts carry the scales down the chain. ``rotations`` are world rotations the
    caller already composed the same way from the same locals, taken as they are. ``positions=False``
    leaves out the joints' positions but the roots' (a later call with these rotations adds them).
    ``scaled_by`` (default ``joints``) are the joints whose scales decide whether the pose carries
    linear parts, so that a pose of fewer joints has those a later call over all of them has.
    """
    rotations = rotations or {}
    pose = Pose({}, {}, {})
    trs = {j: local(j) for j in joints}
    scales = [trs[j][2] for j in joints] if scaled_by is None else [local(j)[2] for j in scaled_by]
    unit = all(_all_one(s) for s in scales)
    for j in joints:
        t, q, s = trs[j]
        p = int(parents[j])
        if p < 0:
            pose.rotation[j], pose.position[j] = rot.normalize(q), t
            if not unit:
                pose.linear[j] = rot.to_matrix(q) * s[..., None, :]
            continue
        if positions:
            pose.position[j] = pose.place(p, t)
        pose.rotation[j] = rotations[j] if j in rotations else rot.normalized_product(pose.rotation[p], q)
        if not unit:
            pose.linear[j] = pose.linear[p] @ (rot.to_matrix(q) * s[..., None, :])
    return pose


def _all_one(s: np.ndarray) -> bool:
    """Whether every scale is exactly 1; a column broadcast from one row (a constant one, as most
    scales are) is judged by that row."""
    s = np.asarray(s)
    if s.ndim and len(s) and s.strides[0] == 0:
        s = s[:1]
    return bool(np.all(s == 1.0))


UP_SNAP_DEG = 30.0
"""The stage's up carried into skeleton space within this of one of its axes is that axis: a character
placed on a slope (a parent pitched 10 deg) is modelled upright in its own space, and taking the
tilted vector made its forward, and the eyes' modelled axis with it, miss every target by the tilt.
An axis exactly (a Z-up rig turned into a Y-up stage) is kept as it is."""


def snap_up(up: np.ndarray) -> np.ndarray:
    """``up`` (skeleton space) as the nearest skeleton axis when within :data:`UP_SNAP_DEG` of it,
    else ``up`` normalized."""
    up = rot.normalize(np.asarray(up, dtype=float))
    axis = int(np.argmax(np.abs(up)))
    if np.degrees(np.arccos(min(1.0, abs(float(up[axis]))))) < UP_SNAP_DEG:
        snapped = np.zeros(3)
        snapped[axis] = np.sign(up[axis])
        return snapped
    return up
