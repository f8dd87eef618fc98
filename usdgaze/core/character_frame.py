"""The character frame: the canonical axes (X left, Y up, Z forward) of a skeleton in its neutral
pose, from the stage's up axis and mirrored left/right joints (or an explicit forward). The other
half of rig binding (:mod:`usdgaze.core.rig`, which binds the gaze chain).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.core import names
from usdgaze.core import rotations as rot
from usdgaze.errors import RigError


def mirrored_pairs(joints: list[str]) -> list[tuple[int, int]]:
    """(left, right) joint index pairs whose names differ only in their side word.

    Digits count unless a rig numbers joints through the whole skeleton (then a key is unique only
    without them).
    """
    pairs = []
    sided = [(i, j, s) for i, j in enumerate(joints) if (s := names.side(j))]  # read once for both passes
    for numbers in (True, False):
        lefts: dict[str, list[int]] = {}
        rights: dict[str, list[int]] = {}
        for i, j, s in sided:
            (lefts if s > 0 else rights).setdefault(names.mirror_key(j, numbers), []).append(i)
        taken = {i for p in pairs for i in p}
        for key, ls in lefts.items():
            rs = rights.get(key, [])
            if len(ls) == 1 and len(rs) == 1 and ls[0] not in taken and rs[0] not in taken:
                pairs.append((ls[0], rs[0]))
    return sorted(pairs)


def side(joint: str) -> int:
    """+1 for a left-side joint name, -1 for right, 0 otherwise."""
    return names.side(joint)


@dataclass(frozen=True)
class CharacterFrame:
    """The character's canonical axes in skeleton space in the neutral (bind) pose."""

    left: np.ndarray
    up: np.ndarray
    forward: np.ndarray
    source: str = ""
    """Where forward came from: a left/right joint pair, or an explicit forward."""
    note: str = ""
    """A warning for the report where the frame rests on a guess the user may want to overrule."""

    @property
    def rotation(self) -> np.ndarray:
        """Quaternion mapping canonical (X left, Y up, Z forward) to skeleton space."""
        return rot.frame_rotation(self.left, self.up, self.forward)


def character_frame(joints: list[str], neutral_world: np.ndarray, up: np.ndarray,
                    forward: np.ndarray | None = None, where: str = "skeleton",
                    forward_label: str = "gaze:binding:forward", stage_up: np.ndarray | None = None) -> CharacterFrame:
    """Character axes from the neutral pose: up from the stage, left from mirrored left/right joints.

    ``neutral_world`` are skeleton-space transforms ``(J, 4, 4)`` (the bind pose); ``up`` is the
    character's up in skeleton space (the stage's, snapped to a skeleton axis). Nothing assumes a
    vertical spine: a quadruped's hips give left as a biped's do. An explicit ``forward`` (skeleton
    space) wins over the names and fixes the frame as given: up is then ``stage_up`` (the stage's up
    carried into skeleton space, unsnapped; ``up`` where not given) made perpendicular to it.
    """
    up = rot.normalize(np.asarray(up, dtype=float))
    if forward is not None and np.linalg.norm(forward) > 0:
        return _given_forward(np.asarray(forward, dtype=float), up if stage_up is None else stage_up, where,
                              forward_label)
    pairs = mirrored_pairs(joints)
    if not pairs:
        raise RigError(f"{where}: cannot tell the character's forward: no left/right joint pairs by name; "
                       f"give it with --forward X,Y,Z (skeleton space) or {forward_label}")
    pos = neutral_world[:, :3, 3]
    depth = {i: j.count("/") for i, j in enumerate(joints)}
    extent = max(float(np.ptp(pos - np.outer(pos @ up, up), axis=0).max()), float(np.ptp(pos @ up)), 1e-9)
    # The pairs nearest the root (hips before shoulders before hands): limbs far down the hierarchy
    # are often posed asymmetrically. Pairs at one spot (CMU's hip joints) say nothing.
    for level in sorted({depth[l] for l, _ in pairs}):
        at = [(l, r) for l, r in pairs if depth[l] == level]
        spread = [pos[l] - pos[r] for l, r in at]
        spread = [v - np.dot(v, up) * up for v in spread]
        keep = [k for k, v in enumerate(spread) if np.linalg.norm(v) > 0.01 * extent]
        if keep:
            left = rot.normalize(np.mean([spread[k] for k in keep], axis=0))
            l, r = at[keep[0]]
            source = f"left/right pair {names.leaf(joints[l])}/{names.leaf(joints[r])}"
            return CharacterFrame(left=left, up=up, forward=rot.cross(left, up), source=source)
    raise RigError(f"{where}: left and right joints coincide in the neutral pose; give the forward with "
                   f"--forward X,Y,Z (skeleton space) or {forward_label}")


def _given_forward(forward: np.ndarray, stage_up: np.ndarray, where: str, label: str) -> CharacterFrame:
    """The frame of an explicit forward: forward as given, up the stage's made perpendicular to it. The
    user's forward is the one word on a rig whose skeleton space is tilted from the world (a forward
    flattened onto the snapped axis's horizontal could not say it)."""
    fwd = rot.normalize(forward)
    stage_up = rot.normalize(np.asarray(stage_up, dtype=float))
    up = stage_up - np.dot(stage_up, fwd) * fwd
    if np.linalg.norm(up) < 1e-6:
        raise RigError(f"{where}: {label} is parallel to the stage up axis")
    up = rot.normalize(up)
    return CharacterFrame(left=rot.cross(up, fwd), up=up, forward=fwd, source=label)


LEG_AXIS_DEG = 30.0
"""The legs say the character's up only where they hang within this of a skeleton axis (a seated bind
pose's thighs, 45 deg from each, say nothing)."""


def body_up(joints: list[str], neutral_world: np.ndarray) -> np.ndarray | None:
    """The skeleton axis the neutral pose stands upright along, by its legs: from the mirrored pair
    nearest the root that is apart and has joints below (hips, thighs; a quadruped's hind or front
    legs) to the joints furthest down each of those chains (toes, feet), the legs hang down that
    axis. None where that pair's chains do not hang within :data:`LEG_AXIS_DEG` of one axis, or no
    pair serves: arms spread in a T-pose, a seated pose, a rig with no sided chains."""
    pos = neutral_world[:, :3, 3]
    depth = [j.count("/") for j in joints]
    pairs = mirrored_pairs(joints)
    extent = max(float(np.ptp(pos, axis=0).max()), 1e-9)
    for l, r in sorted(pairs, key=lambda p: (depth[p[0]], p)):
        hang = [_furthest_below(joints, pos, j) for j in (l, r)]
        if np.linalg.norm(pos[l] - pos[r]) <= 0.01 * extent or any(h is None for h in hang):
            continue  # CMU's hip joints at one spot; Rigify's pelvis helpers, leaves
        down = rot.normalize(hang[0] + hang[1])
        axis = int(np.argmax(np.abs(down)))
        if np.degrees(np.arccos(min(1.0, abs(float(down[axis]))))) >= LEG_AXIS_DEG:
            return None
        up = np.zeros(3)
        up[axis] = -np.sign(down[axis])
        return up
    return None


def _furthest_below(joints: list[str], pos: np.ndarray, top: int) -> np.ndarray | None:
    """Unit vector from joint ``top`` to the joint of its subtree furthest from it (None: no children
    or all on it)."""
    prefix = joints[top] + "/"
    below = [i for i, j in enumerate(joints) if j.startswith(prefix)]
    if not below:
        return None
    reach = pos[below] - pos[top]
    far = reach[int(np.argmax(np.linalg.norm(reach, axis=1)))]
    return far / np.linalg.norm(far) if np.linalg.norm(far) > 0 else None
