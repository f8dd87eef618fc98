"""Rig conventions from studio DCCs that the synthetic rigs do not make, measured with UsdSkel FK:
a head-named twist joint, squash and stretch, joints mirrored by a negative scale.

A twist or roll joint named after the head between the neck and the head (``head_roll``,
``mixamorig:HeadTwist``, ``Head_Roll_JNT``): the head is the joint the eyes hang from, not the
head-named helper above it. Bound to the helper, the pass aimed the eyes along the helper's forward,
so the real head's own nod and turn (which the base motion's eyes follow) were cancelled from the
first frame on: the line of sight moved by the head's own motion before any directive (1.5-2 deg on
a 2 deg head sway; 10 deg here) and a shift held off its request by as much.

The stage is written here with pxr and numpy (bone frames in the skeleton, eye joints whose local
+Y looks ahead); every number is measured with UsdSkel's forward kinematics on the composed result
(tests/measure.py), head and eye axes from the bind pose.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Vt
from scipy.spatial.transform import Rotation as R

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.console.main import main

from . import measure
from . import synthetic as syn

RATE, FRAMES, SHIFT_S, HOLD_S = 30.0, 60, 0.2, 1.5

# key: (parent, position at bind in metres, X left, Y up, Z forward)
_BODY = {
    "root": (None, (0.0, 0.0, 0.0)),
    "pelvis": ("root", (0.0, 0.95, 0.0)),
    "spine_01": ("pelvis", (0.0, 1.10, 0.0)),
    "spine_02": ("spine_01", (0.0, 1.28, 0.0)),
    "neck_01": ("spine_02", (0.0, 1.48, 0.0)),
    "twist": ("neck_01", (0.0, 1.56, 0.01)),
    "head": ("twist", (0.0, 1.62, 0.02)),
    "eye_l": ("head", (0.032, 1.70, 0.10)),
    "eye_r": ("head", (-0.032, 1.70, 0.10)),
    "thigh_l": ("pelvis", (0.09, 0.92, 0.0)),
    "calf_l": ("thigh_l", (0.09, 0.50, 0.0)),
    "thigh_r": ("pelvis", (-0.09, 0.92, 0.0)),
    "calf_r": ("thigh_r", (-0.09, 0.50, 0.0)),
}


def _write(path, twist_name: str = "neck_02", scale: dict | None = None, squash: dict | None = None
           ) -> tuple[str, dict[str, str]]:
    """The rig; ``scale``: a joint's own (local) scale in the bind pose, which its children inherit (a
    negative one mirrors it); ``squash``: a joint's scale animated about that, (x, y, z) amplitudes."""
    scale, squash = scale or {}, squash or {}
    keys = list(_BODY)
    leaf = {k: (twist_name if k == "twist" else k) for k in keys}
    parents = [keys.index(_BODY[k][0]) if _BODY[k][0] else -1 for k in keys]
    paths: list[str] = []
    for i, k in enumerate(keys):
        paths.append(leaf[k] if parents[i] < 0 else f"{paths[parents[i]]}/{leaf[k]}")
    rng = np.random.default_rng(5)
    world = np.tile(np.eye(4), (len(keys), 1, 1))
    for i, k in enumerate(keys):
        world[i, :3, 3] = _BODY[k][1]
        # Bone frames: a random roll for the body, eyes whose local +Y looks ahead (+Z).
        world[i, :3, :3] = (R.from_euler("x", -90, degrees=True) if k.startswith("eye")
                            else R.from_rotvec([0.0, rng.uniform(-3, 3), 0.0])).as_matrix()
    local = world.copy()
    for i, p in enumerate(parents):
        if p >= 0:
            local[i] = np.linalg.solve(world[p], world[i])
    rigid = local.copy()
    own = np.array([scale.get(k, (1.0, 1.0, 1.0)) for k in keys], dtype=float)
    local[:, :3, :3] = rigid[:, :3, :3] * own[:, None, :]
    for i, p in enumerate(parents):  # the bind pose as UsdSkel composes the scaled locals
        world[i] = local[i] if p < 0 else world[p] @ local[i]
    t = np.arange(FRAMES) / RATE
    rot = np.empty((FRAMES, len(keys), 4))
    for i, k in enumerate(keys):
        # The head nods (about left) and turns (about up) on its own, 10 and 6 degrees; the others sway a little.
        amp = {"head": (10.0, 6.0), "spine_01": (2.0, 3.0), "neck_01": (1.0, 2.0),
               "twist": (0.0, 1.0)}.get(k, (0.0, 0.0))
        rv_world = (np.outer(np.radians(amp[0]) * np.sin(2 * np.pi * 0.7 * t), [1.0, 0, 0])
                    + np.outer(np.radians(amp[1]) * np.sin(2 * np.pi * 0.45 * t + 0.4), [0, 1.0, 0]))
        rv_local = rv_world @ world[i, :3, :3]  # world axis -> the joint's own axes at bind
        rot[:, i] = (R.from_matrix(rigid[i, :3, :3]) * R.from_rotvec(rv_local)).as_quat()
    trans = np.broadcast_to(local[:, :3, 3], (FRAMES, len(keys), 3))
    scales = np.broadcast_to(own, (FRAMES, len(keys), 3)).copy()
    for k, amp in squash.items():
        scales[:, keys.index(k)] *= 1.0 + np.outer(np.sin(2 * np.pi * 0.5 * t), amp)
    layer = Sdf.Layer.CreateAnonymous("in.usda")
    layer.timeCodesPerSecond = layer.framesPerSecond = RATE
    layer.startTimeCode, layer.endTimeCode = 0, FRAMES - 1
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    tv = Sdf.ValueTypeNames
    root = Sdf.CreatePrimInLayer(layer, "/Char")
    root.specifier, root.typeName = Sdf.SpecifierDef, "SkelRoot"
    skel = Sdf.CreatePrimInLayer(layer, "/Char/Skel")
    skel.specifier, skel.typeName = Sdf.SpecifierDef, "Skeleton"
    schemas = Sdf.TokenListOp()
    schemas.prependedItems = ["SkelBindingAPI"]
    skel.SetInfo("apiSchemas", schemas)
    uniform = Sdf.VariabilityUniform
    usd = lambda m: Vt.Matrix4dArray.FromNumpy(np.ascontiguousarray(np.transpose(m, (0, 2, 1))))  # noqa: E731
    Sdf.AttributeSpec(skel, "joints", tv.TokenArray, uniform).default = Vt.TokenArray(paths)
    Sdf.AttributeSpec(skel, "bindTransforms", tv.Matrix4dArray, uniform).default = usd(world)
    Sdf.AttributeSpec(skel, "restTransforms", tv.Matrix4dArray, uniform).default = usd(local)
    Sdf.RelationshipSpec(skel, "skel:animationSource", False).targetPathList.explicitItems = ["/Char/Skel/Anim"]
    anim = Sdf.CreatePrimInLayer(layer, "/Char/Skel/Anim")
    anim.specifier, anim.typeName = Sdf.SpecifierDef, "SkelAnimation"
    Sdf.AttributeSpec(anim, "joints", tv.TokenArray, uniform).default = Vt.TokenArray(paths)
    for name, type_name, values, vt in (("rotations", tv.QuatfArray, rot, Vt.QuatfArray),
                                        ("translations", tv.Float3Array, trans, Vt.Vec3fArray),
                                        ("scales", tv.Half3Array, scales, Vt.Vec3hArray)):
        attr = Sdf.AttributeSpec(anim, name, type_name)
        dtype = np.float16 if name == "scales" else np.float32
        for i in range(FRAMES):
            layer.SetTimeSample(attr.path, float(i), vt.FromNumpy(np.ascontiguousarray(values[i], dtype=dtype)))
    layer.Export(str(path))
    return "/Char/Skel", leaf


@pytest.mark.parametrize("twist_name", ["head_roll", "mixamorig_HeadTwist", "Head_Roll_JNT", "neck_02"])
def test_a_head_named_twist_above_the_head_is_not_the_head(tmp_path, twist_name):
    skeleton, leaf = _write(tmp_path / "in.usda", twist_name)
    before = measure.sha256(tmp_path / "in.usda")
    api.apply(tmp_path / "in.usda", [f"{SHIFT_S}s:30:-10"], tmp_path / "gaze.usda", preview=tmp_path / "preview.usda")
    assert measure.sha256(tmp_path / "in.usda") == before
    base = measure.posed(str(tmp_path / "in.usda"), skeleton)
    new = measure.posed(str(tmp_path / "preview.usda"), skeleton)
    fwd = measure.character_forward_skel(base, "thigh_l", "thigh_r")
    change, _, _ = measure.gaze_change(base, new, fwd, "head", ("eye_l", "eye_r"))
    seconds = base.times / RATE
    before_shift = np.abs(change[seconds < SHIFT_S]).max()
    held = np.abs(change[seconds >= HOLD_S] - [30.0, -10.0]).max()
    # Before the shift the gaze is the base motion's; once it settles, the request within 0.5 deg.
    assert before_shift < 0.05, (twist_name, before_shift)
    assert held < 0.5, (twist_name, held)


def _gaze(tmp_path, skeleton, *directives, look_at=None):
    before = measure.sha256(tmp_path / "in.usda")
    api.apply(tmp_path / "in.usda", list(directives), tmp_path / "gaze.usda", preview=tmp_path / "preview.usda",
              look_at=look_at or [])
    assert measure.sha256(tmp_path / "in.usda") == before
    return measure.posed(str(tmp_path / "in.usda"), skeleton), measure.posed(str(tmp_path / "preview.usda"), skeleton)


@pytest.mark.parametrize("scale, squash", [
    ({"head": (1.0, 1.3, 0.9)}, {}),  # a head modelled stretched
    ({}, {"head": (-0.1, 0.2, -0.1)}),  # squash and stretch, animated
    ({}, {"neck_01": (-0.1, 0.2, -0.1)}),  # on the neck
])
def test_eyes_in_a_squashed_and_stretched_head_aim_where_asked(tmp_path, scale, squash):
    """The eyes turn in a scaled socket: aimed through the head's rotation alone, the gaze here moved
    0.07 deg before any directive (the stretched head) and held 2.8 and 2.7 deg off the shift (the
    squashes); on the rigs of a sweep, look-at targets were missed by up to 8.6 deg."""
    skeleton, _ = _write(tmp_path / "in.usda", scale=scale, squash=squash)
    base, new = _gaze(tmp_path, skeleton, f"{SHIFT_S}s:30:-10")
    fwd = measure.character_forward_skel(base, "thigh_l", "thigh_r")
    change, _, _ = measure.gaze_change(base, new, fwd, "head", ("eye_l", "eye_r"))
    seconds = base.times / RATE
    assert np.abs(change[seconds < SHIFT_S]).max() < 0.05
    assert np.abs(change[seconds >= HOLD_S] - [30.0, -10.0]).max() < 0.5

    base_eyes = 0.5 * (base.position("eye_l") + base.position("eye_r"))[0]
    target = base_eyes + 1.2 * fwd + 0.4 * np.cross([0.0, 1.0, 0.0], fwd) - [0.0, 0.25, 0.0]
    _, new = _gaze(tmp_path, skeleton, look_at=[f"{target[0]:.5f},{target[1]:.5f},{target[2]:.5f}@{SHIFT_S}s"])
    for eye in ("eye_l", "eye_r"):
        miss = measure.eye_miss_deg(new, eye, fwd, target)
        assert miss[seconds >= HOLD_S].max() < 0.5, (eye, miss[seconds >= HOLD_S].max())


@pytest.mark.parametrize("mirrored", ["eye_r", "thigh_r"])
def test_a_joint_mirrored_off_the_chain_is_carried(tmp_path, mirrored):
    """A negative scale mirrors one side of some rigs: the command stopped with an internal error
    (exit 1) on any such joint, a leg or an eye included."""
    skeleton, _ = _write(tmp_path / "in.usda", scale={mirrored: (-1.0, 1.0, 1.0)})
    base, new = _gaze(tmp_path, skeleton, f"{SHIFT_S}s:30:-10")
    fwd = measure.character_forward_skel(base, "thigh_l", "thigh_r")
    change, _, _ = measure.gaze_change(base, new, fwd, "head", ("eye_l", "eye_r"))
    assert np.abs(change[base.times / RATE >= HOLD_S] - [30.0, -10.0]).max() < 0.5


def test_a_mirrored_chain_is_refused_in_one_line(tmp_path, capsys):
    _write(tmp_path / "in.usda", scale={"root": (-1.0, 1.0, 1.0)})
    assert main(["apply", str(tmp_path / "in.usda"), "--shift", "0.2s:30:0", "--out", str(tmp_path / "gaze.usda")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "joint 'root' of the gaze chain is mirrored" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda"]


def _on_a_tilted_parent(tmp_path, tilt: float):
    """A standing rig under ``/World`` pitched ``tilt`` degrees about X; the rig and its base pose."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=96, time_codes_per_second=24, walk_speed=0.0, mesh=False,
                       root_path="/World/Character")
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    world = layer.GetPrimAtPath("/World")
    world.typeName = "Xform"
    Sdf.AttributeSpec(world, "xformOp:rotateX", Sdf.ValueTypeNames.Double).default = tilt
    Sdf.AttributeSpec(world, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:rotateX"])
    layer.Save()
    return rig, measure.posed(str(rig.path), rig.skeleton)


def _look_miss(tmp_path, rig, target: np.ndarray, name: str = "gaze") -> np.ndarray:
    """``apply --look-at target@12``; the line of sight's miss by UsdSkel FK from time code 48 on,
    the eyes' axes the rig's own forward in skeleton space."""
    preview = tmp_path / f"{name}_preview.usda"
    assert main(["apply", str(rig.path), "--look-at", ",".join(f"{v:.5f}" for v in target) + "@12",
                 "--out", str(tmp_path / f"{name}.usdc"), "--preview", str(preview)]) == 0
    new = measure.posed(str(preview), rig.skeleton)
    left, right = rig.eye_leaves
    line = measure.sight_line(new, left, right, measure.local_forward(new, left, rig.forward),
                              measure.local_forward(new, right, rig.forward))
    goal = target - 0.5 * (new.position(left) + new.position(right))
    goal /= np.linalg.norm(goal, axis=1, keepdims=True)
    return measure.angle_between(line, goal)[new.times >= 48]


@pytest.mark.parametrize("tilt", [10.0, 20.0])
def test_a_character_on_a_slope_looks_at_its_target(tmp_path, tilt):
    """Its parent pitched ``tilt`` degrees, the character is upright in its own space: its eyes'
    modelled axis (the bind pose's forward) lands on a look-at target (it missed by the tilt)."""
    rig, base = _on_a_tilted_parent(tmp_path, tilt)
    left, right = rig.eye_leaves
    target = 0.5 * (base.position(left) + base.position(right))[0] + np.array([1.0, 0.3, 1.5])
    assert _look_miss(tmp_path, rig, target).max() < 1.0


@pytest.mark.parametrize("tilt", [60.0, 90.0, -90.0])
def test_a_character_leaning_or_lying_looks_at_its_target(tmp_path, capsys, tilt):
    """Its parent pitched 60 deg (past the 30 deg snap onto a skeleton axis), or lying face down or on
    its back: the forward, left x the stage's up, was off the face's by the lean, and flat the stage's
    up is the line of sight, about which every azimuth is a roll: look-at targets beside and ahead of
    the face were missed by 45-90 deg by UsdSkel FK, unsaid. The legs say the character stands along
    its skeleton's +Y; it is taken upright there (said), azimuths about its own up."""
    rig, base = _on_a_tilted_parent(tmp_path, tilt)
    left, right = rig.eye_leaves
    eyes = 0.5 * (base.position(left) + base.position(right))[0]
    face = base.axis(left, measure.local_forward(base, left, rig.forward))[0]
    for i, target in enumerate([eyes + 1.5 * face + 0.8 * rig.left, eyes + 1.5 * rig.left + 0.5 * face]):
        assert _look_miss(tmp_path, rig, target, f"gaze{i}").max() < 1.0, (i, tilt)
        assert f"{abs(tilt):.1f} deg off the skeleton's +Y axis" in capsys.readouterr().err


def _tilt_skeleton_space(path, rig, tilt: float) -> None:
    """Rotate the Skeleton prim ``tilt`` degrees about X and counter-rotate its joints in skeleton
    space (bind, rest and animated root), so the character stands exactly where it stood: only the
    skeleton's own space is tilted from the world (row vectors: new = old @ X^-1)."""
    from pxr import Gf

    x_inv = np.eye(4)
    x_inv[:3, :3] = R.from_euler("x", tilt, degrees=True).as_matrix()  # row-vector inverse of rotateX(tilt)
    layer = Sdf.Layer.FindOrOpen(str(path))
    skel = layer.GetPrimAtPath(rig.skeleton)
    Sdf.AttributeSpec(skel, "xformOp:rotateX", Sdf.ValueTypeNames.Double).default = tilt
    Sdf.AttributeSpec(skel, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:rotateX"])
    bind = skel.attributes["bindTransforms"]
    bind.default = Vt.Matrix4dArray([Gf.Matrix4d(*(np.array(m) @ x_inv).ravel()) for m in bind.default])
    rest = skel.attributes["restTransforms"]
    rest_m = [np.array(m) for m in rest.default]
    root = rig.joints.index(next(j for j in rig.joints if "/" not in j))
    rest_m[root] = rest_m[root] @ x_inv
    rest.default = Vt.Matrix4dArray([Gf.Matrix4d(*m.ravel()) for m in rest_m])
    anim = layer.GetPrimAtPath(rig.animation)
    a_root = list(anim.attributes["joints"].default).index(rig.joints[root])
    rot_path = anim.attributes["rotations"].path
    pos_path = anim.attributes["translations"].path
    for t in layer.ListTimeSamplesForPath(rot_path):
        q = np.array([[v.imaginary[0], v.imaginary[1], v.imaginary[2], v.real]
                      for v in layer.QueryTimeSample(rot_path, t)])
        p = np.array(layer.QueryTimeSample(pos_path, t), dtype=float)
        m = np.eye(4)
        m[:3, :3], m[3, :3] = R.from_quat(q[a_root]).as_matrix().T, p[a_root]  # row vectors
        m = m @ x_inv
        q[a_root] = R.from_matrix(m[:3, :3].T).as_quat()
        p[a_root] = m[3, :3]
        layer.SetTimeSample(rot_path, t, Vt.QuatfArray([Gf.Quatf(float(w), float(x), float(y), float(z))
                                                        for x, y, z, w in q]))
        layer.SetTimeSample(pos_path, t, Vt.Vec3fArray.FromNumpy(p.astype(np.float32)))
    layer.Save()


def test_a_skeleton_space_tilted_from_the_world_is_said_and_its_forward_honoured(tmp_path, capsys):
    """The Skeleton prim rotated 25 deg and its joints counter-rotated: the character stands upright in
    the world, its skeleton's space does not. Nothing in the skeleton tells that from a character on a
    slope (which the stage's up, snapped to the skeleton's axis, is right for), so the pass takes the
    slope's reading, and its eyes missed a 40 deg shift by 7 deg with "hold error 0.000 deg". The
    report now says so with the forward that reads it as upright in the world; given, the eyes land
    on a look-at target."""
    tilt = 25.0
    rig = syn.make_rig(tmp_path / "in.usda", frames=96, time_codes_per_second=24, walk_speed=0.0, mesh=False,
                       root_path="/World/Character")
    before = measure.posed(str(rig.path), rig.skeleton)
    _tilt_skeleton_space(rig.path, rig, tilt)
    base = measure.posed(str(rig.path), rig.skeleton)
    assert np.abs(base.world - before.world).max() < 1e-4  # the character stands where it stood
    forward_skel = R.from_euler("x", -tilt, degrees=True).apply(rig.forward)  # the world's forward, in skeleton space

    assert main(["apply", str(rig.path), "--shift", "1s:40:0", "--out", str(tmp_path / "plain.usdc")]) == 0
    err = capsys.readouterr().err
    assert "25.0 deg off the skeleton's +Y axis" in err, err
    given = np.array([float(v) for v in err.split("give --forward ")[1].split()[0].split(",")])
    assert np.abs(given - forward_skel).max() < 1e-3, given

    left, right = rig.eye_leaves
    target = 0.5 * (base.position(left) + base.position(right))[0] + np.array([1.0, 0.3, 1.5])
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--look-at", ",".join(f"{v:.5f}" for v in target) + "@12",
                 "--forward", ",".join(f"{v:.4g}" for v in given),
                 "--out", str(tmp_path / "gaze.usdc"), "--preview", str(preview)]) == 0
    assert "deg off the skeleton's" not in capsys.readouterr().err  # a forward given is the user's word
    new = measure.posed(str(preview), rig.skeleton)
    line = measure.sight_line(new, left, right, measure.local_forward(new, left, forward_skel),
                              measure.local_forward(new, right, forward_skel))
    goal = target - 0.5 * (new.position(left) + new.position(right))
    goal /= np.linalg.norm(goal, axis=1, keepdims=True)
    assert measure.angle_between(line, goal)[new.times >= 48].max() < 1.0
