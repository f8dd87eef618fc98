"""Joint names as words: split a rig's joint name into lower-case tokens and read what they say.

Real rigs wrap the anatomical word in prefixes, namespaces, numbering and separators
(``mixamorig:Spine1``, ``b_Spine01_02``, ``DEF-spine.003``, ``Bip01 Head``, ``CC_Base_NeckTwist01``,
``J_Bip_C_Head``, ``lEye``), and UsdSkel joint tokens carry exporters' spellings of them (``:``, ``-``,
``.`` and spaces become ``_``). Splitting on separators, case changes and digits gives the same tokens
for every spelling, so a role is recognised by a word among the tokens rather than by a whole name.

Pure Python; no numpy, no pxr.
"""

from __future__ import annotations

import functools
import re

_SEPARATORS = re.compile(r"[\s_\-.:|]+")
# "LHipJoint" -> L Hip Joint, "NeckTwist01" -> Neck Twist 01, "FACIAL" -> FACIAL, "lEye" -> l Eye
_CAMEL = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+")

# Words a lower-case compound ("lowerback", "headtop", "lhand") is made of. Only used to split a
# token that is entirely made of them, so an unknown word is never cut up.
_VOCABULARY = frozenset("""
left right lower upper low up mid middle neck back chest spine head hips hip pelvis eye eyes eyeball ball
top end twist joint face facial jaw root waist torso abdomen collar shoulder arm leg hand foot toe fore
thigh calf knee shin base nub tip finger fingers thumb bone bend clavicle elbow wrist ankle ctrl ik fk
""".split())

LEFT_WORDS = frozenset({"left", "l"})
RIGHT_WORDS = frozenset({"right", "r"})


def leaf(joint: str) -> str:
    """The last element of a joint path (``Hips/Spine/Head`` -> ``Head``)."""
    return joint.rsplit("/", 1)[-1]


def spelled_with_names(joints: list[str], parents, names) -> list[str] | None:
    """The joint paths spelled with a skeleton's ``jointNames`` (``Hips/Spine`` for tokens ``j0/j1``
    named Hips and Spine), or None when there are none, not one per joint, or they spell the same."""
    if names is None or len(names) != len(joints):
        return None
    spelled: list[str] = []
    for i, name in enumerate(names):
        above = spelled[parents[i]].split("/") if parents[i] >= 0 else []
        own = _own_name(str(name), above) or leaf(joints[i])
        spelled.append(f"{spelled[parents[i]]}/{own}" if parents[i] >= 0 else own)
    return None if spelled == list(joints) else spelled


_PATH_SEPARATORS = re.compile(r"[/|]")


def _own_name(name: str, above: list[str]) -> str:
    """A ``jointNames`` entry's own name. A DCC may name a joint by its path (Maya's ``|grp|Hips|Spine``,
    ``Hips/Spine``, or the last few elements of it): where the elements before the last are the names of
    the joint's ancestors (``above``, root first; a root's may be groups above the skeleton), it is the
    last. Read whole, the head was ``Hips_Spine_..._Head``, a name of every word, and no chain bound."""
    parts = [p for p in _PATH_SEPARATORS.split(name) if p]
    k = min(len(parts) - 1, len(above))
    if parts and parts != [name] and parts[len(parts) - 1 - k:-1] == above[len(above) - k:]:
        return parts[-1]
    return name.replace("/", "_")


def names_not_read(joints: list[str], names) -> str:
    """What a binding failure adds where the skeleton's ``jointNames`` are not one per joint (and so
    were not read, see :func:`spelled_with_names`): otherwise the line suggests there are none."""
    if names is None or len(names) == len(joints):
        return ""
    return (f"; its jointNames holds {len(names)} names for {len(joints)} joints (not one per joint), so they were "
            "not read: author one name per joint")


@functools.lru_cache(maxsize=4096)
def _segment(word: str) -> tuple[str, ...]:
    """A lower-case token as vocabulary words, a leading side letter allowed (``lhand``); else itself."""
    if word in _VOCABULARY or len(word) < 4:
        return (word,)

    @functools.lru_cache(maxsize=None)
    def split(start: int) -> tuple[str, ...] | None:
        if start == len(word):
            return ()
        for end in range(len(word), start, -1):
            if word[start:end] in _VOCABULARY:
                rest = split(end)
                if rest is not None:
                    return (word[start:end],) + rest
        return None

    words = split(0)
    if words is None and word[0] in "lr":
        rest = split(1)
        words = (word[0],) + rest if rest else None
    return words if words else (word,)


@functools.lru_cache(maxsize=4096)
def tokens(joint: str) -> tuple[str, ...]:
    """Lower-case words of a joint's own name: ``mixamorig_Spine1`` -> ``('mixamorig', 'spine', '1')``."""
    out: list[str] = []
    for part in _SEPARATORS.split(leaf(joint)):
        for piece in _CAMEL.findall(part):
            out.extend(_segment(piece.lower()))
    return tuple(out)


@functools.lru_cache(maxsize=4096)  # as tokens: asked for every joint of every character bound
def side(joint: str) -> int:
    """+1 for a left-side joint name, -1 for right, 0 for neither (or both)."""
    words = set(tokens(joint))
    left, right = bool(words & LEFT_WORDS), bool(words & RIGHT_WORDS)
    return int(left) - int(right)


@functools.lru_cache(maxsize=4096)
def mirror_key(joint: str, numbers: bool = True) -> str:
    """The name with its side word blanked: a left joint and its right twin share it.

    ``numbers=False`` also drops digits, for rigs that number joints through the whole skeleton
    (``b_LeftLeg_12`` / ``b_RightLeg_27``).
    """
    words = ["*" if w in LEFT_WORDS or w in RIGHT_WORDS else w for w in tokens(joint)]
    return ".".join(w for w in words if numbers or not w.isdigit())


# -- what a name says about its role --------------------------------------------------------------

# A rig's control and helper joints, whatever body word they carry.
_CONTROLS = frozenset({"ik", "fk", "ctrl", "ctl", "control", "target", "tgt", "aim", "pole", "helper", "mch",
                       "null", "locator", "loc", "socket"})
_NOT_A_BODY_JOINT = _CONTROLS | {"end", "nub", "tip", "top", "look", "jaw", "hair", "hat", "cap"}
_NOT_AN_EYEBALL = _NOT_A_BODY_JOINT | {"lid", "lids", "lash", "lashes", "brow", "blink", "upper", "lower", "inner",
                                       "outer", "highlight", "spec", "tear", "iris", "pupil"}


def is_control(joint: str) -> bool:
    """A rig's control or helper joint by its name (UE's ``ik_foot_l``, ``ik_hand_gun``, ``MCH-...``):
    whatever body word it carries, not that body part."""
    return bool(set(tokens(joint)) & _CONTROLS)


_PROPS = frozenset({"prop", "props", "weapon", "attach", "attachment", "grip", "holster"})


def is_prop(joint: str) -> bool:
    """A joint a prop hangs from (UE's ``weapon_r``, ``prop_r``; ``RightHandGrip``): no body part."""
    return bool(set(tokens(joint)) & _PROPS)


def is_head(joint: str) -> bool:
    words = set(tokens(joint))
    return "head" in words and not words & _NOT_A_BODY_JOINT and side(joint) == 0


def is_pelvis(joint: str) -> bool:
    words = set(tokens(joint))
    return bool(words & {"hips", "hip", "pelvis"}) and not words & _NOT_A_BODY_JOINT and side(joint) == 0


def is_eye(joint: str) -> int:
    """+1 a left eyeball joint, -1 a right one, 0 not an eyeball (lids, targets, ...)."""
    words = set(tokens(joint))
    if not words & {"eye", "eyes", "eyeball"} or words & _NOT_AN_EYEBALL:
        return 0
    return side(joint)


_UPPER_TRUNK = frozenset({"chest", "thorax", "ribcage", "ribs"})
_LOWER_TRUNK = frozenset({"abdomen", "waist", "belly", "stomach", "back"})
_SPINE = frozenset({"spine", "back", "torso"})


def spine_part(joint: str) -> str | None:
    """What a joint between pelvis and head says it is: ``neck``, ``lowerSpine``, ``upperSpine``,
    ``spine`` (a spine word, or no word at all: its place on the chain decides) or None (not a chain
    joint by its name: a side joint, an end or a control)."""
    words = set(tokens(joint))
    if words & _NOT_A_BODY_JOINT or side(joint) != 0:
        return None
    if "neck" in words:
        return "neck"
    if words & _UPPER_TRUNK or ("upper" in words and words & _SPINE):
        return "upperSpine"
    if words & _LOWER_TRUNK or ("lower" in words and "spine" in words):
        return "lowerSpine"
    return "spine"


def says_trunk(joint: str) -> bool:
    """A trunk word in the name (``spine``, ``chest``, ``back``, ...; not ``neck``): what the name says
    outweighs the joint's place on the chain, where :func:`spine_part` lets the place decide."""
    return bool(set(tokens(joint)) & (_UPPER_TRUNK | _LOWER_TRUNK | _SPINE))


# What DCCs and exporters put after a joint's own words: side and centre letters (AdvancedSkeleton's
# HeadEnd_M, Maya's C_/L_/R_ ... _jnt), joint and deform tags (_JNT, _bind, _def) and numbering
# (b_HeadEnd_06). Read at a name's end only, so no word inside a name is dropped.
_SUFFIXES = LEFT_WORDS | RIGHT_WORDS | {"c", "m", "ctr", "jnt", "jj", "jt", "joint", "bind", "bnd", "def", "drv",
                                        "skin"}
_END_SITE = re.compile(r"(end|top|nub|site|tip)$")


def is_end_site(joint: str) -> bool:
    """An exporter's end site by name: its last word but the suffixes ends in end, top, nub, site or tip
    (``HeadTop_End``, ``LeftToe_End``, ``Bip01 HeadNub``, ``headtop``; ``C_headEnd_jnt``, ``HeadEnd_M``).
    Whole names were matched before: a suffix made Maya's and AdvancedSkeleton's head ends a 2.8 kg head."""
    words = list(tokens(joint))
    while words and (words[-1] in _SUFFIXES or words[-1].isdigit()):
        words.pop()
    return bool(words) and bool(_END_SITE.search(words[-1]))


_RIGIFY = re.compile(r"^(?:(?:def|org)\.)?spine(?:\.(\d+))?$")
RIGIFY_ROLES = {0: "pelvis", 1: "lowerSpine", 2: "upperSpine", 3: "upperSpine", 4: "neck", 5: "neck", 6: "head"}
"""Rigify's human metarig numbers one ``spine`` chain from the hips (0, unnumbered) to the head (6)."""


def rigify_number(joint: str) -> int | None:
    """The number of a Rigify ``spine.NNN`` bone (``DEF-spine.003`` -> 3, ``DEF-spine`` -> 0), else None."""
    m = _RIGIFY.match(".".join(tokens(joint)))
    return int(m.group(1) or 0) if m else None


def unique(base: str, taken: set[str]) -> str:
    """``base``, or ``base_2``, ``base_3``... the first not in ``taken``; added to ``taken``."""
    name, i = base, 1
    while name in taken:
        i += 1
        name = f"{base}_{i}"
    taken.add(name)
    return name
