"""Rig binding: find the gaze chain on a skeleton and work out the character frame.

Joints are recognised by the words in their names (:mod:`usdgaze.core.names`), then by the
skeleton's shape where names say nothing: the head is the joint named so (or the eyes' parent, or
Rigify's ``spine.006``), the pelvis the deepest hips/pelvis-named joint above it (or the first joint
above it where a mirrored pair of limbs branches off), and the joints between them are split into
lower spine, upper spine and neck by their words and their order. Explicit bindings (``--bind``,
``gaze:binding:<role>``) win over all of that. Every role carries the reason it was bound, for
``usdgaze inspect``.

Pure numpy; joint names come in as Skeleton joint paths (``Hips/Spine/...``). The character frame
is worked out in :mod:`usdgaze.core.character_frame`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from usdgaze.core import names
from usdgaze.core.character_frame import (  # noqa: F401  (rig binding's names)
    CharacterFrame, character_frame, mirrored_pairs, side)
from usdgaze.errors import NoHeadError, RigError
from usdgaze.gaze.definition import ROLES

_MIXAMO_PREFIX = re.compile(r"^mixamorig\d*_")
_SPINE_ROLES = ("lowerSpine", "upperSpine", "neck")
_TWIST_WORDS = frozenset({"twist", "roll"})  # helpers that share a body part's name (UE's upperarm_twist_01_l)
_HINT = ("bind it with --bind ROLE=JOINT[+JOINT...] (roles: " + ", ".join(ROLES) + ") or gaze:binding:<role> on "
         "the SkelRoot's GazeMapAPI (usdgaze inspect lists the joints)")


def leaf(joint: str) -> str:
    """The joint's own name without its path or a namespace prefix (``mixamorig:Head``,
    ``mixamorig_Head`` -> ``Head``)."""
    return _MIXAMO_PREFIX.sub("", joint.rsplit("/", 1)[-1].rsplit(":", 1)[-1])


@dataclass(frozen=True)
class Chain:
    """The bound gaze chain: joint indices (skeleton order) per role, root to tip."""

    roles: dict[str, tuple[int, ...]]
    path: tuple[int, ...]
    """Every joint from the first pelvis joint down to the head, inclusive."""
    leg_roots: tuple[int, ...]
    """Children of the last pelvis joint that are not on the chain (they counter-rotate)."""
    reasons: dict[str, str] = field(default_factory=dict)
    """Role -> why these joints were bound (a name, a hint, the skeleton's shape)."""

    @property
    def pelvis(self) -> int:
        return self.roles["pelvis"][-1]

    @property
    def head(self) -> int:
        return self.roles["head"][-1]

    @property
    def eyes(self) -> tuple[int, int] | None:
        left, right = self.roles.get("leftEye", ()), self.roles.get("rightEye", ())
        return (left[0], right[0]) if left and right else None


def _path_to_root(j: int, parents: np.ndarray) -> list[int]:
    out = []
    while j >= 0:
        out.append(j)
        j = int(parents[j])
    return out[::-1]


def _listed(joints: list[str], idx, most: int = 10) -> str:
    idx = list(idx)
    shown = [names.leaf(joints[i]) for i in idx[:most]]
    return ", ".join(shown) + (f", ... ({len(idx)} in all)" if len(idx) > most else "") if idx else "-"


def resolve_joint(name: str, joints: list[str], what: str) -> int:
    """Index of the joint a user named: its path, else its own name (as written or as exporters spell it)."""
    if name in joints:
        return joints.index(name)
    token = re.sub(r"[^A-Za-z0-9_]", "_", name.rsplit("/", 1)[-1])
    for same in (lambda j: names.leaf(j) == token, lambda j: leaf(j) == leaf(token),
                 lambda j: names.leaf(j).lower() == token.lower(), lambda j: leaf(j).lower() == leaf(token).lower()):
        hits = [i for i, j in enumerate(joints) if same(j)]
        if len(hits) > 1:
            raise RigError(f"{what}: '{name}' matches {len(hits)} joints ({_listed(joints, hits, 4)}); give the joint path")
        if hits:
            return hits[0]
    raise RigError(f"{what}: '{name}' is not a joint of this skeleton")


def _explicit(joints: list[str], bindings, labels, where: str,
              tokens: list[str] | None = None) -> tuple[dict[str, list[int]], dict[str, str]]:
    found, reasons = {}, {}
    for role, wanted in bindings.items():
        label = labels.get(role, f"gaze:binding:{role}")
        if role not in ROLES:
            raise RigError(f"{where}: {label}: unknown gaze role '{role}' (roles: {', '.join(ROLES)})")
        picked = [resolve_either(n, joints, tokens, f"{where}: {label}") for n in wanted]
        twice = sorted({j for j in picked if picked.count(j) > 1})
        if twice:
            raise RigError(f"{where}: {label}: names joint '{names.leaf(joints[twice[0]])}' twice")
        found[role] = sorted(picked)
        reasons[role] = label
    _one_role_each(joints, found, where, "a joint plays one role")
    return found, reasons


def resolve_either(name: str, joints: list[str], tokens: list[str] | None, what: str) -> int:
    """A bound joint named by its token (path or own name) where ``joints`` spell the skeleton with its
    jointNames (``tokens``: the same joints as USD names them), else by that spelling."""
    if tokens is None or tokens is joints:
        return resolve_joint(name, joints, what)
    try:
        return resolve_joint(name, tokens, what)
    except RigError:
        return resolve_joint(name, joints, what)


def _one_role_each(joints: list[str], found: dict[str, list[int]], where: str, advice: str) -> None:
    owner: dict[int, str] = {}
    for role in ROLES:
        for j in found.get(role, []):
            if j in owner:
                raise RigError(f"{where}: joint '{names.leaf(joints[j])}' would play two roles, {owner[j]} and "
                               f"{role}; {advice}")
            owner[j] = role


def _check_bound_places(path: list[int], head: int, joints, parents, found, bindings, labels, where: str) -> None:
    """Explicitly bound joints where their roles can be: the body's on the pelvis-to-head path, in
    that order, and the eyes below the head."""
    place = {j: i for i, j in enumerate(path)}
    body = ("pelvis", "lowerSpine", "upperSpine", "neck", "head")
    for role in bindings:
        label = labels.get(role, f"gaze:binding:{role}")
        for j in found.get(role, []):
            if role in body and j not in place:
                raise RigError(f"{where}: {label}: joint '{names.leaf(joints[j])}' is not on the chain from pelvis "
                               f"'{names.leaf(joints[path[0]])}' to head '{names.leaf(joints[head])}'; {_HINT}")
            if role in ("leftEye", "rightEye") and head not in _path_to_root(j, parents)[:-1]:
                raise RigError(f"{where}: {label}: joint '{names.leaf(joints[j])}' is not below head "
                               f"'{names.leaf(joints[head])}'")
    spans = [(r, [place[j] for j in found.get(r, []) if j in place]) for r in body]
    spans = [(r, at) for r, at in spans if at]
    for (r0, a0), (r1, a1) in zip(spans, spans[1:]):
        if max(a0) >= min(a1) and (r0 in bindings or r1 in bindings):
            raise RigError(f"{where}: {r1} '{names.leaf(joints[path[min(a1)]])}' is not above {r0} "
                           f"'{names.leaf(joints[path[max(a0)]])}' on the chain (pelvis, lowerSpine, upperSpine, "
                           f"neck, head from the root up); {_HINT}")


def _below(j: int, parents: np.ndarray) -> list[int]:
    """Joints under j (not j itself), shallow first (in joint order at one depth)."""
    up = [int(p) for p in parents]  # Python ints: each joint's walk to the root reads them
    under, depth = [], {}
    for i in range(len(up)):
        k, d, inside = up[i], 1, False
        while k >= 0:
            inside, d, k = inside or k == j, d + 1, up[k]
        if inside:
            under.append(i)
            depth[i] = d
    return sorted(under, key=depth.get)


def _eyes_under(head: int, joints, parents) -> dict[str, list[int]]:
    under = _below(head, parents)
    return {"leftEye": [i for i in under if names.is_eye(joints[i]) > 0][:1],
            "rightEye": [i for i in under if names.is_eye(joints[i]) < 0][:1]}


def _mirrored_children(j: int, joints: list[str], parents: np.ndarray) -> tuple[int, int] | None:
    kids = [i for i in range(len(joints)) if parents[i] == j]
    for numbers in (True, False):
        for a in kids:
            for b in kids:
                if (names.side(joints[a]) > 0 > names.side(joints[b])
                        and names.mirror_key(joints[a], numbers) == names.mirror_key(joints[b], numbers)):
                    return a, b
    return None


def _legs_off_the_spine(path: list[int], joints, parents, found, reasons) -> None:
    """3ds Max Biped hangs the thighs off the first spine joint, not the pelvis: that joint then turns
    with the pelvis, and the legs under it counter-rotate."""
    pelvis = found["pelvis"][-1]
    at = path.index(pelvis)
    claimed = {j for r in found for j in found[r]}
    if _mirrored_children(pelvis, joints, parents) or at + 1 >= len(path) or path[at + 1] in claimed:
        return
    nxt = path[at + 1]
    rest = [j for j in path[at + 2:] if j not in claimed]
    pair = _mirrored_children(nxt, joints, parents)
    if pair and len(rest) >= 3:
        found["pelvis"] = found["pelvis"] + [nxt]
        reasons["pelvis"] += (f"; '{names.leaf(joints[nxt])}' too: legs {names.leaf(joints[pair[0]])}/"
                              f"{names.leaf(joints[pair[1]])} hang off it")


def _find_head(joints, parents, found, reasons) -> None:
    named = [i for i, j in enumerate(joints) if names.is_head(j)]
    if named:
        # The one with eyes under it, else the shallowest (a 'HeadTwist' under 'Head' is no head);
        # a twist or roll helper is no head either where a plain head is a candidate: 'head_roll'
        # between neck and head has the eyes under it too, but the head's own motion is below it.
        with_eyes = [i for i in named if any(_eyes_under(i, joints, parents).values())]
        candidates = with_eyes or named
        plain = [i for i in candidates if not set(names.tokens(joints[i])) & _TWIST_WORDS]
        depth = {i: len(_path_to_root(i, parents)) for i in named}
        found["head"] = [min(plain or candidates, key=depth.get)]
        reasons["head"] = f"name '{names.leaf(joints[found['head'][0]])}'"
        return
    rigify = {names.rigify_number(j): i for i, j in enumerate(joints) if names.rigify_number(j) is not None}
    if 6 in rigify:
        numbered: dict[str, list[int]] = {}
        for number, i in sorted(rigify.items()):
            if number in names.RIGIFY_ROLES:
                numbered.setdefault(names.RIGIFY_ROLES[number], []).append(i)
        for role, idx in numbered.items():
            if role not in found:
                found[role], reasons[role] = idx, "Rigify spine numbering"
        return
    left = [i for i, j in enumerate(joints) if names.is_eye(j) > 0]
    right = [i for i, j in enumerate(joints) if names.is_eye(j) < 0]
    if left and right and parents[left[0]] == parents[right[0]] >= 0:
        found["head"] = [int(parents[left[0]])]
        reasons["head"] = "parent of the eye joints"


def _find_pelvis(joints, parents, head: int, found, reasons) -> None:
    above = _path_to_root(head, parents)[:-1]
    named = [j for j in above if names.is_pelvis(joints[j])]
    if named:
        found["pelvis"] = [named[-1]]  # the deepest: legs hang off 'Pelvis' under 'Hips'
        reasons["pelvis"] = f"name '{names.leaf(joints[named[-1]])}'"
        return
    for j in above:  # the first joint above the head where a mirrored pair branches off: the legs
        pair = _mirrored_children(j, joints, parents)
        if pair:
            found["pelvis"] = [j]
            reasons["pelvis"] = f"legs {names.leaf(joints[pair[0]])}/{names.leaf(joints[pair[1]])} branch here"
            return


def _split_spine(path: list[int], joints, found, reasons, fixed: set[str]) -> None:
    """Lower spine, upper spine and neck among the joints between pelvis and head.

    Named joints take their role; joints with only a spine word (or none) take theirs from their
    place: below the first upper-spine joint (or above the last lower-spine one) and, with neither
    named, the first third lower and the rest upper. Roles bound explicitly get nothing added.
    """
    claimed = {j for r in found for j in found[r]}
    between = [j for j in path if j not in claimed]
    part = {j: names.spine_part(joints[j]) for j in between}
    for role in _SPINE_ROLES:
        hits = [j for j in between if part[j] == role]
        if role not in found and hits:
            found[role] = hits
            reasons[role] = "name " + ", ".join(f"'{names.leaf(joints[j])}'" for j in hits)
    first_neck = min((path.index(j) for j in found.get("neck", [])), default=len(path))
    generic = [j for j in between if part[j] == "spine" and path.index(j) < first_neck]
    if "neck" not in found and len(generic) >= 3:
        found["neck"] = [generic.pop()]
        reasons["neck"] = f"'{names.leaf(joints[found['neck'][0]])}', the last joint before the head (no neck by name)"
    if not generic:
        return
    lower, upper = found.get("lowerSpine", []), found.get("upperSpine", [])
    if upper:
        boundary = min(path.index(j) for j in upper)
    elif lower:
        boundary = max(path.index(j) for j in lower) + 1
    else:
        boundary = path.index(generic[max(1, len(generic) // 3) - 1]) + 1
    for role, extra in (("lowerSpine", [j for j in generic if path.index(j) < boundary]),
                        ("upperSpine", [j for j in generic if path.index(j) >= boundary])):
        if extra and role not in fixed:
            found[role] = sorted(found.get(role, []) + extra, key=path.index)
            note = "by their place on the chain: " + ", ".join(f"'{names.leaf(joints[j])}'" for j in extra)
            reasons[role] = f"{reasons[role]}; {note}" if role in reasons else note


def bind_chain(joints: list[str], parents: np.ndarray, bindings: dict[str, tuple[str, ...]] | None = None,
               where: str = "skeleton", labels: dict[str, str] | None = None, tokens: list[str] | None = None) -> Chain:
    """Bind roles to joints: explicit bindings first, then names, then the skeleton's shape.

    ``bindings`` name joints by path or by their own name; ``labels`` say where each role's binding
    came from (``--bind``), for messages. ``tokens``: the skeleton's own joint paths where ``joints``
    spell them with its jointNames (a binding may name a joint either way). Raises :class:`RigError`
    listing the joints considered.
    """
    bindings = {k: tuple(v) for k, v in (bindings or {}).items() if v}
    found, reasons = _explicit(joints, bindings, labels or {}, where, tokens)
    if "head" not in found:
        _find_head(joints, parents, found, reasons)
    if "head" in found and "pelvis" not in found:
        _find_pelvis(joints, parents, found["head"][-1], found, reasons)
    if "head" not in found or "pelvis" not in found:
        raise _no_chain(joints, found, where)
    pelvis_first, head = found["pelvis"][0], found["head"][-1]
    path = _path_to_root(head, parents)
    if pelvis_first not in path:
        raise RigError(f"{where}: head '{names.leaf(joints[head])}' is not below pelvis "
                       f"'{names.leaf(joints[pelvis_first])}'; {_HINT}")
    path = path[path.index(pelvis_first):]
    if "pelvis" not in bindings:
        _legs_off_the_spine(path, joints, parents, found, reasons)
    _check_bound_places(path, head, joints, parents, found, bindings, labels or {}, where)
    _split_spine(path, joints, found, reasons, fixed=set(bindings))
    for role in _SPINE_ROLES:
        if not found.get(role):
            between = [j for j in path if j not in found["pelvis"] and j not in found["head"]]
            raise RigError(f"{where}: no {role} joint between pelvis '{names.leaf(joints[pelvis_first])}' and head "
                           f"'{names.leaf(joints[head])}'; considered {_listed(joints, between)}; {_described(joints, found)}; {_HINT}")

    _find_eyes(head, joints, parents, found, reasons, where)
    # A binding may have taken a joint the names gave another role.
    _one_role_each(joints, found, where, f"one of them is bound; {_described(joints, found)}; {_HINT}")
    pelvis = found["pelvis"][-1]
    on_chain = set(path)
    legs = tuple(i for i in range(len(joints)) if parents[i] == pelvis and i not in on_chain)
    roles = {r: tuple(sorted(found.get(r, []), key=lambda j: len(_path_to_root(j, parents)))) for r in ROLES}
    return Chain(roles=roles, path=tuple(path), leg_roots=legs, reasons=reasons)


def _no_chain(joints: list[str], found: dict, where: str) -> RigError:
    """The error for a skeleton whose names give no head, or no pelvis above it: what was considered."""
    heads = [i for i, j in enumerate(joints) if "head" in names.tokens(j)]
    pelvises = [i for i, j in enumerate(joints) if set(names.tokens(j)) & {"hips", "hip", "pelvis"}]
    if "head" not in found:  # no character at all (a face's or a prop's skeleton): NoHeadError says so
        what = "no head (a joint named head, the eye joints' parent, or Rigify's spine.006)"
    else:
        what = (f"no pelvis above head '{names.leaf(joints[found['head'][-1]])}' (a joint named hips or pelvis, "
                "or one where a mirrored pair of legs branches off)")
    return (NoHeadError if "head" not in found else RigError)(
        f"{where}: no gaze chain (pelvis and head) found by name: {what}; considered as head: "
        f"{_listed(joints, heads)}; as pelvis: {_listed(joints, pelvises)}; joints: "
        f"{_listed(joints, range(len(joints)), 12)}; {_HINT}")


def _find_eyes(head: int, joints: list[str], parents: np.ndarray, found: dict, reasons: dict, where: str) -> None:
    """The eyes under ``head`` by name, where no binding gave them; both or neither."""
    eyes = _eyes_under(head, joints, parents)
    for role in ("leftEye", "rightEye"):
        if role not in found:
            found[role] = eyes[role]
            if eyes[role]:
                reasons[role] = f"name '{names.leaf(joints[eyes[role][0]])}'"
    if bool(found["leftEye"]) != bool(found["rightEye"]):
        considered = [i for i in _below(head, parents) if set(names.tokens(joints[i])) & {"eye", "eyes", "eyeball"}]
        raise RigError(f"{where}: found only one eye joint; considered {_listed(joints, considered)}; "
                       f"{_described(joints, found)}; {_HINT}")


def _described(joints: list[str], found: dict[str, list[int]]) -> str:
    return "found " + " ".join(f"{r}={'+'.join(names.leaf(joints[i]) for i in found.get(r, [])) or '-'}" for r in ROLES)
