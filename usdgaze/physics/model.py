"""A MuJoCo body model of any UsdSkel skeleton, as plain arrays (pure numpy; no pxr, no mujoco).

Coordinates. MuJoCo works Z-up in metres. A point ``p`` in skeleton space goes to the model's world
as ``p_mj = metersPerUnit * C @ (skel_to_world @ p)``, with ``C`` the identity on Z-up stages and, on
Y-up stages, the rotation of +90 degrees about X, ``(x, y, z) -> (x, -z, y)``: the stage's up becomes
+Z, its X stays X, and handedness is kept. The ground plane is the stage's ``up = 0`` plane. A
mirrored character (``skel_to_world`` of negative determinant: a SkelRoot scaled -1 along an axis)
is simulated as its mirror image, ``C`` followed by the mirror of the model's X: every stage point
and direction (the body, pushes, balls, stones, obstacles) goes through the same ``to_model``, so
the model's world is the stage's mirrored and its bodies are right-handed.

Bodies. One body per skeleton joint from the floating base (the first pelvis/hips joint, else the
joint where the two legs meet: the common ancestor of the lowest end joints at rest) down; its frame
is the joint's frame in the rest pose (``restTransforms``, or those derived from ``bindTransforms``),
orthonormalized, so ``qpos`` of all zeros but the root is the rest pose.
Joints above the base or outside its subtree are not simulated and are carried from the reference.
The base has a free joint; knees and elbows are hinges (axis fitted to the reference motion when
given, else the anatomical flexion axis); exporter end sites are welded; every other joint is a
ball. Masses and inertias follow de Leva (1996) (:mod:`usdgaze.physics.segments`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.kinematics import world_matrices
from usdgaze.core.names import is_control
from usdgaze.core.rig import character_frame, leaf
from usdgaze.errors import RigError, UsdGazeError
from usdgaze.physics import checks
from usdgaze.physics import segments as seg
from usdgaze.physics import shape_roles as shape
from usdgaze.physics import shapes
from usdgaze.physics.joint_kinds import fit_to_reference, hinges, is_toe, strengths, welded

Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_BASE = re.compile(r"^(hips|pelvis|hip|bip\d*pelvis|defspine|orgspine)$", re.I)
# Fractions of standing height used where the skeleton gives no length (leaf joints).
# A forearm that ends its arm (a rig without hand joints) is a forearm, 0.146 of the height (Drillis and
# Contini); continued by the 3% of other leaves it was a stump.
_LEAF_LENGTH = {"head": 0.12, "hand": 0.06, "foot": 0.06, "forearm": 0.146, "other": 0.03}


def stage_to_model(up_axis: str, meters_per_unit: float) -> np.ndarray:
    """The 3x3 linear map from stage world coordinates to the model's (Z-up metres)."""
    c = np.eye(3) if up_axis == "Z" else Y_UP_TO_Z_UP
    return float(meters_per_unit) * c


@dataclass
class BodyModel:
    """Everything the MJCF writer and the retargeter need, one row per simulated body."""

    joints: list[str]
    parents: np.ndarray
    bodies: np.ndarray  # skeleton joint index per body, parents first; bodies[0] is the base
    body_parent: np.ndarray  # body index of each body's parent (-1 for the base)
    kind: list[str]  # "free", "ball", "hinge", "weld"
    role: list[str]
    names: list[str]  # MJCF-safe body names
    offset: np.ndarray  # (B, 3) body origin in its parent's frame, metres
    rel_quat: np.ndarray  # (B, 4) xyzw, body frame in its parent's frame at rest
    base_pos: np.ndarray  # (3,) base origin at rest, model world
    base_quat: np.ndarray  # (4,) xyzw
    axis: np.ndarray  # (B, 3) hinge axis in the body frame (zero for non-hinges)
    range_deg: np.ndarray  # (B, 2): ball (0, max angle); hinge (lo, hi)
    mass: np.ndarray  # (B,)
    com: np.ndarray  # (B, 3) in the body frame
    inertia: np.ndarray  # (B, 3) principal moments
    inertia_quat: np.ndarray  # (B, 4) xyzw, principal axes (z along the segment) in the body frame
    radius: np.ndarray  # (B,)
    geoms: list[list[tuple[str, np.ndarray]]]  # per body: ("capsule", fromto(6)) | ("sphere", pos(3))
    strength: np.ndarray  # (B,) N m per unit control
    to_model: np.ndarray  # 3x3 stage-world -> model-world linear map (includes metersPerUnit)
    total_mass: float
    height: float
    lift: float  # metres the rest pose is raised in the MJCF so that it stands on the ground
    feet: list[int] = field(default_factory=list)  # body indices of the topmost foot bodies
    forward: np.ndarray | None = None  # character forward at rest, model world (None: no left/right names)
    eyes: list[int] = field(default_factory=list)  # eye bodies (by name or the gaze binding), welded
    rest_pos: np.ndarray | None = None  # (B, 3) body origins at rest, model world (before the lift)
    rest_rot: np.ndarray | None = None  # (B, 3, 3) body frames at rest, model world

    @property
    def dof_bodies(self) -> np.ndarray:
        return np.array([b for b, k in enumerate(self.kind) if k in ("ball", "hinge")], dtype=int)

    @property
    def toes(self) -> list[int]:
        """Bodies of the toes: foot bodies below a foot body."""
        return [b for b in range(1, len(self.kind)) if is_toe(self.role, self.body_parent, b)]

    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        """First ``qpos`` and ``qvel`` index of each body's joint (MuJoCo's order: bodies in order)."""
        nq = np.array([{"free": 7, "ball": 4, "hinge": 1, "weld": 0}[k] for k in self.kind])
        nv = np.array([{"free": 6, "ball": 3, "hinge": 1, "weld": 0}[k] for k in self.kind])
        return np.concatenate([[0], np.cumsum(nq)[:-1]]), np.concatenate([[0], np.cumsum(nv)[:-1]])

    def body_of(self, joint: int) -> int:
        hits = np.flatnonzero(self.bodies == joint)
        return int(hits[0]) if len(hits) else -1


def _base_joint(joints: list[str], parents: np.ndarray, heights: np.ndarray, where: str = "skeleton") -> int:
    """The floating base: the first joint named as a pelvis, else where the two legs meet: the
    nearest common ancestor of the lowest end joint at rest (a toe) and the lowest one on another
    branch (the other foot). Many rigs put a root joint on the ground above the hips, some with props
    or IK targets beside them, so neither the root nor the first branching is the pelvis."""
    for j, name in enumerate(joints):
        if _BASE.search(re.sub(r"[^a-z0-9]", "", leaf(name).lower())):
            return _legs_beside(joints, parents, heights, j, where)

    def chain(j: int) -> list[int]:
        out = [j]
        while parents[out[-1]] >= 0:
            out.append(int(parents[out[-1]]))
        return out

    ends = [int(j) for j in np.argsort(heights, kind="stable") if not np.any(parents == j)]
    low, span = float(np.min(heights)), float(np.ptp(heights))
    if len(ends) >= 2 and span > 0:
        first = chain(ends[0])
        for other in ends[1:]:
            up = set(chain(other))
            meet = next((j for j in first if j in up), None)  # None: another skeleton tree
            # Two ends of one foot (toe, heel) meet low; the legs meet at about half the height.
            if meet is not None and heights[meet] - low > 0.25 * span:
                return meet
    return int(np.flatnonzero(parents < 0)[0])


def _legs_beside(joints: list[str], parents: np.ndarray, heights: np.ndarray, pelvis: int, where: str) -> int:
    """The pelvis joint by name, or, where nothing below it reaches the ground and two legs branch from one
    of its ancestors instead (``Root > {Hips, LeftUpLeg, RightUpLeg}``), that ancestor: the joint the legs
    hang from is the body's pelvis, and the one named so below it the lower trunk. Such a rig was refused
    as having no feet. Legs hung from a joint on the ground at rest are refused: the model's bodies follow
    the skeleton's tree, so its thighs would hang from the ground, not from the moving hips."""
    children = seg.children_of(parents)
    low, span = float(np.min(heights)), float(np.ptp(heights))

    def grounded(j: int) -> bool:
        return min(float(heights[k]) for k in seg.subtree_of(children, j)) - low < 0.1 * span

    if span <= 0 or grounded(pelvis):
        return pelvis
    below, a = pelvis, int(parents[pelvis])
    while a >= 0:
        legs = [c for c in children[a]
                if c != below and not is_control(joints[c]) and len(children[c]) and grounded(c)]
        if len(legs) >= 2:
            up = (float(heights[a]) - low) / span
            if up > 0.25:
                return a
            raise UsdGazeError(
                f"{where}: its legs ('{leaf(joints[legs[0]])}', '{leaf(joints[legs[1]])}') hang from "
                f"'{leaf(joints[a])}', beside its pelvis '{leaf(joints[pelvis])}' and {up:.0%} of its height up "
                "at rest: the physics body's legs hang from its pelvis, or from a joint at the hips above it")
        below, a = a, int(parents[a])
    return pelvis


def _subtree(base: int, parents: np.ndarray) -> np.ndarray:
    """``base`` and its descendants in depth-first pre-order (MuJoCo's body order for nested XML)."""
    children = seg.children_of(parents)
    out, stack = [], [base]
    while stack:
        j = stack.pop()
        out.append(j)
        stack.extend(reversed(children[j]))
    return np.array(out, dtype=int)


def _safe_names(joints: list[str], idx: np.ndarray) -> list[str]:
    out, seen = [], set()
    for j in idx:
        name = re.sub(r"[^A-Za-z0-9_]", "_", leaf(joints[j])) or f"joint{j}"
        while name in seen:
            name += "_"
        seen.add(name)
        out.append(name)
    return out


def build(joints: list[str], parents: np.ndarray, rest_local: np.ndarray, skel_to_world: np.ndarray,
          up_axis: str, meters_per_unit: float, total_mass: float = 75.0,
          reference: np.ndarray | None = None, where: str = "skeleton", weld_still: bool = True,
          hints: Hints | None = None) -> BodyModel:
    """The body model of a skeleton; ``reference`` (``(F, J, 4)`` local xyzw rotations) fits hinge axes
    and widens joint ranges to what the motion uses. ``weld_still``: weld the joints the reference holds
    at rest throughout (off where a task must move what the reference does not, e.g. arms to catch;
    the pelvis's bones, ``segments.pelvis_bones``, weld where held even then).
    ``hints``: the gaze binding's head, eyes and forward, for rigs whose names say nothing."""
    parents = np.asarray(parents, dtype=int)
    if total_mass <= 0:
        raise UsdGazeError(f"{where}: total mass must be positive, got {total_mass}")
    to_model, skel_to_world0, world, idx, body_of, bparent = _body_tree(
        joints, parents, rest_local, skel_to_world, up_axis, meters_per_unit, where)

    pos, orient, rmat, offset, rel = _rest_frames(world[idx], bparent, to_model)
    n = len(idx)
    hints = hints or Hints()
    names = [joints[j] for j in idx]
    p = shape.body_parts(joints, idx, body_of, bparent, pos, hints.head, hints.eyes, where, meters_per_unit)
    roles, eyes, children, head, tips, attached, aside, extent, height = (
        p.roles, p.eyes, p.children, p.head, p.tips, p.attached, p.aside, p.extent, p.height)
    passive = tips | attached  # no segment, mass or degrees of freedom of their own
    far = {b for b in aside if np.linalg.norm(offset[b]) > 0.25 * height}  # longer than a thigh: no bone of it
    seg_vec = _segment_vectors(pos, rmat, offset, bparent, children, roles, height, tips, p.phalanges, head, attached)
    lengths = np.linalg.norm(seg_vec, axis=1)
    mass = _masses(roles, lengths, total_mass, passive, bparent)

    kind = ["free"] + ["weld" if b in eyes or b in passive or welded(joints[idx[b]], roles, bparent, b, children)
                       else "ball" for b in range(1, n)]
    checks.unmirrored(joints, idx, bparent, kind, to_model @ world[idx, :3, :3], where)
    checks.evenly_scaled(joints, idx, bparent, kind, world[idx, :3, :3], where)
    rest4 = np.concatenate([np.concatenate([np.eye(3)[None].repeat(n, 0), pos[:, :, None]], 2),
                            np.tile([0, 0, 0, 1.0], (n, 1, 1))], 1)
    feet = [b for b in range(1, n) if roles[b] == "foot" and roles[bparent[b]] != "foot"]  # topmost foot bodies
    forward = _forward(names, rest4, feet, bparent, pos, hints, to_model @ skel_to_world0[:3, :3], where)
    axis, range_deg = hinges(kind, roles, bparent, children, rmat, seg_vec, forward)
    if reference is not None:
        # Without weld_still the pelvis's own bones still weld where held: the pelvis is one rigid segment.
        # The legs never weld: a body stands by them. A reference that keys only the upper body (its legs
        # held at rest) had its hips, knees and ankles welded, and the stiff body slid 17 cm in 0.5 s.
        legs = {b for b in range(n) if roles[b] in ("thigh", "shank", "foot") and not is_toe(roles, bparent, b)}
        still = set(range(n)) - legs if weld_still else seg.pelvis_bones(roles, bparent)
        fit_to_reference(np.asarray(reference, dtype=float)[:, idx], rel, kind, axis, range_deg, set(still),
                         seg_vec, bparent)

    com, inertia, iquat = seg.inertials(roles, seg_vec, mass)
    radius = shapes.radii(mass, lengths, roles, height)
    geoms = shapes.geoms(offset, children, seg_vec, roles, rmat, feet, attached | far)
    lowest = min(shapes.lowest(pos, rmat, geoms, radius, b) for b in extent)
    strength = strengths(roles, bparent) * total_mass / 75.0
    return BodyModel(
        joints=list(joints), parents=parents, bodies=idx, body_parent=bparent, kind=kind, role=roles,
        names=_safe_names(joints, idx), offset=offset, rel_quat=rel, base_pos=pos[0], base_quat=orient[0],
        axis=axis, range_deg=range_deg, mass=mass, com=com, inertia=inertia, inertia_quat=iquat,
        radius=radius, geoms=geoms, strength=strength, to_model=to_model, total_mass=float(total_mass),
        height=height, lift=-lowest, feet=feet, forward=forward, eyes=sorted(eyes), rest_pos=pos, rest_rot=rmat)


def _body_tree(joints, parents: np.ndarray, rest_local: np.ndarray, skel_to_world, up_axis: str,
               meters_per_unit: float, where: str):
    """The stage-to-model map (mirrored for a left-handed skeleton), the first frame's skeleton-to-world
    matrix, the rest pose's world matrices, the simulated joints (the base joint's subtree), their body
    indices by joint and each body's parent body (-1 for the base)."""
    to_model = stage_to_model(up_axis, meters_per_unit)
    checks.rigid_placement(skel_to_world, where)
    skel_to_world0 = np.asarray(skel_to_world, dtype=float).reshape(-1, 4, 4)[0]
    if np.linalg.det(skel_to_world0[:3, :3]) < 0.0:
        to_model = np.diag([-1.0, 1.0, 1.0]) @ to_model  # the mirror image: right-handed bodies
    world = skel_to_world0 @ world_matrices(rest_local[None], parents)[0]
    base = _base_joint(joints, parents, (world[:, :3, 3] @ to_model.T)[:, 2], where)
    idx = _subtree(base, parents)
    if len(idx) < 2:
        raise UsdGazeError(f"{where}: the skeleton below '{joints[base]}' has no joints to simulate")
    body_of = {int(j): b for b, j in enumerate(idx)}
    bparent = np.array([body_of.get(int(parents[j]), -1) for j in idx])
    bparent[0] = -1
    return to_model, skel_to_world0, world, idx, body_of, bparent


@dataclass(frozen=True)
class Hints:
    """What the gaze binding knows that names may not: the head and eye joints (skeleton indices) and
    the character's forward in skeleton space. Used only where the names say nothing."""

    head: int | None = None
    eyes: tuple[int, ...] = ()
    forward: np.ndarray | None = None


def _forward(names, rest4, feet, bparent, pos, hints: Hints, skel_to_model, where: str) -> np.ndarray | None:
    """The character's forward at rest, model world: from left/right names; else the binding's
    forward; else the feet (heel to toe, on the ground plane); None if nothing tells (no hinges then)."""
    try:
        return character_frame(names, rest4, np.array([0.0, 0.0, 1.0]), where=where).forward
    except RigError:
        pass
    if hints.forward is not None:
        f = skel_to_model @ np.asarray(hints.forward, dtype=float)
    else:
        toes = [(b, max(_subtree(b, bparent)[1:], key=lambda k: np.linalg.norm(pos[k] - pos[b]), default=b))
                for b in feet]
        f = sum((pos[t] - pos[b] for b, t in toes if t != b), np.zeros(3))
    f = np.array([f[0], f[1], 0.0])
    return f / np.linalg.norm(f) if np.linalg.norm(f) > 1e-9 else None


def _rest_frames(world: np.ndarray, bparent: np.ndarray, to_model: np.ndarray):
    """Model-space rest positions, orientations (quaternions and matrices) of the bodies, and each
    body's offset and rotation relative to its parent."""
    pos = world[:, :3, 3] @ to_model.T
    # A joint mirrored by a negative scale (some rigs mirror an eye, a hand or a leg) takes the mirror
    # on its x scale, as UsdSkel's decomposition does; its body frame is the rotation that is left.
    orient, _ = rot.rotation_part(to_model @ world[:, :3, :3])
    rmat = rot.to_matrix(orient)
    n = len(world)
    offset = np.zeros((n, 3))
    rel = np.tile(rot.IDENTITY, (n, 1))
    for b in range(1, n):
        p = bparent[b]
        offset[b] = rmat[p].T @ (pos[b] - pos[p])
        rel[b] = rot.relative(orient[p], orient[b])
    return pos, orient, rmat, offset, rel


def _masses(roles: list[str], lengths: np.ndarray, total_mass: float, passive: set[int], bparent: np.ndarray):
    """de Leva's segment masses; a ``passive`` body (tip, attachment) weighs a token mass taken from
    the body it hangs from, so the total stays."""
    share = seg.segment_masses(roles, lengths, total_mass, passive, bparent)
    mass = np.maximum(share, 1e-3 * total_mass / len(roles))
    for b in sorted(passive):
        a = bparent[b]
        while a in passive:
            a = bparent[a]
        mass[a] -= mass[b] - share[b]
    return mass


def _segment_vectors(pos, rmat, offset, bparent, children, roles, height: float, tips=frozenset(),
                     phalanges=frozenset(), head: int | None = None, attached=frozenset()) -> np.ndarray:
    """Per body, in its frame, the segment from its joint toward its main child (not one of the
    ``attached``; the one on the way to the head, else the largest subtree, else one that is no
    tip); a leaf continues its bone by a role's share of the height (a last phalanx in
    ``phalanges`` by its bone's own length), else points up; an end site in ``tips`` has none."""
    n = len(pos)
    seg_vec = np.zeros((n, 3))
    for b in range(n):
        # A body whose children all ride on it (a hand holding only a weapon's chain) ends as a leaf does.
        kids = [] if b not in attached and all(c in attached for c in children[b]) else children[b]
        if kids:  # the head's way first: a fingered arm's subtree outnumbers the neck's
            below = [seg.subtree_of(children, c) for c in kids]
            keys = [(c not in attached, head is not None and head in sub, len(sub), c not in tips)
                    for c, sub in zip(kids, below)]
            c = kids[max(range(len(keys)), key=keys.__getitem__)]
            seg_vec[b] = offset[c]
            # A foot whose toe sits on its ankle (a zero-length bone) runs on to the joint below the toe: continued
            # along the shank it stood on a stilt into the ground. (Elsewhere the bone's continuation stays, as
            # CMU's hips and wrists were measured with it.)
            while roles[b] == "foot" and np.linalg.norm(seg_vec[b]) < 1e-6 and children[c]:
                c = max(children[c], key=lambda k: len(seg.subtree_of(children, k)))
                seg_vec[b] = rmat[b].T @ (pos[c] - pos[b])
        if np.linalg.norm(seg_vec[b]) < 1e-6 and b not in tips:
            d = pos[b] - pos[bparent[b]] if b else np.zeros(3)
            d = rmat[b].T @ (d if np.linalg.norm(d) > 1e-6 else np.array([0, 0, 1.0]))
            length = np.linalg.norm(d) if b in phalanges else _LEAF_LENGTH.get(roles[b], _LEAF_LENGTH["other"]) * height
            seg_vec[b] = d / np.linalg.norm(d) * length
    return seg_vec
