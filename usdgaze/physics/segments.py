"""Body segments by joint role, with de Leva's (1996) segment inertia parameters.

Source of the numbers: P. de Leva, "Adjustments to Zatsiorsky-Seluyanov's segment inertia
parameters", J. Biomechanics 29(9):1223-1230, 1996, Table 4 (male subjects). Per segment: mass as a
fraction of total body mass, the centre of mass as a fraction of the segment length from its
proximal end, and radii of gyration as fractions of segment length (about the two transverse axes,
averaged here, and the longitudinal axis). The head segment runs from vertex to the seventh cervical
vertebra, so it includes the neck; the trunk is the sum of de Leva's upper, middle and lower trunk.

A joint's body is the segment from that joint to its child, so on a leg chain the hip joint's body
is the thigh, the knee's the shank and the ankle's the foot (toes included). Roles come from the
joint names (``foot``/``ankle``, ``hand``/``wrist``, ``head``, ``neck``); limbs are then walked up
from the hand and foot. Where no name says foot, hand or head, the skeleton's shape at rest does
(:func:`usdgaze.physics.shape_roles.shape_roles`). Joints neither identifies share what is left of the total mass in proportion to
their segment length.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.core.names import is_control, is_end_site, is_head, is_prop, rigify_number, spine_part
from usdgaze.core.rig import leaf
from usdgaze.errors import UsdGazeError


@dataclass(frozen=True)
class Segment:
    mass: float  # fraction of total body mass
    com: float  # centre of mass from the proximal joint, fraction of segment length
    gyration_transverse: float  # radius of gyration / length, mean of sagittal and transverse
    gyration_long: float  # radius of gyration / length, longitudinal


# de Leva (1996) Table 4, males.
DE_LEVA = {
    "head": Segment(0.0694, 0.5002, (0.303 + 0.315) / 2, 0.261),  # head+neck, from cervicale (C7) up
    "trunk": Segment(0.4346, 0.5138, (0.328 + 0.306) / 2, 0.169),
    "upperArm": Segment(0.0271, 0.5772, (0.285 + 0.269) / 2, 0.158),
    "forearm": Segment(0.0162, 0.4574, (0.276 + 0.265) / 2, 0.121),
    "hand": Segment(0.0061, 0.7900, (0.628 + 0.513) / 2, 0.401),
    "thigh": Segment(0.1416, 0.4095, 0.329, 0.149),
    "shank": Segment(0.0433, 0.4459, (0.255 + 0.249) / 2, 0.103),
    "foot": Segment(0.0137, 0.4415, (0.257 + 0.245) / 2, 0.124),
}

# Ball-joint range (max rotation from the model's neutral, degrees) and motor strength (N m per
# unit control) per role; knees and elbows are hinges. Strengths are of the order of human peak
# joint torques (hip and knee 150-250 N m, ankle ~150, trunk extension 200-300, shoulder ~80, elbow
# ~60, neck ~30, the toe flexors at the metatarsophalangeal joints some tens of N m). "toe" is not a
# segment role (de Leva's foot includes the toes); the model gives it to a foot body below the foot.
RANGE_DEG = {"head": 70.0, "trunk": 45.0, "upperArm": 170.0, "forearm": 150.0, "hand": 80.0,
             "thigh": 120.0, "shank": 150.0, "foot": 60.0, "other": 60.0}
STRENGTH = {"head": 40.0, "trunk": 300.0, "upperArm": 80.0, "forearm": 60.0, "hand": 15.0,
            "thigh": 250.0, "shank": 200.0, "foot": 120.0, "toe": 20.0, "other": 30.0}

_FOOT = re.compile(r"(foot|ankle)", re.I)
_HAND = re.compile(r"(hand|wrist)", re.I)


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", leaf(name).lower())


_PART = re.compile(r"(twist|roll|bend)?\d*$")


def _split_of(child: str, parent: str) -> bool:
    """Whether joint key ``child`` names a further part of ``parent``'s bone: the same name but for a part
    word or number at its end (``defshinl001`` of ``defshinl``, ``lthightwist`` of ``lthighbend``)."""
    stem = _PART.sub("", child)
    return bool(stem) and child != parent and stem == _PART.sub("", parent)


def _topmost(j: int, parents: np.ndarray, names: list[str], pattern: re.Pattern) -> int:
    """The highest ancestor-or-self of ``j`` whose name matches ``pattern`` on an unbroken run."""
    while parents[j] >= 0 and pattern.search(_key(names[parents[j]])):
        j = int(parents[j])
    return j


def assign_roles(joints: list[str], parents: np.ndarray) -> list[str]:
    """A de Leva segment role (or ``"other"``) for the body of each joint."""
    n = len(joints)
    # A control joint's body word names what it drives (UE's ik_foot_root), not a segment.
    keys = ["" if is_control(j) else _key(j) for j in joints]
    roles = ["other"] * n
    children = children_of(parents)
    for limb, pattern, above in (("foot", _FOOT, ("shank", "thigh")), ("hand", _HAND, ("forearm", "upperArm"))):
        tops = {_topmost(j, parents, joints, pattern) for j in range(n) if pattern.search(keys[j])}
        # Only the topmost of nested matches starts a limb end (CMU: LeftWrist > lhand).
        tops = {t for t in tops if not any(a in tops for a in _ancestors(t, parents))}
        for t in tops:
            _mark(roles, children, t, limb)
            p = int(parents[t])
            for role in above:
                if p < 0 or roles[p] != "other":
                    break
                roles[p] = role
                # A bone split in parts is one segment: Rigify's DEF-shin.L and DEF-shin.L.001, DAZ's
                # lThighBend and lThighTwist (the shin's upper half had been the thigh, the thigh the trunk).
                while parents[p] >= 0 and roles[parents[p]] == "other" and _split_of(keys[p], keys[parents[p]]):
                    p = int(parents[p])
                    roles[p] = role
                p = int(parents[p])
    for j in range(n):
        if roles[j] == "other" and is_head_joint(joints[j]):
            _mark(roles, children, j, "head")
            p = int(parents[j])
            while p >= 0 and spine_part(joints[p]) == "neck" and roles[p] == "other":
                roles[p] = "head"  # de Leva's head segment includes the neck
                p = int(parents[p])
    return roles


def children_of(parents: np.ndarray) -> list[list[int]]:
    """Each joint's children, in index order."""
    children = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    return children


def _mark(roles: list[str], children: list[list[int]], j: int, role: str) -> None:
    """``role`` for ``j`` and everything below it."""
    stack = [j]
    while stack:
        k = stack.pop()
        roles[k] = role
        stack.extend(children[k])


def subtree_of(children: list[list[int]], j: int) -> list[int]:
    """``j`` and everything below it."""
    out, stack = [], [j]
    while stack:
        k = stack.pop()
        out.append(k)
        stack.extend(children[k])
    return out


def _ancestors(j: int, parents: np.ndarray) -> list[int]:
    out = []
    while parents[j] >= 0:
        j = int(parents[j])
        out.append(j)
    return out


def is_head_joint(name: str) -> bool:
    """The head joint by name, read as the gaze binding reads it (``Head``, ``mixamorig:Head``, ``Bip01 Head``,
    ``C_head_jnt``, ``Head_M``, ``CC_Base_Head``; Rigify's ``spine.006``). A whole-name match missed the
    suffixed ones: Maya's and AdvancedSkeleton's heads came from the shape, their necks stayed trunk."""
    return is_head(name) or rigify_number(name) == 6


def is_end_joint(name: str) -> bool:
    """Exporter end sites (``HeadTop_End``, ``LeftToe_End``, ``..._nub``, ``C_headEnd_jnt``): no degrees of freedom."""
    return is_end_site(name)


# A leaf this many joints below its limb's first foot or hand joint marks the limb's tip (Mixamo's
# LeftToe_End below Foot and ToeBase; LeftHandIndex4 below Hand and three phalanges), not a joint
# whose segment the skeleton leaves unmeasured (CMU's LeftToe below LeftAnkle, LFingers two below
# LeftWrist; UE's ball_l).
_TIP_DEPTH = {"foot": 2, "hand": 4}


def _on_bone(j: int, parent: int, siblings: list[int], pos: np.ndarray) -> bool:
    """Leaf ``j`` lies on the bone from ``parent`` to one of its ``siblings`` (a twist or roll joint)."""
    at = pos[j] - pos[parent]
    for c in siblings:
        bone = pos[c] - pos[parent]
        length = float(np.linalg.norm(bone))
        if length < 1e-9:
            continue
        along = float(at @ bone) / length
        if 0.05 * length < along < 0.95 * length and np.linalg.norm(at - along * bone / length) < 0.15 * length:
            return True
    return False


def _is_aside(j: int, names: list[str], roles: list[str], parents: np.ndarray, children: list[list[int]],
              head: int | None, pos: np.ndarray | None) -> bool:
    """Whether leaf ``j`` hangs beside its body rather than ending a segment."""
    # A leaf beside a joint the chain goes on through is an attachment on its parent's bone (UE's
    # and CC's twist joints, a breast or a tail helper), not a segment; a hand's and a foot's
    # leaves are judged by their depth (CMU's thumb is a leaf beside its fingers) or named props,
    # and a leaf head (CMU's) is the head, whatever hangs beside it.
    siblings = [c for c in children[int(parents[j])] if c != j]
    judged = roles[j] in ("hand", "foot") or j == head
    return is_prop(names[j]) or (not judged and (
        any(children[c] for c in siblings) or (pos is not None and _on_bone(j, int(parents[j]), siblings, pos))))


def asides(names: list[str], roles: list[str], parents: np.ndarray, children: list[list[int]], head: int | None,
           pos: np.ndarray | None = None) -> set[int]:
    """The leaves beside the body (props, helpers, twist joints; a camera or a marker hung from the hips)."""
    return {j for j in range(1, len(names)) if not children[j] and _is_aside(j, names, roles, parents, children, head, pos)}


def leaf_ends(names: list[str], roles: list[str], parents: np.ndarray, children: list[list[int]],
              head: int | None, pos: np.ndarray | None = None) -> tuple[set[int], set[int]]:
    """The leaves whose extent the skeleton itself gives: ``tips`` mark where their parent's segment
    ends (exporter end sites by name, any leaf below the head: the skull's top, eyes, a face's or
    hair's joints; a foot's or a finger's leaf at least ``_TIP_DEPTH`` joints down its limb) or sit
    on it (a leaf beside a joint its parent's chain goes on through) and have no length, shape or
    degrees of freedom of their own; ``phalanges``, a finger's last phalanx three joints down (UE's
    index_03_l), are as long as the one before."""
    tips, phalanges = set(), set()
    for j in range(1, len(names)):
        if children[j]:
            continue
        depth, top = 0, j
        while parents[top] >= 0 and roles[int(parents[top])] == roles[j]:
            top, depth = int(parents[top]), depth + 1
        aside = _is_aside(j, names, roles, parents, children, head, pos)
        if (is_end_joint(names[j]) or (head is not None and head in _ancestors(j, parents)) or aside
                or depth >= _TIP_DEPTH.get(roles[j], 1 << 30)):
            tips.add(j)
        elif roles[j] == "hand" and depth == _TIP_DEPTH["hand"] - 1:
            phalanges.add(j)
    return tips, phalanges


def _by_length(lengths: np.ndarray) -> np.ndarray:
    """Shares in proportion to ``lengths``; equal ones where every length is zero (all tips)."""
    total = lengths.sum()
    return lengths / total if total > 0 else np.full(len(lengths), 1.0 / len(lengths))


def props(roles: list[str], parents: np.ndarray, children: list[list[int]], names: list[str] | None = None,
          pos: np.ndarray | None = None) -> set[int]:
    """What a character holds, no part of de Leva's body: every joint at or below one named a prop (UE's
    ``weapon_r``, ``prop_r``; ``names.is_prop``) and, by ``pos`` (rest positions), a chain in a hand that
    reaches farther from the wrist than the forearm is long: a hand, wrist to fingertip, is 0.108 of the
    height against the forearm's 0.146 (Drillis and Contini), so no finger does; a sword does."""
    tops = {j for j in range(len(roles)) if names is not None and is_prop(names[j])}
    if pos is not None:
        for t, forearm in _wrists(roles, parents, pos):
            stack = list(children[t])
            while stack:
                c = stack.pop()
                far = [k for k in children[c] if _reach(children, pos, k, t) > forearm]
                if _reach(children, pos, c, t) <= forearm:
                    continue  # a finger (nothing below it reaches farther)
                if len(far) < len(children[c]) and float(np.linalg.norm(pos[c] - pos[t])) <= forearm:
                    stack.extend(far)  # a hand joint holding fingers and the prop (CMU's lhand below LeftWrist)
                else:
                    tops.add(c)
    return {k for j in tops for k in subtree_of(children, j)}


def _wrists(roles: list[str], parents: np.ndarray, pos: np.ndarray) -> list[tuple[int, float]]:
    """Each hand's first joint and its forearm's length (a split forearm's parts summed)."""
    out = []
    for t, r in enumerate(roles):
        if r != "hand" or parents[t] < 0 or roles[int(parents[t])] == "hand":
            continue
        length, j = 0.0, t
        while parents[j] >= 0 and roles[int(parents[j])] == "forearm":
            length += float(np.linalg.norm(pos[j] - pos[int(parents[j])]))
            j = int(parents[j])
        if length > 0:
            out.append((t, length))
    return out


def _reach(children: list[list[int]], pos: np.ndarray, j: int, origin: int) -> float:
    """How far from ``origin`` the farthest joint at or below ``j`` lies."""
    return max(float(np.linalg.norm(pos[k] - pos[origin])) for k in subtree_of(children, j))


def attachments(roles: list[str], parents: np.ndarray, children: list[list[int]], head: int | None,
                tips=frozenset(), names: list[str] | None = None, pos: np.ndarray | None = None) -> set[int]:
    """Bodies off the body's frame (the ways from the base to the head, the hands and the feet, and
    the hands' and feet's own subtrees): a face's and the hair's chains below the head, a skirt's or a
    bust's beside the trunk (VRoid's ``J_Sec_*``); and the props (:func:`props`, a prop's leaf joint
    included), wherever they hang. They ride welded on the joint they hang from, with a token mass and
    no shape; other ``tips`` keep their own rules. Only the props where no head is known."""
    # A weapon_r > weapon_r_end chain in the hand took 85% of the hand's mass and a 0.9 m capsule; a sword
    # no name calls a prop took the hands' share by its length (0.44 of both hands' 0.92 kg); a weapon_r
    # leaf made a hand without fingers end at it (5 cm long: 0.29 kg against the other hand's 0.62).
    held = props(roles, parents, children, names, pos)
    if head is None:
        return held
    ends = [b for b, r in enumerate(roles) if r in ("hand", "foot") and (parents[b] < 0 or roles[int(parents[b])] != r)]
    ends += [b for b, r in enumerate(roles) if r == "forearm" and not children[b]]  # an arm without a hand
    frame = {head, *_ancestors(head, parents)}
    for b in ends:
        frame.update(_ancestors(b, parents))
        frame.update(subtree_of(children, b))
    return {b for b in range(len(roles)) if (b not in frame and b not in tips) or b in held}


def segment_masses(roles: list[str], lengths: np.ndarray, total_mass: float, tips=frozenset(),
                   parents: np.ndarray | None = None) -> np.ndarray:
    """Mass per joint body: each de Leva segment's share split over its bodies by length; the trunk's
    share, plus that of segments the rig lacks, split over the ``other`` bodies by length. ``tips``
    (no segment of their own) get none. With ``parents``, a limb the rig has on one side only (one
    arm, one leg) weighs one side's share, the other's going to the trunk: it weighed both."""
    lengths = np.maximum(np.asarray(lengths, dtype=float), 1e-3)
    lengths[sorted(tips)] = 0.0
    masses = np.zeros(len(roles))
    present = set(roles)
    left_over = 1.0
    for role, seg in DE_LEVA.items():
        if role == "trunk":
            continue
        members = [i for i, r in enumerate(roles) if r == role]
        if not members:
            continue
        # Paired limbs appear twice; the table gives one side's share.
        sides = 1 if role == "head" else 2
        if parents is not None and sides == 2:
            sides = min(2, sum(1 for i in members if parents[i] < 0 or roles[int(parents[i])] != role))
        share = seg.mass * sides
        # Split per side by length; bodies of one role on both sides share the paired total.
        masses[members] = share * _by_length(lengths[members])
        left_over -= share
    others = [i for i, r in enumerate(roles) if r in ("other", "trunk")]
    if others:
        masses[others] = left_over * _by_length(lengths[others])
    elif "other" not in present:
        masses *= 1.0 / max(masses.sum(), 1e-9)
    return masses * total_mass


HEIGHT_M = (0.25, 5.0)
"""Standing heights (m) the physics body is built for: de Leva's person, scaled. A rig in metres on a
stage that says centimetres (1.8 cm tall) made inertias MuJoCo refuses, and attend --physics failed."""


def check_biped(roles: list[str], pos: np.ndarray, height: float, where: str, extent=None,
                meters_per_unit: float = 1.0) -> None:
    """The body is de Leva's human standing: a skeleton lying down or upside down in the stage at rest
    (its head not above its pelvis, or its feet not below), and one whose hands are on the ground at
    rest (a quadruped's front feet), would be simulated as a person in a pose it cannot hold (a lying
    rig was said to have 'stayed up' at 247% of its pelvis height), so they are refused, as is one
    without feet, or of no person's height (``height`` in metres, :data:`HEIGHT_M`; ``meters_per_unit``:
    the stage's, said where it is not). ``extent``: the bodies that size it (not a camera joint hung
    from the hips)."""
    body = pos if extent is None else pos[list(extent)]
    size = float(np.linalg.norm(np.ptp(body, axis=0)))
    heads = [b for b, r in enumerate(roles) if r == "head"]
    feet = [b for b, r in enumerate(roles) if r == "foot"]
    if not feet:  # a rig without feet (cut off at the knees) was built hovering 45 cm up and fell at once
        raise UsdGazeError(f"{where}: no feet, by name or by the shape of the legs (no branch of the skeleton reaches "
                           "the ground at rest): the physics body stands on its feet")
    if heads and size > 0:
        head_up = max(float(pos[b, 2]) for b in heads) - float(pos[0, 2])
        feet_down = float(pos[0, 2]) - min(float(pos[b, 2]) for b in feet)
        if min(head_up, feet_down) < 0.15 * size:
            raise UsdGazeError(f"{where}: it does not stand at rest in the stage (head {head_up / size:.0%} of its size "
                               f"above the pelvis, feet {feet_down / size:.0%} below): the physics body stands "
                               "upright; a character lying down or upside down is not supported")
    hands = [b for b, r in enumerate(roles) if r == "hand"]
    low = min((float(pos[b, 2] - body[:, 2].min()) for b in hands), default=np.inf)
    if low < 0.2 * height:
        raise UsdGazeError(f"{where}: its hands are on the ground at rest ({low / height:.0%} of its height up): "
                           "the physics body is a biped (de Leva's human segments); quadrupeds are not supported")
    # Last: a body lying down (or on all fours) is as tall as it is thick, and its stance is what to say.
    if not HEIGHT_M[0] <= height <= HEIGHT_M[1]:
        raise UsdGazeError(f"{where}: the body stands {height:.3g} m tall in the stage (metersPerUnit "
                           f"{meters_per_unit:g}), not {HEIGHT_M[0]:g} to {HEIGHT_M[1]:g} m: the physics body is a "
                           "person's size; check the stage's metersPerUnit or the SkelRoot's scale")


def inertials(roles: list[str], seg_vec: np.ndarray, mass: np.ndarray):
    """Per body, de Leva's centre of mass, principal moments and their frame along its segment."""
    n = len(roles)
    com = np.zeros((n, 3))
    inertia = np.zeros((n, 3))
    iquat = np.tile(rot.IDENTITY, (n, 1))
    for b in range(n):
        s = DE_LEVA.get(roles[b], DE_LEVA["trunk"])
        length = float(np.linalg.norm(seg_vec[b]))
        com[b] = s.com * seg_vec[b]
        kt, kl = s.gyration_transverse * length, s.gyration_long * length
        inertia[b] = mass[b] * np.array([kt * kt, kt * kt, max(kl * kl, 1e-6)])
        if length > 0:  # an end site's (zero) segment has no axis: its inertia stays in its frame
            iquat[b] = rot.shortest_arc(np.array([0, 0, 1.0]), seg_vec[b] / length)
    return com, np.maximum(inertia, 1e-6), iquat


def pelvis_bones(roles: list[str], bparent: np.ndarray) -> set[int]:
    """Bodies between the base and a thigh that lead to neither the head nor a hand: bones inside the
    pelvis (CMU's ``LHipJoint``), which is one rigid segment (de Leva's lower trunk)."""
    def above(kinds: tuple[str, ...]) -> set[int]:
        return {a for b, r in enumerate(roles) if r in kinds for a in _ancestors(b, bparent)}

    return {b for b in above(("thigh",)) - above(("head", "hand")) if b > 0 and roles[b] == "other"}
