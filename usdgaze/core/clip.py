"""A skeleton and its animation as plain arrays: what flows from the stage reader to the model."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.names import spelled_with_names


@dataclass
class SkelClip:
    """One skeleton and its bound SkelAnimation.

    Joint-indexed arrays are in skeleton order (``joints``) unless named ``anim_*``; matrices are
    column-vector (see :mod:`usdgaze.core.rotations`). Animation samples keep their USD types (float32
    quaternions xyzw, float32 translations, float16 scales) so untouched joints are written back
    bit for bit.
    """

    source: str
    skel_root: str
    skeleton: str
    animation: str
    joints: list[str]
    parents: np.ndarray
    rest_local: np.ndarray
    bind_world: np.ndarray
    anim_joints: list[str]
    anim_to_skel: np.ndarray
    """The skeleton joint of each animation column; -1 for a joint the skeleton lacks (UsdSkel ignores it)."""
    times: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    skel_to_world: np.ndarray
    up_axis: str
    meters_per_unit: float
    time_codes_per_second: float
    frames_per_second: float
    start_time: float
    end_time: float
    joint_names: list[str] | None = None
    neutral_world: np.ndarray | None = None
    """Skeleton-space transforms ``(J, 4, 4)`` of the neutral pose, where the character, its head and
    its eyes look straight ahead: the bind pose, or the rest pose where bindTransforms is unusable."""
    neutral_source: str = "restTransforms"
    """Which pose :meth:`neutral` is, and why (``bindTransforms``, ``restTransforms (...)``)."""
    authored_poses: tuple[bool, bool] = (True, True)
    """Whether the input authors (restTransforms, bindTransforms): a layer adding joints extends only those."""
    held_pose: bool = False
    """The animation holds one pose (defaults only, or none is bound): ``times`` are the frames of the
    stage's playback range, not time samples of the input."""
    animation_bound: bool = True
    """False for a Skeleton with no animation bound: ``animation`` is the path the layer defines (and
    binds), and the arrays hold the rest pose at every frame of the stage's range."""
    notes: list[str] = field(default_factory=list)
    """What the reader noticed and the reports say (joints of the animation the skeleton lacks)."""
    stray_influences: list[tuple[str, int]] = field(default_factory=list)
    """``(mesh primvar, index)`` per mesh skinned by a joint index past the skeleton's joints, the smallest:
    an eye joint added there would take those vertices (see :mod:`usdgaze.usd.skinning`)."""
    owns_arrays: bool = False
    """The animation arrays belong to this clip alone (a fresh read nobody else holds), so a pass may
    write its result into them instead of into copies: one copy of the animation less at the peak."""

    def where(self, attribute: str = "") -> str:
        """``file:/prim/path.attribute`` of the animation, for messages."""
        return f"{self.source}:{self.animation}{'.' + attribute if attribute else ''}"

    def frames(self, lo: int, hi: int) -> "SkelClip":
        """The clip cut to its frames ``lo`` to ``hi`` (exclusive): times, animation samples and, where
        it moves, the skeleton's transform."""
        import dataclasses

        moving = len(self.skel_to_world) > 1
        return dataclasses.replace(
            self, times=self.times[lo:hi], rotations=self.rotations[lo:hi], translations=self.translations[lo:hi],
            scales=self.scales[lo:hi], skel_to_world=self.skel_to_world[lo:hi] if moving else self.skel_to_world,
            owns_arrays=False)

    def named_joints(self) -> list[str] | None:
        """The joint paths spelled with the skeleton's ``jointNames`` (``Hips/Spine`` for tokens
        ``j0/j1`` named Hips and Spine), or None when it authors none, not one per joint, or the same."""
        return spelled_with_names(self.joints, self.parents, self.joint_names)

    @property
    def seconds(self) -> np.ndarray:
        """Sample times in seconds from the stage's start time code."""
        return (self.times - self.start_time) / self.time_codes_per_second

    @property
    def world_up(self) -> np.ndarray:
        return np.array([0.0, 0.0, 1.0]) if self.up_axis == "Z" else np.array([0.0, 1.0, 0.0])

    @property
    def handedness(self) -> np.ndarray:
        """Per frame ``(F,)``: +1, or -1 where skeleton -> world mirrors (a negative scale on the
        SkelRoot or above), so the skeleton's left is the world's right."""
        return np.sign(np.linalg.det(self.skel_to_world[:, :3, :3]))

    def rest_world(self) -> np.ndarray:
        """Skeleton-space rest transforms ``(J, 4, 4)``."""
        from usdgaze.core.kinematics import world_matrices

        return world_matrices(self.rest_local[None], self.parents)[0]

    def neutral(self) -> np.ndarray:
        """Skeleton-space transforms of the neutral pose ``(J, 4, 4)`` (see ``neutral_world``)."""
        return self.neutral_world if self.neutral_world is not None else self.rest_world()

    def local_trs(self, joint: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Translation, rotation, scale of one skeleton joint per frame (float64), animated or rest."""
        f = len(self.times)
        hits = np.flatnonzero(self.anim_to_skel == joint)
        if len(hits):
            a = hits[0]
            return (_column(self.translations[:, a]), self.rotations[:, a].astype(float),
                    _column(self.scales[:, a]))
        t, q, s = rot.decompose_tr(self.rest_local[joint])
        return np.broadcast_to(t, (f, 3)), np.broadcast_to(q, (f, 4)), np.broadcast_to(s, (f, 3))


def _column(values: np.ndarray) -> np.ndarray:
    """One joint's samples ``(F, 3)`` as float64; a column whose every sample has the same bits (a bone
    length, a unit scale) as a read-only broadcast of its first row instead of F copies of it."""
    # Compared as bytes (one copy of the strided column, one memcmp): a moving column differs at its
    # last sample already, as a rule, and is told by one row.
    first = values[:1].tobytes()
    if len(values) and values[-1:].tobytes() == first and values.tobytes() == first * len(values):
        return np.broadcast_to(values[0].astype(float), values.shape)
    return values.astype(float)
