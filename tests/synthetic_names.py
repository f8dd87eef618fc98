"""Joint names of real-world rig conventions, and a quadruped body, for tests/synthetic.py.

Each table maps the synthetic template's keys (tests/synthetic.py) to the DCC name a convention
gives that joint; ``{i:02d}`` is the joint's index in the skeleton (game rigs that number every
joint). Written from the conventions' documented names, not from usdgaze's word lists.
"""

from __future__ import annotations


def _sided(table: dict[str, str], left: str, right: str) -> dict[str, str]:
    """Expand ``{s}`` in a table's names to each side's spelling (keys end in _l / _r)."""
    out = {}
    for key, name in table.items():
        if "{s}" in name:
            out[f"{key}_l"] = name.replace("{s}", left)
            out[f"{key}_r"] = name.replace("{s}", right)
        else:
            out[key] = name
    return out


SCHEMES = {
    # A game rig numbering every joint by its index: b_Hips_01, b_Spine01_02, b_Neck_04, b_Head_05.
    "indexed": _sided({
        "root": "b_Root_{i:02d}", "pelvis": "b_Hips_{i:02d}", "spine_a": "b_Spine01_{i:02d}",
        "spine_b": "b_Spine02_{i:02d}", "neck": "b_Neck_{i:02d}", "head": "b_Head_{i:02d}",
        "head_end": "b_HeadEnd_{i:02d}", "eye": "b_{s}Eye_{i:02d}", "thigh": "b_{s}UpLeg_{i:02d}",
        "knee": "b_{s}Leg_{i:02d}", "ankle": "b_{s}Foot_{i:02d}", "toe": "b_{s}Toe_{i:02d}",
        "clav": "b_{s}Shoulder_{i:02d}", "arm": "b_{s}Arm_{i:02d}", "forearm": "b_{s}ForeArm_{i:02d}",
        "hand": "b_{s}Hand_{i:02d}",
    }, "Left", "Right"),
    # 3ds Max Biped (no eye joints).
    "biped": _sided({
        "root": "Bip01", "pelvis": "Bip01 Pelvis", "spine_a": "Bip01 Spine", "spine_b": "Bip01 Spine1",
        "spine_c": "Bip01 Spine2", "neck": "Bip01 Neck", "head": "Bip01 Head", "head_end": "Bip01 HeadNub",
        "thigh": "Bip01 {s} Thigh", "knee": "Bip01 {s} Calf", "ankle": "Bip01 {s} Foot", "toe": "Bip01 {s} Toe0",
        "clav": "Bip01 {s} Clavicle", "arm": "Bip01 {s} UpperArm", "forearm": "Bip01 {s} Forearm",
        "hand": "Bip01 {s} Hand",
    }, "L", "R"),
    # Reallusion Character Creator.
    "cc": _sided({
        "root": "CC_Base_BoneRoot", "pelvis": "CC_Base_Hip", "spine_a": "CC_Base_Waist", "spine_b": "CC_Base_Spine01",
        "spine_c": "CC_Base_Spine02", "neck": "CC_Base_NeckTwist01", "neck_b": "CC_Base_NeckTwist02",
        "head": "CC_Base_Head", "eye": "CC_Base_{s}_Eye", "hipside": "CC_Base_{s}_Hip0", "thigh": "CC_Base_{s}_Thigh",
        "knee": "CC_Base_{s}_Calf", "ankle": "CC_Base_{s}_Foot", "toe": "CC_Base_{s}_ToeBase",
        "clav": "CC_Base_{s}_Clavicle", "arm": "CC_Base_{s}_Upperarm", "forearm": "CC_Base_{s}_Forearm",
        "hand": "CC_Base_{s}_Hand",
    }, "L", "R"),
    # VRoid / VRM.
    "vroid": _sided({
        "root": "Root", "pelvis": "J_Bip_C_Hips", "spine_a": "J_Bip_C_Spine", "spine_b": "J_Bip_C_Chest",
        "spine_c": "J_Bip_C_UpperChest", "neck": "J_Bip_C_Neck", "head": "J_Bip_C_Head", "eye": "J_Adj_{s}_FaceEye",
        "thigh": "J_Bip_{s}_UpperLeg", "knee": "J_Bip_{s}_LowerLeg", "ankle": "J_Bip_{s}_Foot",
        "toe": "J_Bip_{s}_ToeBase", "clav": "J_Bip_{s}_Shoulder", "arm": "J_Bip_{s}_UpperArm",
        "forearm": "J_Bip_{s}_LowerArm", "hand": "J_Bip_{s}_Hand",
    }, "L", "R"),
    # DAZ Genesis: camelCase, a side letter glued to the front.
    "daz": _sided({
        "pelvis": "hip", "spine_a": "abdomenLower", "spine_b": "abdomenUpper", "spine_c": "chestLower",
        "neck": "neckLower", "neck_b": "neckUpper", "head": "head", "eye": "{s}Eye", "thigh": "{s}ThighBend",
        "knee": "{s}Shin", "ankle": "{s}Foot", "toe": "{s}Toe", "clav": "{s}Collar", "arm": "{s}ShldrBend",
        "forearm": "{s}ForearmBend", "hand": "{s}Hand",
    }, "l", "r"),
    # Maya AdvancedSkeleton: no name says pelvis ("Root_M"), and "Hip_L" is a thigh.
    "advanced": _sided({
        "pelvis": "Root_M", "spine_a": "Spine1_M", "spine_b": "Spine2_M", "spine_c": "Chest_M", "neck": "Neck_M",
        "head": "Head_M", "head_end": "HeadEnd_M", "eye": "Eye_{s}", "thigh": "Hip_{s}", "knee": "Knee_{s}",
        "ankle": "Ankle_{s}", "toe": "Toes_{s}", "clav": "Scapula_{s}", "arm": "Shoulder_{s}", "forearm": "Elbow_{s}",
        "hand": "Wrist_{s}",
    }, "L", "R"),
    # Maya's naming: a side or centre prefix (C_, L_, R_) and a _jnt suffix around a camelCase word.
    "maya": _sided({
        "root": "C_root_jnt", "pelvis": "C_pelvis_jnt", "spine_a": "C_spine01_jnt", "spine_b": "C_spine02_jnt",
        "spine_c": "C_chest_jnt", "neck": "C_neck01_jnt", "head": "C_head_jnt", "head_end": "C_headEnd_jnt",
        "eye": "{s}_eye_jnt", "thigh": "{s}_hip_jnt", "knee": "{s}_knee_jnt", "ankle": "{s}_ankle_jnt",
        "toe": "{s}_ball_jnt", "toe_end": "{s}_toeEnd_jnt", "clav": "{s}_clavicle_jnt", "arm": "{s}_shoulder_jnt",
        "forearm": "{s}_elbow_jnt", "hand": "{s}_wrist_jnt",
    }, "L", "R"),
    # A quadruped (use with body="quadruped"): Blender-style .L/.R, spine and neck numbered.
    "quadruped": _sided({
        "root": "root", "pelvis": "Pelvis", "spine_a": "Spine.001", "spine_b": "Spine.002", "spine_c": "Spine.003",
        "neck": "Neck.001", "neck_b": "Neck.002", "head": "Head", "head_end": "Head.end", "eye": "Eye.{s}",
        "thigh": "BackThigh.{s}", "knee": "BackShin.{s}", "ankle": "BackFoot.{s}", "toe": "BackToe.{s}",
        "clav": "FrontShoulder.{s}", "arm": "FrontUpperLeg.{s}", "forearm": "FrontLowerLeg.{s}",
        "hand": "FrontFoot.{s}",
    }, "L", "R"),
}
SCHEMES["numbered"] = {k: "j{i}" for k in SCHEMES["cc"]}
"""No name says anything: ``j0`` ... ``jN`` (bind it with --bind and --forward)."""

# A dog-sized quadruped (character frame: X left, Y up, Z forward, metres): the spine runs
# horizontally from the hind legs to the front legs, the neck rises forward, the head looks ahead.
QUADRUPED = {
    "root": (None, (0.0, 0.0, 0.0)),
    "pelvis": ("root", (0.0, 0.60, -0.35)),
    "spine_a": ("pelvis", (0.0, 0.61, -0.20)),
    "spine_b": ("spine_a", (0.0, 0.62, -0.05)),
    "spine_c": ("spine_b", (0.0, 0.62, 0.10)),
    "neck": ("spine_c", (0.0, 0.68, 0.22)),
    "neck_b": ("neck", (0.0, 0.74, 0.30)),
    "head": ("neck_b", (0.0, 0.80, 0.36)),
    "head_end": ("head", (0.0, 0.82, 0.52)),
    "eye_l": ("head", (0.03, 0.84, 0.44)),
    "eye_r": ("head", (-0.03, 0.84, 0.44)),
}
for _s, _x in (("l", 1.0), ("r", -1.0)):
    QUADRUPED.update({
        f"hipside_{_s}": ("pelvis", (_x * 0.05, 0.60, -0.34)),
        f"thigh_{_s}": ("pelvis", (_x * 0.08, 0.56, -0.36)),
        f"knee_{_s}": (f"thigh_{_s}", (_x * 0.08, 0.36, -0.30)),
        f"ankle_{_s}": (f"knee_{_s}", (_x * 0.08, 0.16, -0.38)),
        f"toe_{_s}": (f"ankle_{_s}", (_x * 0.08, 0.02, -0.34)),
        f"toe_end_{_s}": (f"toe_{_s}", (_x * 0.08, 0.0, -0.28)),
        f"clav_{_s}": ("spine_c", (_x * 0.05, 0.58, 0.10)),
        f"arm_{_s}": (f"clav_{_s}", (_x * 0.08, 0.50, 0.12)),
        f"forearm_{_s}": (f"arm_{_s}", (_x * 0.08, 0.30, 0.12)),
        f"hand_{_s}": (f"forearm_{_s}", (_x * 0.08, 0.05, 0.12)),
    })
