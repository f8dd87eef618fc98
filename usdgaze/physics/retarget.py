"""Base animation <-> MuJoCo ``qpos``, vectorized over frames (pure numpy).

Forward: skeleton-space FK of the reference gives each simulated joint's world orientation in the
model's frame; a ball joint's quaternion is its rotation relative to its rest frame in the parent
body, a hinge's angle is the twist of that rotation about the hinge axis, and the free base takes the
base joint's world position and orientation. Backward inverts this: local rotations are the rest
rotation times the joint's rotation, the base's local transform comes from its world pose through
the reference's (unsimulated) ancestors and skeleton-to-world transform. Welded joints and joints
outside the model keep the reference's local transforms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.clip import SkelClip
from usdgaze.core.kinematics import world_matrices
from usdgaze.physics.joint_kinds import STILL_DEG
from usdgaze.physics.model import BodyModel


@dataclass
class Reference:
    """A clip's local transforms for every skeleton joint, float64."""

    translations: np.ndarray  # (F, J, 3)
    rotations: np.ndarray  # (F, J, 4) xyzw
    scales: np.ndarray  # (F, J, 3)
    skel_to_world: np.ndarray  # (F, 4, 4) or (1, 4, 4)

    @classmethod
    def from_clip(cls, clip: SkelClip) -> "Reference":
        trs = [clip.local_trs(j) for j in range(len(clip.joints))]
        t, q, s = (np.stack([x[i] for x in trs], axis=1) for i in range(3))
        return cls(t, q, s, np.asarray(clip.skel_to_world, dtype=float).reshape(-1, 4, 4))


# A joint keyed to a zero scale (a hand, an eye or a prop hidden for some frames) has no orientation in
# the world: the retargeting took its rotation from a zero matrix and stopped (SVD did not converge, exit 1).
# Each scale keeps at least this size, with its sign; the body keeps its rest proportions anyway and the
# layer keeps the input's scales.
_MIN_SCALE = 1e-6


def reference_world(ref: Reference, parents: np.ndarray) -> np.ndarray:
    """Stage-world transforms ``(F, J, 4, 4)`` of every joint."""
    scales = np.where(np.abs(ref.scales) < _MIN_SCALE, np.where(ref.scales < 0, -_MIN_SCALE, _MIN_SCALE), ref.scales)
    local = rot.compose_trs(ref.translations, ref.rotations, scales)
    return ref.skel_to_world[:, None] @ world_matrices(local, parents)


def _wxyz(q: np.ndarray) -> np.ndarray:
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


def _xyzw(q: np.ndarray) -> np.ndarray:
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def to_qpos(m: BodyModel, ref: Reference) -> np.ndarray:
    """``qpos`` ``(F, nq)`` of the reference, frame by frame."""
    world = reference_world(ref, m.parents)[:, m.bodies]
    orient, _ = rot.rotation_part(m.to_model @ world[..., :3, :3])  # a mirrored joint: as the model's rest frames
    qadr, _ = m.layout()
    nq = int(qadr[-1] + {"free": 7, "ball": 4, "hinge": 1, "weld": 0}[m.kind[-1]])
    qpos = np.zeros((len(world), nq))
    qpos[:, 0:3] = world[:, 0, :3, 3] @ m.to_model.T
    qpos[:, 3:7] = _wxyz(orient[:, 0])
    # Where a hinge cannot take the reference's turn (its part off the axis: a forearm's pronation keyed
    # on the elbow), the ball joint below it takes that part, so the hand and its fingers stay where the
    # reference has them (the synthetic Mixamo rig's round trip moved a fingertip 2.9 cm otherwise). The
    # bodies below such a hinge, until a ball, are placed as the model's joints turn them; any other body
    # is where the reference has it, bit for bit as before (the simulation is chaotic).
    placed: dict[int, np.ndarray] = {}
    for b in range(1, len(m.bodies)):
        p = m.body_parent[b]
        above = placed.get(p, orient[:, p])
        local = rot.relative(above, orient[:, b])
        if m.kind[b] == "weld":
            if p in placed:  # as the layer writes it: the reference's own turn, on its placed parent
                placed[b] = rot.multiply(above, rot.relative(orient[:, p], orient[:, b]))
            continue
        rel = np.broadcast_to(m.rel_quat[b], local.shape)
        q = rot.relative(rel, local)
        if m.kind[b] == "ball":
            qpos[:, qadr[b]:qadr[b] + 4] = _wxyz(rot.positive_w(q))
            continue
        q = rot.positive_w(q)
        qpos[:, qadr[b]] = 2.0 * np.arctan2(q[:, :3] @ m.axis[b], q[:, 3])
        kept = rot.from_axis_angle(m.axis[b], qpos[:, qadr[b]])
        if p in placed or np.degrees(rot.angle(rot.relative(kept, q))).max() > STILL_DEG:
            placed[b] = rot.multiply(rot.multiply(above, rel), kept)
    return qpos


def from_qpos(m: BodyModel, qpos: np.ndarray, ref: Reference) -> tuple[np.ndarray, np.ndarray]:
    """Skeleton local rotations ``(F, J, 4)`` and translations ``(F, J, 3)`` of simulated ``qpos``.

    Frames of ``qpos`` pair with the reference's frames (the reference supplies what the model does
    not simulate)."""
    qpos = np.asarray(qpos, dtype=float)
    rotations = ref.rotations.copy()
    translations = ref.translations.copy()
    qadr, _ = m.layout()
    for b in range(1, len(m.bodies)):
        j = m.bodies[b]
        if m.kind[b] == "ball":
            q = _xyzw(qpos[:, qadr[b]:qadr[b] + 4])
        elif m.kind[b] == "hinge":
            q = rot.from_axis_angle(m.axis[b], qpos[:, qadr[b]])
        else:
            continue
        rotations[:, j] = rot.multiply(np.broadcast_to(m.rel_quat[b], q.shape), rot.normalize(q))
    base = m.bodies[0]
    parent = m.parents[base]
    if parent >= 0:
        outer = reference_world(ref, m.parents)[:, parent]
    else:
        outer = np.broadcast_to(ref.skel_to_world, (len(qpos), 4, 4))
    lin = m.to_model @ outer[..., :3, :3]  # model-world linear map of the base's parent frame
    p = qpos[:, 0:3] - np.einsum("ij,fj->fi", m.to_model, outer[..., :3, 3])
    translations[:, base] = np.linalg.solve(lin, p[..., None])[..., 0]
    rotations[:, base] = rot.relative(rot.from_matrix(lin), _xyzw(qpos[:, 3:7]))
    rotations = rot.align_hemisphere(rotations, ref.rotations)
    return rotations, translations
