"""Rig binding: find the gaze chain on a skeleton by joint names and work out the character frame.

Pure numpy; joint names come in as Skeleton joint paths (``Hips/Spine/...``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.gaze.definition import ROLES
from usdgaze.errors import RigError


# UsdSkel joint tokens are path elements, which cannot hold ':', '-' or '.', so exporters write
# Mixamo's "mixamorig:Head" as "mixamorig_Head" and Rigify's "DEF-spine.001" / "DEF-eye.L" as
# "DEF_spine_001" / "DEF_eye_L". Both spellings must bind alike.
_MIXAMO_PREFIX = re.compile(r"^mixamorig\d*_")
_SANITIZED_SUFFIX = re.compile(r"_(\d{3}|[LRlr])$")


def leaf(joint: str) -> str:
    """The joint's own name without its path or a namespace prefix (``mixamorig:Head``,
    ``mixamorig_Head`` -> ``Head``)."""
    return _MIXAMO_PREFIX.sub("", joint.rsplit("/", 1)[-1].rsplit(":", 1)[-1])


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9.]", "", _SANITIZED_SUFFIX.sub(r".\1", leaf(name)).lower())


# Exact (normalized) leaf names per role for the conventions we know. Order inside a role does not
# matter: a role's joints are always taken root-to-tip along the chain.
_NAMES = {
    # "spine" alone is the lower spine (Mixamo); Rigify's pelvis bone is DEF-spine / ORG-spine.
    "pelvis": {"hips", "pelvis", "hip", "defspine", "orgspine", "bippelvis", "bip01pelvis"},
    "lowerSpine": {"lowerback", "spine", "spine01", "defspine.001", "orgspine.001", "spine.001", "bip01spine", "bipspine"},
    "upperSpine": {
        "chest", "chest2", "upperchest", "spine1", "spine2", "spine3", "spine02", "spine03", "spine04",
        "spine05", "defspine.002", "defspine.003", "orgspine.002", "orgspine.003", "spine.002", "spine.003",
        "bip01spine1", "bip01spine2", "bip01spine3",
    },
    "neck": {"neck", "lowerneck", "upperneck", "neck1", "neck01", "neck02", "defspine.004", "defspine.005",
             "orgspine.004", "orgspine.005", "spine.004", "spine.005", "bip01neck", "bip01neck1"},
    "head": {"head", "defspine.006", "orgspine.006", "spine.006", "bip01head"},
}
_LEFT_EYE = re.compile(r"^(left[_.]?eye|l[_.]?eye|eye[_.]?l|eye[_.]?left|facial[_.]?l[_.]?eye|defeye\.l|orgeye\.l|eye\.l)$")
_RIGHT_EYE = re.compile(r"^(right[_.]?eye|r[_.]?eye|eye[_.]?r|eye[_.]?right|facial[_.]?r[_.]?eye|defeye\.r|orgeye\.r|eye\.r)$")
# Case matters: "LHipJoint" is left, "lowerback" is not.
_LEFT = re.compile(r"(^(Left|left|LEFT)|^L(?=[A-Z_.])|^l_|[_.][lL]$|\.[lL]\.)")
_RIGHT = re.compile(r"(^(Right|right|RIGHT)|^R(?=[A-Z_.])|^r_|[_.][rR]$|\.[rR]\.)")


@dataclass(frozen=True)
class Chain:
    """The bound gaze chain: joint indices (skeleton order) per role, root to tip."""

    roles: dict[str, tuple[int, ...]]
    path: tuple[int, ...]
    """Every joint from the first pelvis joint down to the head, inclusive."""
    leg_roots: tuple[int, ...]
    """Children of the last pelvis joint that are not on the chain (they counter-rotate)."""

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


def _describe(joints: list[str], found: dict[str, list[int]]) -> str:
    parts = [f"{role}={','.join(leaf(joints[i]) for i in idx) or '-'}" for role, idx in found.items()]
    return "found " + " ".join(parts)


def _hint() -> str:
    return "bind it explicitly with gaze:binding:<role> on the SkelRoot's GazeMapAPI (usdgaze inspect lists the joints)"


def bind_chain(joints: list[str], parents: np.ndarray, bindings: dict[str, tuple[str, ...]] | None = None,
               where: str = "skeleton") -> Chain:
    """Bind roles to joints: explicit bindings first, then names; raise :class:`RigError` with what was found."""
    bindings = {k: tuple(v) for k, v in (bindings or {}).items() if v}
    index = {j: i for i, j in enumerate(joints)}
    found: dict[str, list[int]] = {}
    for role, names in bindings.items():
        if role not in ROLES:
            raise RigError(f"{where}: unknown gaze role '{role}' (roles: {', '.join(ROLES)})")
        missing = [n for n in names if n not in index]
        if missing:
            raise RigError(f"{where}: gaze:binding:{role} names '{missing[0]}', which is not a joint of this skeleton")
        found[role] = sorted(index[n] for n in names)

    keys = [_key(j) for j in joints]
    for role in ("pelvis", "head"):
        if role not in found:
            found[role] = [i for i, k in enumerate(keys) if k in _NAMES[role]][:1]
    if not found["pelvis"] or not found["head"]:
        auto = {r: [i for i, k in enumerate(keys) if k in _NAMES[r]] for r in _NAMES}
        raise RigError(f"{where}: no gaze chain (pelvis and head) found by name; {_describe(joints, auto)}; {_hint()}")

    pelvis_first, head = found["pelvis"][0], found["head"][-1]
    path = _path_to_root(head, parents)
    if pelvis_first not in path:
        raise RigError(f"{where}: head '{leaf(joints[head])}' is not below pelvis '{leaf(joints[pelvis_first])}'; {_hint()}")
    path = path[path.index(pelvis_first):]
    between = [j for j in path if j not in found["pelvis"] and j not in found["head"]]

    for role in ("lowerSpine", "upperSpine", "neck"):
        if role not in found:
            found[role] = [j for j in between if keys[j] in _NAMES[role]]
    claimed = {j for r in ("lowerSpine", "upperSpine", "neck") for j in found[r]}
    rest = [j for j in between if j not in claimed]
    # Unknown names: joints above the first neck joint are spine, split a third low / the rest high.
    first_neck = min(found["neck"], default=None)
    spine_rest = [j for j in rest if first_neck is None or path.index(j) < path.index(first_neck)]
    if spine_rest and not (found["lowerSpine"] and found["upperSpine"]):
        if not found["lowerSpine"] and not found["upperSpine"]:
            cut = max(1, len(spine_rest) // 3)
            found["lowerSpine"], found["upperSpine"] = spine_rest[:cut], spine_rest[cut:]
        elif not found["lowerSpine"]:
            found["lowerSpine"] = spine_rest
        else:
            found["upperSpine"] = spine_rest
    for role in ("lowerSpine", "upperSpine", "neck"):
        if not found[role]:
            raise RigError(f"{where}: no {role} joint between pelvis and head; {_describe(joints, found)}; {_hint()}")

    if "leftEye" not in found or "rightEye" not in found:
        below_head = [i for i in range(len(joints)) if head in _path_to_root(i, parents)[:-1]]
        left = [i for i in below_head if _LEFT_EYE.match(_key(joints[i]).replace("..", "."))]
        right = [i for i in below_head if _RIGHT_EYE.match(_key(joints[i]).replace("..", "."))]
        found.setdefault("leftEye", left[:1])
        found.setdefault("rightEye", right[:1])
    if bool(found["leftEye"]) != bool(found["rightEye"]):
        raise RigError(f"{where}: found only one eye joint; {_describe(joints, found)}; {_hint()}")

    pelvis = found["pelvis"][-1]
    on_chain = set(path)
    legs = tuple(i for i in range(len(joints)) if parents[i] == pelvis and i not in on_chain)
    roles = {r: tuple(sorted(found.get(r, []), key=lambda j: len(_path_to_root(j, parents)))) for r in ROLES}
    return Chain(roles=roles, path=tuple(path), leg_roots=legs)


_MIRROR = (("Left", "Right"), ("left", "right"), ("LEFT", "RIGHT"))


def mirror(joint: str) -> str | None:
    """The right-side name of a left-side joint path (``Hips/LeftUpLeg`` -> ``Hips/RightUpLeg``)."""
    head, _, name = joint.rpartition("/")
    for a, b in _MIRROR:
        if name.startswith(a):
            return f"{head}/{b}{name[len(a):]}".lstrip("/")
    for pattern, repl in ((r"^L(?=[A-Z_.])", "R"), (r"^l_", "r_"), (r"([_.])l$", r"\1r"), (r"([_.])L$", r"\1R"),
                          (r"\.L\.", ".R."), (r"\.l\.", ".r.")):
        if re.search(pattern, name):
            return f"{head}/{re.sub(pattern, repl, name, count=1)}".lstrip("/")
    return None


def mirrored_pairs(joints: list[str]) -> list[tuple[int, int]]:
    """(left, right) joint index pairs whose names mirror each other (parents mirrored too)."""
    by_leaf = {}
    for i, j in enumerate(joints):
        by_leaf.setdefault(leaf(j), []).append(i)
    pairs = []
    for i, j in enumerate(joints):
        if side(j) <= 0:
            continue
        other = mirror(leaf(j))
        for k in by_leaf.get(other.lstrip("/") if other else "", []):
            if side(joints[k]) < 0:
                pairs.append((i, k))
                break
    return pairs


def side(joint: str) -> int:
    """+1 for a left-side joint name, -1 for right, 0 otherwise."""
    name = leaf(joint)
    if _LEFT.search(name):
        return 1
    if _RIGHT.search(name):
        return -1
    return 0


@dataclass(frozen=True)
class CharacterFrame:
    """The character's canonical axes in skeleton space at rest."""

    left: np.ndarray
    up: np.ndarray
    forward: np.ndarray

    @property
    def rotation(self) -> np.ndarray:
        """Quaternion mapping canonical (X left, Y up, Z forward) to skeleton space."""
        return rot.frame_rotation(self.left, self.up, self.forward)


def character_frame(joints: list[str], rest_world: np.ndarray, up: np.ndarray,
                    forward: np.ndarray | None = None, where: str = "skeleton") -> CharacterFrame:
    """Character axes from the rest pose: up from the stage, left from left/right-named joints.

    ``rest_world`` are skeleton-space rest transforms ``(J, 4, 4)``; ``up`` is the stage up axis in
    skeleton space. An explicit ``forward`` (skeleton space) wins over the names.
    """
    up = rot.normalize(np.asarray(up, dtype=float))
    if forward is not None and np.linalg.norm(forward) > 0:
        fwd = np.asarray(forward, dtype=float)
        fwd = rot.normalize(fwd - np.dot(fwd, up) * up)
        if np.linalg.norm(fwd) == 0:
            raise RigError(f"{where}: gaze:binding:forward is parallel to the stage up axis")
        return CharacterFrame(left=np.cross(up, fwd), up=up, forward=fwd)
    pairs = mirrored_pairs(joints)
    if not pairs:
        raise RigError(
            f"{where}: cannot tell the character's forward: no left/right joint pairs by name; set gaze:binding:forward"
        )
    pos = rest_world[:, :3, 3]
    depth = {i: j.count("/") for i, j in enumerate(joints)}
    extent = max(float(np.ptp(pos @ up)), 1e-9)
    left = np.zeros(3)
    # The pairs nearest the root (hips before shoulders before hands): limbs far down the
    # hierarchy are often posed asymmetrically at rest. Pairs at one spot (CMU's hip joints) say nothing.
    for level in sorted({depth[l] for l, _ in pairs}):
        spread = [pos[l] - pos[r] for l, r in pairs if depth[l] == level]
        spread = [v - np.dot(v, up) * up for v in spread]
        spread = [v for v in spread if np.linalg.norm(v) > 0.01 * extent]
        if spread:
            left = np.mean(spread, axis=0)
            break
    if np.linalg.norm(left) < 1e-9:
        raise RigError(f"{where}: left and right joints coincide at rest; set gaze:binding:forward")
    left = rot.normalize(left)
    return CharacterFrame(left=left, up=up, forward=np.cross(left, up))
