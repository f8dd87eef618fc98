"""Segment roles from the skeleton's shape at rest, where no name says foot, hand or head (pure numpy):
legs reach the ground from the base, the head tops the highest end joint, arms are the two longest
branches off the spine, the neck lies between the arms and the head. Only what no name says is filled in:
a joint named as a limb, the head, the neck or the trunk keeps its name's role."""

from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from usdgaze.core.names import RIGIFY_ROLES, rigify_number, says_trunk
from usdgaze.core.rig import leaf
from usdgaze.physics import segments as _seg
from usdgaze.physics.segments import _ancestors, _mark, children_of, subtree_of

# An eye by name, where the gaze binding names none: not an eyelid, eyelash or eyebrow beside it.
_EYE = re.compile(r"eye(?!_?(lid|lash|brow))", re.I)


def shape_roles(roles: list[str], parents: np.ndarray, pos: np.ndarray, head: int | None = None,
                names: list[str] | None = None) -> list[str]:
    """Roles the names left out, from the tree and the rest positions ``pos (J, 3)`` (z up; joint 0
    the floating base): legs, arms, head (``head``: the bound head joint, else the parent of the
    highest end joint) and neck (:func:`_neck`; ``names``: the joints' names). Only what no name
    placed is filled in, so a named rig is unchanged."""
    roles = list(roles)
    n = len(roles)
    children = children_of(parents)
    z = pos[:, 2] - pos[:, 2].min()
    leaves = [j for j in range(n) if not children[j]]
    legs: list[int] = []
    if "foot" not in roles:
        legs = _shape_legs(roles, children, z)
    if "head" not in roles:
        if head is None:
            head = _shape_head(roles, parents, children, leaves, legs, z)
        if head is not None and head > 0:
            # Only what no name placed: a bound head above the arms must not make them the head.
            for k in subtree_of(children, head):
                if roles[k] == "other":
                    roles[k] = "head"
    heads = [j for j in range(n) if roles[j] == "head"]
    if heads:
        spine = _ancestors(min(heads, key=lambda j: len(_ancestors(j, parents))), parents)
        if "hand" not in roles:
            _shape_arms(roles, children, pos, spine, float(np.ptp(z)))
        _neck(roles, parents, spine, z, names)
    return roles


_ARM = ("upperArm", "forearm", "hand")


def _neck(roles: list[str], parents: np.ndarray, spine: list[int], z: np.ndarray, names: list[str] | None) -> None:
    """de Leva's head segment starts at C7: the spine joints above the arms' branch point (the highest
    spine joint an arm hangs from; ``spine``: the head's ancestors, nearest first) are its neck, whether
    the head and arms came from names or from the shape, unless a name says trunk (``spine``, ``chest``;
    not Rigify's numbered neck, ``DEF-spine.004``). Only rigs whose arms came from the shape had it:
    named wrists left a neck no name calls one (CMU's renamed ``Cervical...``) 2.7 kg of trunk a joint
    with 300 N m motors, where by their names they are 1.35 kg of head each with 40."""
    on_spine = set(spine)
    branch_points = set()
    for b, role in enumerate(roles):
        if role in _ARM:
            a = b
            while a >= 0 and a not in on_spine:
                a = int(parents[a])
            if a > 0:  # an arm off the base is no shoulder
                branch_points.add(a)
    if not branch_points:
        return
    for j in spine[:spine.index(max(branch_points, key=lambda j: z[j]))]:
        if roles[j] == "other" and not (names is not None and _names_trunk(names[j])):
            roles[j] = "head"


def _names_trunk(name: str) -> bool:
    """A trunk word in the name, but for Rigify's neck (``DEF-spine.004`` and ``.005``, whose spine
    chain runs from the hips to the head: its numbers, not its words, say which part a bone is)."""
    return says_trunk(name) and RIGIFY_ROLES.get(rigify_number(name)) != "neck"


def _shape_head(roles: list[str], parents: np.ndarray, children: list[list[int]], leaves: list[int],
                legs: list[int], z: np.ndarray) -> int | None:
    """The head where no name says it: the parent of the highest end joint off the legs (a skull's top
    end site), or that end joint itself where its parent also carries named limbs (a rig without a
    head joint, whose neck is the highest end: its parent, the chest, made the arms the head)."""
    off_legs = [j for j in leaves if not any(a in legs for a in [j, *_ancestors(j, parents)])]
    top = max(off_legs, key=lambda j: z[j], default=None)
    if top is None or parents[top] <= 0:
        return top
    parent = int(parents[top])
    if any(roles[k] != "other" for k in subtree_of(children, parent)):
        return top
    return parent


def _main_path(children: list[list[int]], start: int, score) -> list[int]:
    """From ``start`` down through the child whose subtree scores highest, to a leaf."""
    path = [start]
    while children[path[-1]]:
        path.append(max(children[path[-1]], key=score))
    return path


def _shape_legs(roles: list[str], children: list[list[int]], z: np.ndarray) -> list[int]:
    """The base's two branches that reach the ground are legs: the foot is the first joint down the
    leg below a fifth of the base's height (an ankle sits at 5-10% of hip height), above it the shank
    and the thigh."""
    reach = {c: min(z[k] for k in subtree_of(children, c)) for c in children[0]}
    grounded = sorted((c for c in reach if reach[c] < 0.1 * max(z[0], 1e-9)), key=lambda c: reach[c])[:2]
    for c in grounded:
        path = _main_path(children, c, lambda k: -min(z[i] for i in subtree_of(children, k)))
        foot = next((i for i, j in enumerate(path) if z[j] < 0.2 * z[0]), None)
        if foot is None or foot < 2:
            continue
        _mark(roles, children, path[foot], "foot")
        for role, j in zip(("shank", "thigh"), (path[foot - 1], path[foot - 2])):
            if roles[j] == "other":
                roles[j] = role
    return grounded


def _shape_arms(roles, children, pos: np.ndarray, spine: list[int], height: float) -> None:
    """The two longest branches off the spine (below the head, above the base) are arms. Along each,
    the upper arm and forearm are the most distal two consecutive bones of at least 0.6 of the
    branch's longest (a clavicle can be as long as a forearm: 19 vs 18.5 cm on CMU's left arm; hand
    and finger bones are shorter); the hand is where they end. Where no two long bones follow each
    other and the longest ends the branch, the arm has no hand joint: that bone is the upper arm and
    its end the forearm (a handless rig's shoulder became a hinge elbow, its elbow a wrist)."""
    def reach(k: int, start: int) -> float:
        return max(float(np.linalg.norm(pos[i] - pos[start])) for i in subtree_of(children, k))

    branches = [(reach(c, c), c, s) for s in spine if s != 0 for c in children[s]
                if c not in spine and roles[c] == "other"]
    arms = [b for b in sorted(branches, reverse=True)[:2] if b[0] > 0.2 * height]
    for _, c, _ in arms:
        path = _main_path(children, c, lambda k: reach(k, c))
        bones = np.linalg.norm(np.diff(pos[path], axis=0), axis=1)
        # No arm bone is longer than 0.3 of the height (the upper arm: 0.186, Drillis and Contini): the path
        # to the farthest reach ran on along a sword the hand holds, which made the arm's bones the sword's.
        held = np.flatnonzero(bones > 0.3 * height)
        if len(held) and held[0] >= 2:
            path, bones = path[:held[0] + 1], bones[:held[0]]
        long = bones >= 0.6 * bones.max()
        pairs = np.flatnonzero(long[:-1] & long[1:])
        if not len(pairs) and int(np.argmax(bones)) == len(bones) - 1:
            roles[path[-1]], roles[path[-2]] = "forearm", "upperArm"
            continue
        i = int(pairs[-1]) if len(pairs) else int(np.argmax(bones[:-1] + bones[1:]))
        _mark(roles, children, path[i + 2], "hand")
        roles[path[i + 1]], roles[path[i]] = "forearm", "upperArm"


class BodyParts(NamedTuple):
    """What each body is: its role, and which are the head, eyes, end sites and attachments."""

    roles: list[str]
    eyes: set[int]
    children: list[list[int]]
    head: int | None
    tips: set[int]  # end sites and eyes with no child: no segment of their own
    phalanges: set[int]
    attached: set[int]  # riding along (twist, IK, control joints): no segment, mass or freedom
    aside: set[int]  # hung beside the body: they neither size nor shape it
    extent: list[int]  # the bodies that size it
    height: float


def body_parts(joints: list[str], idx: np.ndarray, body_of: dict, bparent: np.ndarray, pos: np.ndarray,
               head_joint: int | None, eye_joints: tuple, where: str, meters_per_unit: float) -> BodyParts:
    """Per body (``idx``: its skeleton joint; ``body_of``: the inverse), roles by names and shape, the head,
    eyes, end sites, attachments and asides, and the height; ``head_joint`` and ``eye_joints``: the gaze
    binding's, where it names them."""
    n = len(idx)
    head = body_of.get(head_joint) if head_joint is not None else None
    names = [joints[j] for j in idx]
    roles = shape_roles(_seg.assign_roles(names, bparent), bparent, pos, head, names)
    # The binding's eyes where it names them: eyelids and brows named "eye..." beside them moved the
    # eyes' midpoint, where the vision sees from.
    eyes = ({body_of[e] for e in eye_joints if e in body_of}
            or {b for b, j in enumerate(idx) if _EYE.search(leaf(joints[j]))})
    children = _seg.children_of(bparent)
    # An end site marks where its parent's segment ends, and an eye is a point in the head: neither
    # has a length, mass or shape of its own.
    if head is None:  # the head joint by name (the gaze binding's otherwise)
        head = next((b for b in range(n) if roles[b] == "head" and _seg.is_head_joint(names[b])), None)
    if head is None:  # a head segment of one end joint (a rig whose neck ends it) is the head, no aside leaf
        alone = [b for b in range(1, n) if roles[b] == "head" and not children[b] and roles[bparent[b]] != "head"]
        head = alone[0] if len(alone) == 1 else None
    tips, phalanges = _seg.leaf_ends(names, roles, bparent, children, head, pos)
    tips |= {b for b in eyes if not children[b]}
    attached = _seg.attachments(roles, bparent, children, head, tips, names, pos)
    # What hangs beside the body (not from the head: eyes, a skull's top) neither sizes nor shapes it: a
    # camera joint hung from the hips 8 m ahead made a standing rig 'lying down', one 3.5 m up doubled its
    # height (feet 5.9 cm thick), a marker 30 cm below the ground stood the model 34 cm up (a capsule to it).
    aside = _seg.asides(names, roles, bparent, children, head, pos)
    aside -= set(_seg.subtree_of(children, head)) if head is not None else set()
    extent = sorted(set(range(n)) - attached - aside)
    height = float(np.ptp(pos[extent, 2])) * 1.08 or 1.0
    _seg.check_biped(roles, pos, height, where, extent, meters_per_unit)
    return BodyParts(roles, eyes, children, head, tips, phalanges, attached, aside, extent, height)
