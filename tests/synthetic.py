"""Synthetic UsdSkel stages for tests and benchmarks: real SkelRoot > Skeleton > SkelAnimation files.

Authored at the Sdf level (one ``Sdf.ChangeBlock``, ``Vt.*Array.FromNumpy`` per time sample), so a
100-joint x 20,000-frame animation is written in a few seconds. Nothing here uses usdgaze: the
rig's geometry, rest pose and motion are built with scipy's rotations from a template in the
character frame (X left, Y up, Z forward, metres) and mapped into skeleton space.

What real exports look like, and so what this makes:

* joint tokens are valid USD path elements, because UsdSkel parses them as paths (a token such as
  ``mixamorig:Hips`` or ``DEF-spine.001`` is not one: UsdSkel reads it as a root joint). Exporters
  replace the characters, so Mixamo's ``mixamorig:Hips`` is written ``mixamorig_Hips`` and Rigify's
  ``DEF-spine.001`` ``DEF_spine_001``; the DCC names go into the Skeleton's ``jointNames``;
* joint-local frames are bone-aligned (local +Y along the bone, a roll about it), so no joint's
  local axes line up with the world, while the character faces a known forward;
* the animation may list its joints in another order than the skeleton, and leave some out.

Use :func:`make_rig` (one call, one file) and the returned :class:`Rig` for the paths and names a
test needs.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Vt
from scipy.spatial.transform import Rotation as R

from .synthetic_names import QUADRUPED, SCHEMES

# -- the template ---------------------------------------------------------------------------------
# key: (parent key, position in the character frame, metres: X left, Y up, Z forward)
_BODY = {
    "root": (None, (0.0, 0.0, 0.0)),
    "pelvis": ("root", (0.0, 0.98, 0.0)),
    "spine_a": ("pelvis", (0.0, 1.08, 0.01)),
    "spine_b": ("spine_a", (0.0, 1.20, 0.0)),
    "spine_c": ("spine_b", (0.0, 1.33, -0.01)),
    "neck": ("spine_c", (0.0, 1.48, 0.0)),
    "neck_b": ("neck", (0.0, 1.54, 0.01)),
    "head": ("neck_b", (0.0, 1.60, 0.02)),
    "head_end": ("head", (0.0, 1.80, 0.03)),
    "eye_l": ("head", (0.032, 1.68, 0.10)),
    "eye_r": ("head", (-0.032, 1.68, 0.10)),
}
for _s, _x in (("l", 1.0), ("r", -1.0)):
    _BODY.update({
        f"hipside_{_s}": ("pelvis", (_x * 0.06, 0.98, 0.03)),
        f"thigh_{_s}": ("pelvis", (_x * 0.09, 0.93, 0.0)),
        f"knee_{_s}": (f"thigh_{_s}", (_x * 0.09, 0.50, 0.01)),
        f"ankle_{_s}": (f"knee_{_s}", (_x * 0.09, 0.08, -0.03)),
        f"toe_{_s}": (f"ankle_{_s}", (_x * 0.09, 0.02, 0.10)),
        f"toe_end_{_s}": (f"toe_{_s}", (_x * 0.09, 0.0, 0.17)),
        f"clav_{_s}": ("spine_c", (_x * 0.03, 1.42, 0.02)),
        f"arm_{_s}": (f"clav_{_s}", (_x * 0.17, 1.42, -0.01)),
        f"forearm_{_s}": (f"arm_{_s}", (_x * 0.44, 1.42, -0.02)),
        f"hand_{_s}": (f"forearm_{_s}", (_x * 0.68, 1.42, 0.0)),
    })
FINGERS = ("thumb", "index", "middle", "ring", "pinky")

_MIXAMO = {
    "pelvis": "Hips", "spine_a": "Spine", "spine_b": "Spine1", "spine_c": "Spine2", "neck": "Neck",
    "head": "Head", "head_end": "HeadTop_End", "eye_l": "LeftEye", "eye_r": "RightEye",
}
_UE = {"root": "root", "pelvis": "pelvis", "spine_a": "spine_01", "spine_b": "spine_02", "spine_c": "spine_03",
       "neck": "neck_01", "head": "head", "eye_l": "FACIAL_L_Eye", "eye_r": "FACIAL_R_Eye"}
_RIGIFY = {"pelvis": "DEF-spine", "spine_a": "DEF-spine.001", "spine_b": "DEF-spine.002", "spine_c": "DEF-spine.003",
           "neck": "DEF-spine.004", "neck_b": "DEF-spine.005", "head": "DEF-spine.006",
           "eye_l": "DEF-eye.L", "eye_r": "DEF-eye.R"}
for _s, _side in (("l", "Left"), ("r", "Right")):
    _MIXAMO.update({f"thigh_{_s}": f"{_side}UpLeg", f"knee_{_s}": f"{_side}Leg", f"ankle_{_s}": f"{_side}Foot",
                    f"toe_{_s}": f"{_side}ToeBase", f"toe_end_{_s}": f"{_side}Toe_End", f"clav_{_s}": f"{_side}Shoulder",
                    f"arm_{_s}": f"{_side}Arm", f"forearm_{_s}": f"{_side}ForeArm", f"hand_{_s}": f"{_side}Hand"})
    _UE.update({f"thigh_{_s}": f"thigh_{_s}", f"knee_{_s}": f"calf_{_s}", f"ankle_{_s}": f"foot_{_s}",
                f"toe_{_s}": f"ball_{_s}", f"clav_{_s}": f"clavicle_{_s}", f"arm_{_s}": f"upperarm_{_s}",
                f"forearm_{_s}": f"lowerarm_{_s}", f"hand_{_s}": f"hand_{_s}"})
    S = _s.upper()
    _RIGIFY.update({f"hipside_{_s}": f"DEF-pelvis.{S}", f"thigh_{_s}": f"DEF-thigh.{S}", f"knee_{_s}": f"DEF-shin.{S}",
                    f"ankle_{_s}": f"DEF-foot.{S}", f"toe_{_s}": f"DEF-toe.{S}", f"clav_{_s}": f"DEF-shoulder.{S}",
                    f"arm_{_s}": f"DEF-upper_arm.{S}", f"forearm_{_s}": f"DEF-forearm.{S}", f"hand_{_s}": f"DEF-hand.{S}"})
    for _f in FINGERS:
        for _k in (1, 2, 3, 4):
            _MIXAMO[f"{_f}{_k}_{_s}"] = f"{_side}Hand{_f.capitalize()}{_k}"
        for _k in (1, 2, 3):
            _UE[f"{_f}{_k}_{_s}"] = f"{_f}_0{_k}_{_s}"
            _RIGIFY[f"{_f}{_k}_{_s}"] = f"DEF-{'thumb' if _f == 'thumb' else 'f_' + _f}.0{_k}.{S}"

CONVENTIONS = {
    # names, prefix written into the joint tokens, prefix of the DCC names (jointNames)
    "mixamo": (_MIXAMO, "mixamorig_", "mixamorig:"),
    "ue": (_UE, "", ""),
    "rigify": (_RIGIFY, "", ""),
    "generic": (None, "", ""),
    **{name: (table, "", "") for name, table in SCHEMES.items()},
}
DEFAULT_FORWARD = {
    # skeleton-space forward per (convention, up axis): Mixamo faces +Z (Y up); Blender faces -Y (Z up)
    ("mixamo", "Y"): (0.0, 0.0, 1.0), ("mixamo", "Z"): (0.0, -1.0, 0.0),
    ("ue", "Y"): (0.0, 0.0, 1.0), ("ue", "Z"): (0.0, 1.0, 0.0),
    ("rigify", "Y"): (0.0, 0.0, 1.0), ("rigify", "Z"): (0.0, -1.0, 0.0),
    ("generic", "Y"): (0.0, 0.0, 1.0), ("generic", "Z"): (0.0, -1.0, 0.0),
}


def usd_token(name: str) -> str:
    """A DCC joint name as exporters write it into a UsdSkel joint token (a valid path element)."""
    return re.sub(r"[^A-Za-z0-9_]", "_", name)


# -- result ---------------------------------------------------------------------------------------

@dataclass
class Rig:
    """What was written, with the names a test needs."""

    path: Path
    convention: str
    up_axis: str
    meters_per_unit: float
    skel_root: str
    skeleton: str
    animation: str
    mesh: str | None
    joints: list[str]
    """Skeleton joint tokens (paths), skeleton order."""
    anim_joints: list[str]
    leaf: dict[str, str]
    """Template key -> joint leaf token (``head``, ``eye_l``, ``thigh_l``, ...)."""
    forward: np.ndarray
    """Character forward in skeleton space (unit)."""
    left: np.ndarray
    up: np.ndarray
    times: np.ndarray
    time_codes_per_second: float
    frames_per_second: float
    start_time: float
    end_time: float
    has_eyes: bool
    unanimated: list[str] = field(default_factory=list)
    """Joint tokens in the skeleton but not in the animation."""

    @property
    def sample_rate(self) -> float:
        """Animation samples per second."""
        return self.time_codes_per_second / float(self.times[1] - self.times[0])

    def joint(self, key: str) -> str:
        """Full joint path of a template key."""
        return next(j for j in self.joints if j.rsplit("/", 1)[-1] == self.leaf[key])

    @property
    def chain_leaves(self) -> set[str]:
        keys = ["pelvis", "spine_a", "spine_b", "spine_c", "neck", "neck_b", "head", "eye_l", "eye_r"]
        return {self.leaf[k] for k in keys if k in self.leaf}

    @property
    def leg_root_leaves(self) -> set[str]:
        pelvis = self.joint("pelvis")
        chain = {self.joint(k) for k in ("spine_a",)}
        return {j.rsplit("/", 1)[-1] for j in self.joints if j.rsplit("/", 1)[0] == pelvis and j not in chain}

    @property
    def foot_leaves(self) -> list[str]:
        return [self.leaf[k] for k in ("ankle_l", "ankle_r", "toe_l", "toe_r", "knee_l", "knee_r", "toe_end_l", "toe_end_r")
                if k in self.leaf]

    @property
    def eye_leaves(self) -> tuple[str, str]:
        """Eye joint leaves: the rig's own, or the ones usdgaze adds under the head."""
        return (self.leaf["eye_l"], self.leaf["eye_r"]) if self.has_eyes else ("LeftEye", "RightEye")


# -- geometry -------------------------------------------------------------------------------------

def _template(convention: str, eyes, joints: int | None, body: str = "biped",
              legs_on: str = "pelvis") -> tuple[list[str], dict[str, tuple]]:
    """Template keys in skeleton order (parents first) and their (parent, position)."""
    names = CONVENTIONS[convention][0]
    body = dict(QUADRUPED if body == "quadruped" else _BODY)
    for k in ("hipside_l", "hipside_r", "thigh_l", "thigh_r"):
        body[k] = (legs_on, body[k][1])
    core = ["root", "pelvis", "spine_a", "spine_b", "spine_c", "neck", "neck_b", "head", "head_end", "eye_l", "eye_r"]
    for s in ("l", "r"):
        core += [f"hipside_{s}", f"thigh_{s}", f"knee_{s}", f"ankle_{s}", f"toe_{s}", f"toe_end_{s}"]
    for s in ("l", "r"):
        core += [f"clav_{s}", f"arm_{s}", f"forearm_{s}", f"hand_{s}"]
    keep = {k for k in core if k in (names if names is not None else _MIXAMO)}
    if eyes is False or eyes is None:
        keep -= {"eye_l", "eye_r"}
    elif eyes == "left":
        keep -= {"eye_r"}
    keys = [k for k in core if k in keep]

    # Re-parent past keys a convention lacks (no root: pelvis is the root; no neck_b: head under neck).
    def parent_of(k):
        p = body[k][0]
        while p is not None and p not in keep:
            p = body[p][0]
        return p

    spec = {k: (parent_of(k), body[k][1]) for k in keys}
    want = joints if joints is not None else len(keys)
    for f_i, finger in enumerate(FINGERS):
        for s, x in (("l", 1.0), ("r", -1.0)):
            segs = 4 if convention in ("mixamo", "generic") else 3
            parent = f"hand_{s}"
            for k in range(1, segs + 1):
                if len(keys) >= want:
                    break
                key = f"{finger}{k}_{s}"
                z = (0.04 - 0.02 * f_i) if finger != "thumb" else 0.05
                spec[key] = (parent, (x * (0.72 + 0.03 * k), 1.42 - (0.02 if finger == "thumb" else 0.0), z))
                keys.append(key)
                parent = key
    p = 0
    while len(keys) < want:
        s, x = ("l", 1.0) if p % 2 == 0 else ("r", -1.0)
        key = f"prop{p:03d}"
        spec[key] = (f"hand_{s}", (x * 0.75, 1.38 - 0.002 * p, 0.05))
        keys.append(key)
        p += 1
    return keys, spec


def _name(convention: str, key: str, index: int) -> str:
    names = CONVENTIONS[convention][0]
    if names is None:
        return f"bone_{index:03d}"
    if key.startswith("prop"):
        return {"mixamo": "Prop", "ue": "prop_", "rigify": "DEF-prop."}.get(convention, "prop_") + key[4:]
    return names[key].format(i=index)


def _bone_frames(keys, spec, pos, rng) -> R:
    """Rest rotations in skeleton space: local +Y along the bone to the first child, a random roll."""
    children = {}
    for k in keys:
        p = spec[k][0]
        if p is not None:
            children.setdefault(p, []).append(k)
    mats = []
    for i, k in enumerate(keys):
        kids = children.get(k, [])
        if kids:
            d = pos[keys.index(kids[0])] - pos[i]
        elif spec[k][0] is not None:
            d = pos[i] - pos[keys.index(spec[k][0])]
        else:
            d = np.array([0.0, 0.0, 1.0]) + 0.3
        if np.linalg.norm(d) < 1e-9:
            d = np.array([0.3, 1.0, 0.2])
        y = d / np.linalg.norm(d)
        helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        x = np.cross(y, helper)
        x /= np.linalg.norm(x)
        z = np.cross(x, y)
        roll = R.from_rotvec(y * rng.uniform(-np.pi, np.pi))
        m = roll.as_matrix() @ np.column_stack([x, y, z])
        if k.startswith("eye") or k == "root":
            m = R.random(random_state=rng).as_matrix()  # eyes: any orientation; the test reads it
        mats.append(m)
    return R.from_matrix(np.stack(mats))


# -- motion ---------------------------------------------------------------------------------------

def _motion_angles(key: str, t: np.ndarray, stride_hz: float) -> dict[str, np.ndarray]:
    """Small base rotations (radians) about character axes per joint: {'left'|'up'|'fwd': angle(t)}."""
    w = 2 * np.pi * stride_hz * t
    d = np.radians
    side = 1.0 if key.endswith("_l") else -1.0
    if key in ("spine_a", "spine_b", "spine_c"):
        return {"up": d(3.0) * np.sin(w), "fwd": d(1.5) * np.sin(w + 0.5), "left": d(1.0) * np.sin(2 * w)}
    if key in ("neck", "neck_b"):
        return {"up": d(-2.0) * np.sin(w), "left": d(1.5) * np.sin(2 * w + 1.0)}
    if key == "head":
        return {"up": d(-1.5) * np.sin(w), "left": d(2.0) * np.sin(2 * w + 0.3), "fwd": d(1.0) * np.sin(w)}
    if key.startswith("thigh"):
        return {"left": d(22.0) * side * np.sin(w)}
    if key.startswith("knee"):
        return {"left": d(-20.0) * (1.0 - np.cos(w + (0.0 if side > 0 else np.pi)))}
    if key.startswith("ankle"):
        return {"left": d(8.0) * side * np.sin(w + 0.7)}
    if key.startswith("arm"):
        return {"left": d(-15.0) * side * np.sin(w), "fwd": d(-60.0 * side) + 0 * w}
    if key.startswith("forearm"):
        return {"left": d(-10.0) * (1.0 + np.sin(w))}
    if key.startswith(FINGERS):
        return {"left": d(5.0) * (1.0 + np.sin(w + sum(map(ord, key)) % 7))}
    if key.startswith("prop"):
        return {"up": d(4.0) * np.sin(0.5 * w + int(key[4:]))}
    return {}


def make_rig(
    path: str | Path,
    convention: str = "mixamo",
    up_axis: str = "Y",
    meters_per_unit: float = 1.0,
    eyes: bool | str = True,
    joints: int | None = None,
    frames: int = 240,
    time_codes_per_second: float = 60.0,
    frames_per_second: float | None = None,
    time_step: float = 1.0,
    start_time: float = 0.0,
    forward=None,
    walk_speed: float = 1.2,
    stride_hz: float = 0.913,
    turn_deg_per_s: float = 0.0,
    animated_root: bool = False,
    shuffle_anim: bool = False,
    unanimated: tuple[str, ...] = ("prop",),
    mesh: bool = True,
    joint_names: bool = True,
    root_path: str = "/Character",
    seed: int = 7,
    body: str = "biped",
    rest_pose: str = "bind",
    look_aside_deg: tuple[float, float] = (0.0, 0.0),
    legs_on: str = "pelvis",
    root_height: float | None = None,
) -> Rig:
    """Write a SkelRoot > Skeleton (+ SkelAnimation, skinned Mesh) stage to ``path``; return its :class:`Rig`.

    ``convention``: mixamo, ue, rigify, or generic (``bone_000`` ...: no name a binder knows).
    ``eyes``: True, False, or ``"left"`` (only the left eye joint). ``joints``: pad with finger and
    prop joints up to this count (the body itself is ~25-30 joints). ``frames`` samples every
    ``time_step`` time codes from ``start_time``. ``turn_deg_per_s`` turns the whole body about up
    (its walk follows the heading); ``animated_root`` also moves and turns the SkelRoot's xform.
    The stride frequency is no divisor of common frame rates, so no two frames repeat (as in real
    capture; a periodic walk would let usdc store repeated arrays once and flatter a copy pass).
    ``shuffle_anim`` lists the animation's joints in another order than the skeleton's;
    ``unanimated`` leaves these template keys (``"prop"``: the first prop joint, if any) out of the
    animation. ``legs_on``: the template key the thighs hang from (``"root"``: beside the pelvis);
    ``root_height``: the root joint that high (metres) at rest, not on the ground, and, where the legs
    hang from it, carrying the walk (a ``Root > {Hips, LeftUpLeg, RightUpLeg}`` rig: the root is the
    hips, the pelvis below it the lower trunk).
    """
    path = Path(path)
    rng = np.random.default_rng(seed)
    names, token_prefix, name_prefix = CONVENTIONS[convention]
    units = 1.0 / meters_per_unit
    up = np.array([0.0, 0.0, 1.0]) if up_axis == "Z" else np.array([0.0, 1.0, 0.0])
    default_fwd = DEFAULT_FORWARD.get((convention, up_axis), (0.0, 0.0, 1.0) if up_axis == "Y" else (0.0, -1.0, 0.0))
    fwd = np.asarray(forward if forward is not None else default_fwd, dtype=float)
    fwd = fwd / np.linalg.norm(fwd)
    left = np.cross(up, fwd)
    canon = np.column_stack([left, up, fwd])  # character frame -> skeleton space

    keys, spec = _template(convention, eyes, joints, body, legs_on)
    if root_height is not None and "root" in spec:
        spec["root"] = (None, (0.0, float(root_height), 0.0))
    n = len(keys)
    leaf = {k: token_prefix + usd_token(_name(convention, k, i)) for i, k in enumerate(keys)}
    dcc = {k: name_prefix + _name(convention, k, i) for i, k in enumerate(keys)}
    paths = []
    for k in keys:
        p = spec[k][0]
        paths.append(leaf[k] if p is None else f"{paths[keys.index(p)]}/{leaf[k]}")
    parents = np.array([-1 if spec[k][0] is None else keys.index(spec[k][0]) for k in keys])

    pos = np.array([canon @ np.array(spec[k][1]) for k in keys]) * units
    rest_rot = _bone_frames(keys, spec, pos, rng)
    world = np.tile(np.eye(4), (n, 1, 1))
    world[:, :3, :3] = rest_rot.as_matrix()
    world[:, :3, 3] = pos
    local = world.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            local[j] = np.linalg.solve(world[p], world[j])

    # Animation: every joint's rest local transform, times a small rotation about character axes.
    times = start_time + time_step * np.arange(frames)
    t = (times - start_time) / time_codes_per_second
    f = frames
    rot_q = np.empty((f, n, 4))
    trans = np.broadcast_to(local[:, :3, 3], (f, n, 3)).copy()
    rest_local_rot = R.from_matrix(local[:, :3, :3])
    for j, k in enumerate(keys):
        angles = _motion_angles(k, t, stride_hz)
        if body == "quadruped" and k.startswith("arm"):
            angles = {"left": angles["left"]}  # front legs swing; no arms hanging down
        if any(look_aside_deg) and k in ("neck", "head"):
            angles = {**angles, "up": angles.get("up", 0.0) + np.radians(look_aside_deg[0]) / 2,
                      "left": angles.get("left", 0.0) + np.radians(look_aside_deg[1]) / 2}
        rv = np.zeros((f, 3))
        for axis, a in angles.items():
            axis_s = {"left": left, "up": up, "fwd": fwd}[axis]
            axis_local = rest_rot[j].as_matrix().T @ axis_s
            rv += np.outer(np.broadcast_to(a, (f,)), axis_local)
        rot_q[:, j] = (rest_local_rot[j] * R.from_rotvec(rv)).as_quat()

    # Pelvis: walk along the heading, turn, bob and sway (skeleton space, then into its parent).
    pj = keys.index("root" if legs_on == "root" and root_height is not None else "pelvis")
    heading = np.radians(turn_deg_per_s) * t
    dt = np.diff(t, prepend=t[0])
    step = walk_speed * units * dt
    direction = np.cos(heading)[:, None] * fwd + np.sin(heading)[:, None] * left
    travel = np.cumsum(step[:, None] * direction, axis=0)
    w = 2 * np.pi * stride_hz * t
    bob = 0.02 * units * np.cos(2 * w)[:, None] * up
    pelvis_pos = pos[pj] + travel + bob
    sway = R.from_rotvec(np.outer(np.radians(4.0) * np.sin(w), up) + np.outer(np.radians(2.0) * np.sin(w), fwd)
                         + np.outer(np.radians(1.5) * np.sin(2 * w), left))
    pelvis_world = R.from_rotvec(np.outer(heading, up)) * sway * rest_rot[pj]
    par = parents[pj]
    if par >= 0:
        inv_par = np.linalg.inv(world[par])
        rot_q[:, pj] = (R.from_matrix(inv_par[:3, :3]) * pelvis_world).as_quat()
        trans[:, pj] = pelvis_pos @ inv_par[:3, :3].T + inv_par[:3, 3]
    else:
        rot_q[:, pj] = pelvis_world.as_quat()
        trans[:, pj] = pelvis_pos
    scales = np.ones((f, n, 3), dtype=np.float16)

    rest_local = local.copy()
    if rest_pose == "first_frame":
        rest_local[:, :3, :3] = R.from_quat(rot_q[0]).as_matrix()
        rest_local[:, :3, 3] = trans[0]

    # Which joints the animation lists, and in which order.
    drop = set()
    for u in unanimated:
        if u == "prop":
            drop |= {j for j, k in enumerate(keys) if k == "prop000"}
        elif u in keys:
            drop.add(keys.index(u))
    order = [j for j in range(n) if j not in drop]
    if shuffle_anim:
        order = list(rng.permutation(order))
    rot_q = np.ascontiguousarray(rot_q[:, order], dtype=np.float32)
    trans = np.ascontiguousarray(trans[:, order], dtype=np.float32)
    scales = np.ascontiguousarray(scales[:, order])

    # -- author ------------------------------------------------------------------------------------
    skel_root = root_path
    skeleton = f"{root_path}/Skel"
    animation = f"{root_path}/Anim"
    mesh_path = f"{root_path}/Body" if mesh else None
    layer = Sdf.Layer.CreateAnonymous("synthetic" + path.suffix)
    tv = Sdf.ValueTypeNames
    with Sdf.ChangeBlock():
        layer.timeCodesPerSecond = time_codes_per_second
        layer.framesPerSecond = frames_per_second if frames_per_second is not None else time_codes_per_second / time_step
        layer.startTimeCode = float(times[0])
        layer.endTimeCode = float(times[-1])
        layer.pseudoRoot.SetInfo("upAxis", up_axis)
        layer.pseudoRoot.SetInfo("metersPerUnit", float(meters_per_unit))
        layer.defaultPrim = Sdf.Path(root_path).name

        root = _prim(layer, skel_root, "SkelRoot")
        if animated_root:
            # Walk the character around the stage: translate, then turn about up.
            x = 0.4 * units * np.sin(0.3 * 2 * np.pi * t)
            y = 0.2 * units * t
            tr = np.column_stack([x, np.zeros(f), y]) if up_axis == "Y" else np.column_stack([x, y, np.zeros(f)])
            angle = 30.0 + 25.0 * t
            a_t = _attr(root, "xformOp:translate", tv.Double3)
            a_r = _attr(root, f"xformOp:rotate{up_axis}", tv.Float)
            for i, tc in enumerate(times):
                layer.SetTimeSample(a_t.path, float(tc), Gf.Vec3d(*tr[i]))
                layer.SetTimeSample(a_r.path, float(tc), float(angle[i]))
            _attr(root, "xformOpOrder", tv.TokenArray, uniform=True).default = Vt.TokenArray(
                ["xformOp:translate", f"xformOp:rotate{up_axis}"])

        skel = _prim(layer, skeleton, "Skeleton", api=["SkelBindingAPI"])
        _attr(skel, "joints", tv.TokenArray, uniform=True).default = Vt.TokenArray(paths)
        if joint_names and names is not None:
            _attr(skel, "jointNames", tv.TokenArray, uniform=True).default = Vt.TokenArray([dcc[k] for k in keys])
        _attr(skel, "restTransforms", tv.Matrix4dArray, uniform=True).default = _matrices(rest_local)
        _attr(skel, "bindTransforms", tv.Matrix4dArray, uniform=True).default = _matrices(world)
        rel = Sdf.RelationshipSpec(skel, "skel:animationSource", False)
        rel.targetPathList.explicitItems = [Sdf.Path(animation)]

        anim = _prim(layer, animation, "SkelAnimation")
        _attr(anim, "joints", tv.TokenArray, uniform=True).default = Vt.TokenArray([paths[j] for j in order])
        for name, type_name, values, vt in (("rotations", tv.QuatfArray, rot_q, Vt.QuatfArray),
                                            ("translations", tv.Float3Array, trans, Vt.Vec3fArray),
                                            ("scales", tv.Half3Array, scales, Vt.Vec3hArray)):
            attr_path = _attr(anim, name, type_name).path
            for i, tc in enumerate(times):
                layer.SetTimeSample(attr_path, float(tc), vt.FromNumpy(values[i]))

        if mesh:
            body = _prim(layer, mesh_path, "Mesh", api=["SkelBindingAPI"])
            size = 0.02 * units
            corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float) * size
            points = (pos[:, None, :] + corners[None]).reshape(-1, 3)
            _attr(body, "points", tv.Point3fArray).default = Vt.Vec3fArray.FromNumpy(points.astype(np.float32))
            _attr(body, "faceVertexCounts", tv.IntArray).default = Vt.IntArray([4] * n)
            _attr(body, "faceVertexIndices", tv.IntArray).default = Vt.IntArray(list(range(4 * n)))
            lo, hi = points.min(0), points.max(0)
            _attr(body, "extent", tv.Float3Array).default = Vt.Vec3fArray([Gf.Vec3f(*lo), Gf.Vec3f(*hi)])
            # Two influences per point: its own joint (0.75) and that joint's parent (0.25).
            idx = np.stack([np.arange(n), np.where(parents >= 0, parents, np.arange(n))], axis=1)
            idx = np.repeat(idx, 4, axis=0).reshape(-1)
            wts = np.tile([0.75, 0.25], 4 * n)
            ji = _attr(body, "primvars:skel:jointIndices", tv.IntArray)
            ji.default = Vt.IntArray.FromNumpy(idx.astype(np.int32))
            jw = _attr(body, "primvars:skel:jointWeights", tv.FloatArray)
            jw.default = Vt.FloatArray.FromNumpy(wts.astype(np.float32))
            for a in (ji, jw):
                a.SetInfo("interpolation", "vertex")
                a.SetInfo("elementSize", 2)
            _attr(body, "primvars:skel:geomBindTransform", tv.Matrix4d).default = Gf.Matrix4d(1)
            srel = Sdf.RelationshipSpec(body, "skel:skeleton", False)
            srel.targetPathList.explicitItems = [Sdf.Path(skeleton)]
    path.parent.mkdir(parents=True, exist_ok=True)
    if not layer.Export(str(path)):
        raise RuntimeError(f"could not write {path}")

    return Rig(
        path=path, convention=convention, up_axis=up_axis, meters_per_unit=meters_per_unit,
        skel_root=skel_root, skeleton=skeleton, animation=animation, mesh=mesh_path,
        joints=paths, anim_joints=[paths[j] for j in order], leaf=leaf,
        forward=fwd, left=left, up=up, times=times, time_codes_per_second=time_codes_per_second,
        frames_per_second=layer.framesPerSecond, start_time=float(times[0]), end_time=float(times[-1]),
        has_eyes=bool(eyes is True and "eye_l" in leaf and "eye_r" in leaf),
        unanimated=[paths[j] for j in sorted(drop)],
    )


def _prim(layer: Sdf.Layer, path: str, type_name: str, api: list[str] | None = None) -> Sdf.PrimSpec:
    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierDef
    spec.typeName = type_name
    if api:
        op = Sdf.TokenListOp()
        op.prependedItems = api
        spec.SetInfo("apiSchemas", op)
    # Ancestors CreatePrimInLayer made are overs: make them defs (plain Xforms).
    parent = spec.nameParent
    while parent and parent.path != Sdf.Path.absoluteRootPath:
        if parent.specifier != Sdf.SpecifierDef:
            parent.specifier = Sdf.SpecifierDef
            parent.typeName = "Xform"
        parent = parent.nameParent
    return spec


def _attr(prim: Sdf.PrimSpec, name: str, type_name, uniform: bool = False) -> Sdf.AttributeSpec:
    if name in prim.attributes:
        return prim.attributes[name]
    return Sdf.AttributeSpec(prim, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)


def _matrices(m: np.ndarray) -> Vt.Matrix4dArray:
    """Column-vector 4x4 stacks -> USD's row-vector Matrix4dArray."""
    return Vt.Matrix4dArray.FromNumpy(np.ascontiguousarray(np.transpose(m, (0, 2, 1))))


def edit(path: str | Path, fn) -> None:
    """Open the layer at ``path``, let ``fn(layer)`` change it, save it (for bad-input fixtures)."""
    layer = Sdf.Layer.FindOrOpen(str(path))
    fn(layer)
    layer.Save()
