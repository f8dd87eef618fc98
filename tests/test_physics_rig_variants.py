"""``physics-model`` on valid but unusual bipeds: a rig without a head joint, with one arm, with one leg,
without hand joints.

Measured on MuJoCo's own reading of the MJCF the command writes (subtree masses, joint types,
``mj_kinematics``) against de Leva's (1996) table typed in here and UsdSkel's forward kinematics,
not against usdgaze's model. Before: a rig whose neck was its highest joint made its chest the head
and the arms part of it (no elbow hinges, the arms weighing the head's share); a rig with one arm or
one leg gave that limb both sides' de Leva share (an arm of 7.4 kg, a leg of 29.8 kg); a rig whose
arms end at the forearm (no hand joints, no names saying hand) had its shoulder made a hinge elbow and
its elbow a wrist, and its walk turned 163 deg in 0.5 s.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from usdgaze.console.main import main

from . import measure, rig_extras
from .test_physics_model import model_at_rest, to_mujoco
from . import synthetic as syn

# de Leva (1996), Table 4, males: fractions of the total mass.
ARM = 0.0271 + 0.0162 + 0.0061  # upper arm, forearm, hand
LEG = 0.1416 + 0.0433 + 0.0137  # thigh, shank, foot
HEAD = 0.0694  # head and neck
HAND = 0.0061
MASS = 75.0


def drop_joints(path: Path, leaves: set[str]) -> None:
    """Remove the joints named ``leaves`` and everything below them from the rig's Skeleton and
    SkelAnimation, saved in place (the rig has no mesh)."""
    stage = Usd.Stage.Open(str(path))
    skel = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    anim = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
    joints = [str(j) for j in skel.GetAttribute("joints").Get()]
    gone = {j for j in joints if set(j.split("/")) & leaves}
    keep = [i for i, j in enumerate(joints) if j not in gone]
    for name in ("joints", "jointNames", "restTransforms", "bindTransforms"):
        attr = skel.GetAttribute(name)
        if attr.HasAuthoredValue():
            values = list(attr.Get())
            attr.Set(type(attr.Get())([values[i] for i in keep]))
    listed = [str(j) for j in anim.GetAttribute("joints").Get()]
    kept = [i for i, j in enumerate(listed) if j not in gone]
    anim.GetAttribute("joints").Set(Vt.TokenArray([listed[i] for i in kept]))
    for name in ("rotations", "translations", "scales"):
        attr = anim.GetAttribute(name)
        for t in attr.GetTimeSamples():
            values = np.array(attr.Get(t))
            attr.Set(type(attr.Get(t)).FromNumpy(np.ascontiguousarray(values[kept])), t)
    stage.GetRootLayer().Save()


def _model(tmp_path: Path, drop: set[str], convention: str = "mixamo"):
    """The rig (Y up, centimetres) without the joints ``drop``: MuJoCo's model and data at rest, the
    body id of a template key, and the rest joint positions by UsdSkel in MuJoCo's axes."""
    rig = syn.make_rig(tmp_path / "rig.usda", convention=convention, up_axis="Y", meters_per_unit=0.01,
                       frames=8, mesh=False)
    drop_joints(rig.path, {rig.leaf[k] for k in drop})
    assert UsdGeom.GetStageUpAxis(Usd.Stage.Open(str(rig.path))) == "Y"
    mj, d, posed, rest = model_at_rest(tmp_path, rig, "Y", 0.01)
    mujoco.mj_comPos(mj, d)
    body = lambda key: mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[key].removeprefix("mixamorig_"))  # noqa: E731
    return rig, mj, d, body, posed, rest


def _composed(tmp_path: Path, out: Path, rig) -> Path:
    """A stage of the layer ``out`` over the rig's file, on the rig's clock (a sublayer on another time
    code rate is retimed)."""
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    layer = Sdf.Layer.CreateNew(str(tmp_path / "composed.usda"))
    layer.timeCodesPerSecond, layer.framesPerSecond = src.timeCodesPerSecond, src.framesPerSecond
    layer.subLayerPaths[:] = [str(out), str(rig.path)]
    layer.Save()
    return Path(layer.realPath)


def _fk_error(rig, d, body, posed, rest) -> float:
    """Largest distance between MuJoCo's joint positions at rest and UsdSkel's (relative to the hips)."""
    keys = [k for k in rig.leaf if body(k) >= 0]
    got = np.array([d.xpos[body(k)] - d.xpos[body("pelvis")] for k in keys])
    want = np.array([rest[posed.index(rig.leaf[k])] - rest[posed.index(rig.leaf["pelvis"])] for k in keys])
    return float(np.linalg.norm(got - want, axis=1).max())


def test_a_rig_without_a_head_joint_keeps_its_arms_and_its_neck_is_the_head(tmp_path):
    rig, mj, d, body, posed, rest = _model(tmp_path, {"head"})
    assert _fk_error(rig, d, body, posed, rest) < 0.01
    assert abs(mj.body_mass[1:].sum() - MASS) < 1e-3
    for side in "lr":  # each arm weighs one de Leva arm and bends at a hinge elbow
        assert abs(mj.body_subtreemass[body(f"arm_{side}")] - ARM * MASS) < 1e-3
        elbow = mj.body_jntadr[body(f"forearm_{side}")]
        assert mj.jnt_type[elbow] == mujoco.mjtJoint.mjJNT_HINGE
    neck = body("neck")  # the highest joint: de Leva's head and neck, with its mass above the joint
    assert abs(mj.body_subtreemass[neck] - HEAD * MASS) < 1e-3
    assert d.xipos[neck, 2] > d.xpos[neck, 2] + 0.05


@pytest.mark.parametrize("drop, key, share", [({"clav_l"}, "arm_r", ARM), ({"thigh_l"}, "thigh_r", LEG)],
                         ids=["one arm", "one leg"])
def test_a_limb_on_one_side_only_weighs_one_sides_share(tmp_path, drop, key, share):
    rig, mj, d, body, posed, rest = _model(tmp_path, drop)
    assert _fk_error(rig, d, body, posed, rest) < 0.01
    assert abs(mj.body_mass[1:].sum() - MASS) < 1e-3
    assert abs(mj.body_subtreemass[body(key)] - share * MASS) < 1e-3


def test_arms_without_hand_joints_are_upper_arms_and_forearms_with_hinge_elbows(tmp_path):
    rig, mj, d, body, posed, rest = _model(tmp_path, {"hand_l", "hand_r"}, convention="ue")
    assert _fk_error(rig, d, body, posed, rest) < 0.01
    assert abs(mj.body_mass[1:].sum() - MASS) < 1e-3
    for side in "lr":
        shoulder, elbow = (mj.body_jntadr[body(f"{k}_{side}")] for k in ("arm", "forearm"))
        assert mj.jnt_type[shoulder] == mujoco.mjtJoint.mjJNT_BALL
        assert mj.jnt_type[elbow] == mujoco.mjtJoint.mjJNT_HINGE
        # de Leva's upper arm and forearm (the hand's share is the trunk's), a forearm of a forearm's length
        assert abs(mj.body_subtreemass[body(f"arm_{side}")] - (0.0271 + 0.0162) * MASS) < 1e-3
        forearm = np.flatnonzero(mj.geom_bodyid == body(f"forearm_{side}"))
        assert len(forearm) == 1 and 2 * mj.geom_size[forearm[0], 1] > 0.2


def _scale_root(path: Path, samples: dict) -> None:
    """A scale op on the rig's SkelRoot: ``{time or None (default): (x, y, z)}``."""
    stage = Usd.Stage.Open(str(path))
    root = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Root))
    op = UsdGeom.Xformable(root).AddScaleOp()
    for t, s in samples.items():
        op.Set(Gf.Vec3f(*s), Usd.TimeCode.Default() if t is None else t)
    stage.GetRootLayer().Save()


@pytest.mark.parametrize("samples, says", [({None: (1.0, 1.2, 1.0)}, "unevenly (1 to 1.2"),
                                           ({0: (1.0, 1.0, 1.0), 7: (1.5, 1.5, 1.5)}, "by 1 to 1.5 over the clip")],
                         ids=["squashed", "growing"])
def test_a_skelroot_scaled_unevenly_or_over_time_is_refused_in_one_line(tmp_path, capsys, samples, says):
    """Rigid bodies cannot follow a squash or a growth: the model's joints were 10-15 cm from UsdSkel's as
    they turned (squashed 1.2 along the stage's up)."""
    rig = syn.make_rig(tmp_path / "rig.usda", convention="mixamo", frames=8, mesh=False)
    _scale_root(rig.path, samples)
    out, layer = tmp_path / "model.xml", tmp_path / "out.usda"
    assert main(["physics-model", str(rig.path), "--out", str(out)]) == 2
    assert main(["attend", str(rig.path), "--physics", "--out", str(layer)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(says in line and str(rig.path) in line for line in err), err
    assert not out.exists() and not layer.exists()


def test_a_skelroot_scaled_evenly_is_modelled_where_usdskel_puts_the_joints(tmp_path):
    rig = syn.make_rig(tmp_path / "rig.usda", convention="mixamo", frames=8, mesh=False)
    _scale_root(rig.path, {None: (0.6, 0.6, 0.6)})
    mj, d, posed, rest = model_at_rest(tmp_path, rig, "Y", 1.0)
    body = lambda key: mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[key].removeprefix("mixamorig_"))  # noqa: E731
    assert _fk_error(rig, d, body, posed, rest) < 0.01
    head = rest[posed.index(rig.leaf["head"])] - rest[posed.index(rig.leaf["toe_l"])]
    assert abs(head[2] - 0.6 * 1.58) < 0.01  # the synthetic head 1.58 m above the toe, scaled


def test_a_joint_scaled_unevenly_at_rest_is_refused_and_an_even_one_follows_usdskel(tmp_path, capsys):
    """Below a thigh scaled (1, 1.3, 1) at rest, the knee turns inside a squashed frame: the model's knee
    and foot were 9.7 cm from UsdSkel's as the leg swung (exit 0); now one line naming the joints. A hips
    joint scaled 1.1 along every axis is modelled, its joints within 1 cm of UsdSkel's on every frame."""
    from usdgaze.physics import build, mjcf, retarget

    uneven = syn.make_rig(tmp_path / "uneven.usda", convention="mixamo", frames=8, mesh=False)
    rig_extras.scale_joint(uneven.path, uneven.skeleton, uneven.animation, uneven.leaf["thigh_l"], (1.0, 1.3, 1.0))
    out = tmp_path / "model.xml"
    assert main(["physics-model", str(uneven.path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and uneven.leaf["knee_l"] in err[0] and "unevenly" in err[0], err
    assert not out.exists()

    even = syn.make_rig(tmp_path / "even.usda", convention="mixamo", frames=8, mesh=False)
    rig_extras.scale_joint(even.path, even.skeleton, even.animation, even.leaf["pelvis"], (1.1, 1.1, 1.1))
    clip = build.load_clip(even.path)
    model, ref = build.body_model(clip)
    mj = mujoco.MjModel.from_xml_string(mjcf.write(model))
    d = mujoco.MjData(mj)
    posed = measure.posed(str(even.path), even.skeleton, times=clip.times)
    kept = [b for b in range(len(model.bodies)) if b == 0 or model.kind[model.body_parent[b]] != "weld"]
    for f, q in enumerate(retarget.to_qpos(model, ref)):
        d.qpos[:] = q
        mujoco.mj_kinematics(mj, d)
        want = to_mujoco(posed.world[f][model.bodies, 3, :3], "Y", 1.0)
        assert np.linalg.norm(d.xpos[1:][kept] - want[kept], axis=1).max() < 0.01


def test_a_toe_placed_on_its_ankle_gives_a_foot_along_the_ground(tmp_path):
    """A toe joint at its ankle's place (a zero-length bone): the sole's capsule had no length and MuJoCo
    refused the MJCF, so ``attend --physics`` stopped with an internal error (exit 1). Now the foot runs
    to the toe's tip: no foot shape reaches below the toe tip's level by UsdSkel, less its radius."""
    template = dict(syn._BODY)
    try:
        for s, x in (("l", 1.0), ("r", -1.0)):
            syn._BODY[f"toe_{s}"] = (f"ankle_{s}", syn._BODY[f"ankle_{s}"][1])
        rig, mj, d, body, posed, rest = _model(tmp_path, set())
    finally:
        syn._BODY.clear()
        syn._BODY.update(template)
    assert _fk_error(rig, d, body, posed, rest) < 0.01
    for s in "lr":
        tip = rest[posed.index(rig.leaf[f"toe_end_{s}"])] - rest[posed.index(rig.leaf["pelvis"])] + d.xpos[body("pelvis")]
        for g in np.flatnonzero(mj.geom_bodyid == body(f"ankle_{s}")):
            half = mj.geom_size[g, 1] if mj.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0
            low = d.geom_xpos[g, 2] - abs(d.geom_xmat[g].reshape(3, 3)[2, 2]) * half - mj.geom_size[g, 0]
            assert low > tip[2] - mj.geom_size[g, 0] - 0.01, (s, g, low, tip[2])


def test_a_skeleton_the_body_refuses_stops_the_pass_before_any_simulation(tmp_path):
    """Two skeletons under one SkelRoot, the second lying down (its Skeleton prim turned 90 deg): the
    first was simulated before the second's body was refused. Now no step is simulated."""
    from usdgaze.errors import UsdGazeError
    from usdgaze.passes import physics

    rig = syn.make_rig(tmp_path / "in.usda", convention="mixamo", frames=8, mesh=False)
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    for path in (rig.skeleton, rig.animation):
        Sdf.CopySpec(layer, path, layer, path + "2")
    skel = layer.GetPrimAtPath(rig.skeleton + "2")
    skel.relationships["skel:animationSource"].targetPathList.explicitItems = [Sdf.Path(rig.animation + "2")]
    Sdf.AttributeSpec(skel, "xformOp:rotateX", Sdf.ValueTypeNames.Float).default = 90.0
    Sdf.AttributeSpec(skel, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:rotateX"])
    layer.Save()
    steps = []
    with pytest.raises(UsdGazeError, match="does not stand at rest"):
        physics.run(rig.path, tmp_path / "out.usda", progress=lambda k, n: steps.append(k))
    assert steps == [] and not (tmp_path / "out.usda").exists()


def test_bones_split_in_two_are_one_segment_each(tmp_path):
    """Rigify's deform bones come split (DEF-thigh.L, DEF-thigh.L.001, DEF-shin.L, DEF-shin.L.001, ...):
    the shin's upper half was taken for the thigh and the thigh for the trunk (a leg of 21 kg, the knee a
    ball joint at the knee and a hinge at mid-shin). Now each limb weighs de Leva's share, the knees and
    elbows are hinges, and the leg lift turns the knee and the hip."""
    from usdgaze.physics import build, tracking

    rig = syn.make_rig(tmp_path / "rig.usda", convention="rigify", frames=8, mesh=False)
    for s in "LR":
        for bone, below in (("thigh", "shin"), ("shin", "foot"), ("upper_arm", "forearm"), ("forearm", "hand")):
            rig_extras.split_bone(rig.path, f"DEF_{bone}_{s}", f"DEF_{below}_{s}", f"DEF_{bone}_{s}_001",
                                  f"DEF-{bone}.{s}.001")
    out = tmp_path / "model.xml"
    assert main(["physics-model", str(rig.path), "--out", str(out)]) == 0
    mj = mujoco.MjModel.from_xml_path(str(out))
    body = lambda name: mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name)  # noqa: E731
    for s in "LR":
        assert abs(mj.body_subtreemass[body(f"DEF_thigh_{s}")] - LEG * MASS) < 1e-3
        assert abs(mj.body_subtreemass[body(f"DEF_shin_{s}")] - (0.0433 + 0.0137) * MASS) < 1e-3
        assert abs(mj.body_subtreemass[body(f"DEF_upper_arm_{s}")] - ARM * MASS) < 1e-3
        for joint in (f"DEF_shin_{s}", f"DEF_forearm_{s}"):
            assert mj.jnt_type[mj.body_jntadr[body(joint)]] == mujoco.mjtJoint.mjJNT_HINGE
    model, _ = build.body_model(build.load_clip(rig.path))
    for foot in model.feet:
        side = model.names[foot][-1]
        assert [model.names[b] for b in tracking._leg(model, foot)] == [f"DEF_shin_{side}", f"DEF_thigh_{side}"]


def test_joints_hung_beside_the_body_neither_size_nor_shape_it(tmp_path):
    """A camera joint under the hips 8 m ahead made the standing rig 'lying down' (exit 2); one 3.5 m up
    and a marker 30 cm below the ground stood the model's feet 34 cm above its ground (a capsule from the
    hips to the marker) and doubled their thickness (the height counted the camera). By MuJoCo's own
    geometry at rest: the feet stand on the ground, as thick as the plain rig's."""
    def feet_at_rest(rig):
        out = tmp_path / f"{rig.path.stem}.xml"
        assert main(["physics-model", str(rig.path), "--out", str(out)]) == 0
        mj = mujoco.MjModel.from_xml_path(str(out))
        d = mujoco.MjData(mj)
        mujoco.mj_kinematics(mj, d)
        feet = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[k].removeprefix("mixamorig_"))
                for k in ("ankle_l", "toe_l", "ankle_r", "toe_r")]
        geoms = np.flatnonzero(np.isin(mj.geom_bodyid, feet))
        half = np.where(mj.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_CAPSULE, mj.geom_size[geoms, 1], 0.0)
        axis_z = np.abs(d.geom_xmat[geoms].reshape(-1, 3, 3)[:, 2, 2])
        return float((d.geom_xpos[geoms, 2] - axis_z * half - mj.geom_size[geoms, 0]).min()), mj.geom_size[geoms, 0].max()

    plain = syn.make_rig(tmp_path / "plain.usda", convention="mixamo", frames=8, mesh=False)
    for name, extra in (("far", [("Camera", (0.0, 1.7, 8.0))]),
                        ("up_and_down", [("Camera", (0.0, 3.5, 3.0)), ("GroundMarker", (0.0, -0.3, 0.0))])):
        rig = syn.make_rig(tmp_path / f"{name}.usda", convention="mixamo", frames=8, mesh=False)
        rig_extras.add_joints(rig.path, [(leaf, rig.leaf["pelvis"], at, False) for leaf, at in extra])
        (low, radius), (_, plain_radius) = feet_at_rest(rig), feet_at_rest(plain)
        assert abs(low) < 1e-3 and radius == pytest.approx(plain_radius), (name, low, radius)


def test_a_character_set_below_the_stage_ground_is_measured_as_it_stands(tmp_path):
    """The rest pose with its SkelRoot 2 m below the stage's ground: the body starts raised onto the
    ground, and its pelvis was measured against the reference's below it (a height clamped to 1 um):
    'pelvis >= 94908900% of the reference', and no fall could ever be said. Now the reference is
    raised with the body: the report's lowest ratio lies where UsdSkel FK of the written hips puts it."""
    from usdgaze.passes import physics
    from usdgaze.physics import mpc

    rig = syn.make_rig(tmp_path / "rig.usda", convention="mixamo", frames=16, mesh=False, walk_speed=0.0,
                       time_codes_per_second=60.0)
    stage = Usd.Stage.Open(str(rig.path))
    root = stage.GetPrimAtPath(rig.skel_root)
    UsdGeom.Xformable(root).AddTranslateOp().Set(Gf.Vec3d(0.0, -2.0, 0.0))
    skel = stage.GetPrimAtPath(rig.skeleton)
    skel.GetRelationship("skel:animationSource").ClearTargets(True)  # the rest pose: it stands still
    stage.GetRootLayer().Save()
    out = tmp_path / "out.usda"
    report = physics.run(rig.path, out, mpc.Options(h=0.02, retry_iterations=0))[0]
    composed = _composed(tmp_path, out, rig)
    hips = measure.posed(str(composed), rig.skeleton, times=rig.times).position(rig.leaf["pelvis"])[:, 1]
    assert hips.min() > 0.5  # standing on the stage's ground, not 2 m below it
    assert not report.fell and 0.9 < report.min_pelvis_ratio < 1.1
    assert report.min_pelvis_ratio == pytest.approx(hips.min() / hips[0], abs=0.03)


def test_a_weapon_chain_in_a_hand_rides_on_it(tmp_path):
    """``weapon_r`` with its end joint 0.9 m below the right hand (a sword held point down): the chain was
    part of the hand, with a 0.9 m capsule and 85% of the hand's mass. Now the right hand weighs what the
    left does (de Leva's hand, within the chain's token masses) and no shape reaches past it."""
    rig = syn.make_rig(tmp_path / "rig.usda", convention="ue", frames=8, mesh=False)
    hand = rig_extras._bind_positions(rig)["hand_r"]
    rig_extras.add_joints(rig.path, [("weapon_r", "hand_r", tuple(hand + (-0.05, 0.0, 0.0)), False),
                                     ("weapon_r_end", "weapon_r", tuple(hand + (-0.05, -0.9, 0.0)), False)])
    out = tmp_path / "model.xml"
    assert main(["physics-model", str(rig.path), "--out", str(out)]) == 0
    mj = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)
    body = lambda name: mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name)  # noqa: E731
    left, right = mj.body_subtreemass[body("hand_l")], mj.body_subtreemass[body("hand_r")]
    assert left == pytest.approx(0.0061 * MASS, abs=0.01) and right == pytest.approx(left, abs=0.01)
    for name in ("weapon_r", "weapon_r_end"):
        assert mj.body_geomnum[body(name)] == 0
    geoms = np.flatnonzero(np.isin(mj.geom_bodyid, [body("hand_r"), body("weapon_r"), body("weapon_r_end")]))
    half = mj.geom_size[geoms, 1] * (mj.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_CAPSULE)
    reach = np.linalg.norm(d.geom_xpos[geoms] - d.xpos[body("hand_r")], axis=1) + half + mj.geom_size[geoms, 0]
    assert reach.max() < 0.2


@pytest.mark.parametrize("convention, chain", [
    ("mixamo", (("sword", (-0.05, 0.0, 0.0)), ("blade", (-0.05, -0.9, 0.0)))),  # no name says prop
    ("ue", (("weapon_r", (-0.05, 0.0, 0.0)),)),  # a named prop's one joint, in a hand without fingers
    ("generic", (("sword", (-0.05, 0.0, 0.0)), ("blade", (-0.05, -0.9, 0.0)))),  # no name says hand either
])
def test_a_prop_held_in_a_hand_is_no_part_of_the_body(tmp_path, convention, chain):
    """A chain a hand holds is no part of de Leva's body: each hand weighs his hand's share (within the
    prop's token masses), the prop's bodies have no shape and no joint, no capsule of the hand runs along
    it, and its animation is written through. Before, a sword the hand held point down (``RightHand >
    sword > blade``, 0.9 m, no name saying prop) had a 0.9 m capsule and took the hands' share by length
    (both hands of fingered Mixamo-style rig lighter); a ``weapon_r`` joint 5 cm from a hand without
    fingers ended that hand's segment there (0.29 kg, the other 0.62); on a rig whose names say nothing
    (``bone_NNN``), the arm found by shape ran along the sword: its upper arm, forearm and hand were
    trunk (6.9, 6.1 and 1.3 kg) and the sword's first joint its upper arm (3.1 kg)."""
    rig = syn.make_rig(tmp_path / "rig.usda", convention=convention, frames=8, mesh=False,
                       joints=67 if convention == "mixamo" else None)  # 67: every finger of both hands
    hand = rig_extras._bind_positions(rig)[rig.leaf["hand_r"]]
    parent, extra = rig.leaf["hand_r"], []
    for name, offset in chain:
        extra.append((name, parent, tuple(hand + np.array(offset)), True))  # animated: a twist about its bone
        parent = name
    rig_extras.add_joints(rig.path, extra)
    xml = tmp_path / "model.xml"
    assert main(["physics-model", str(rig.path), "--out", str(xml)]) == 0
    mj = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)
    body = lambda name: mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name.removeprefix("mixamorig_"))  # noqa: E731
    assert abs(mj.body_mass[1:].sum() - MASS) < 1e-3
    for side in "lr":
        assert mj.body_subtreemass[body(rig.leaf[f"hand_{side}"])] == pytest.approx(HAND * MASS, abs=0.01), side
    for name, _ in chain:
        assert mj.body_geomnum[body(name)] == 0 and mj.body_jntnum[body(name)] == 0, name
    geoms = np.flatnonzero(mj.geom_bodyid == body(rig.leaf["hand_r"]))
    half = mj.geom_size[geoms, 1] * (mj.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_CAPSULE)
    reach = np.linalg.norm(d.geom_xpos[geoms] - d.xpos[body(rig.leaf["hand_r"])], axis=1) + half + mj.geom_size[geoms, 0]
    assert reach.max() < 0.2
    out = tmp_path / "out.usda"
    bind = ["--bind", f"pelvis={rig.leaf['pelvis']}", "--bind", f"head={rig.leaf['head']}", "--forward",
            ",".join(map(str, rig.forward))] if convention == "generic" else []
    assert main(["attend", str(rig.path), "--physics", "--out", str(out), "--retry-iterations", "0", *bind]) == 0
    stages = [Usd.Stage.Open(str(p)) for p in (rig.path, _composed(tmp_path, out, rig))]
    given, written = (UsdSkel.Animation(stage.GetPrimAtPath(rig.animation)) for stage in stages)
    for name, _ in chain:
        k, w = ([str(j).rsplit("/", 1)[-1] for j in a.GetJointsAttr().Get()].index(name) for a in (given, written))
        for t in rig.times:
            a, b = np.array(given.GetRotationsAttr().Get(t))[k], np.array(written.GetRotationsAttr().Get(t))[w]
            assert np.array_equal(a, b), (name, t)


def test_a_ball_to_catch_for_a_rig_without_hands_is_one_line(tmp_path, capsys):
    """A UE-style rig without hand joints and a ball its SkelRoot's ``usdgaze:physics:catch`` names: the
    catch task found no hand and the command stopped with an internal error (exit 1)."""
    from .catch_stages import _author_ball, flight

    rig = syn.make_rig(tmp_path / "rig.usda", convention="ue", frames=8, mesh=False, walk_speed=0.0)
    drop_joints(rig.path, {rig.leaf["hand_l"], rig.leaf["hand_r"]})
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    codes = np.array(layer.ListTimeSamplesForPath(Sdf.Path(f"{rig.animation}.rotations")))
    _author_ball(layer, codes, flight(np.array([0.0, 1.7, 6.0]), np.array([0.0, 1.3, 0.4]), 0.5, codes / 60.0), rig.skel_root)
    layer.Save()
    out = tmp_path / "out.usda"
    assert main(["attend", str(rig.path), "--physics", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "usdgaze:physics:catch" in err[0] and "no hand" in err[0], err
    assert not out.exists()


def test_legs_a_reference_holds_at_rest_are_not_welded(tmp_path):
    """A walk keyed on the upper body only (the hips and legs left at rest, as an upper-body clip): the
    legs' joints were welded as joints the reference holds still, and the stiff body slid 17 cm across
    the ground in 0.5 s. Now hips, knees and ankles move (MuJoCo's joints) and, by UsdSkel FK of the
    written layer, the hips stay within 10 cm of the reference's across the ground."""
    from usdgaze.passes import physics
    from usdgaze.physics import build, mjcf, mpc

    legs = ("thigh_l", "thigh_r", "knee_l", "knee_r", "ankle_l", "ankle_r", "toe_l", "toe_r")
    rig = syn.make_rig(tmp_path / "rig.usda", convention="ue", frames=25, mesh=False, unanimated=("root", "pelvis", *legs))
    model, _ = build.body_model(build.load_clip(rig.path))
    mj = mujoco.MjModel.from_xml_string(mjcf.write(model))
    for key in legs[:6]:
        b = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[key])
        assert mj.body_jntnum[b] == 1, key
    out = tmp_path / "out.usda"
    physics.run(rig.path, out, mpc.Options(h=0.02, retry_iterations=0))
    composed = _composed(tmp_path, out, rig)
    hips = [measure.posed(str(p), rig.skeleton, times=rig.times).position(rig.leaf["pelvis"]) for p in (rig.path, composed)]
    drift = np.linalg.norm((hips[1] - hips[0])[:, [0, 2]], axis=1)  # stage Y up: across the ground
    assert drift.max() < 0.1, drift.max()


def test_a_joint_keyed_to_a_zero_scale_is_simulated_and_stays_hidden(tmp_path):
    """The right hand keyed to scale 0 from frame 8 (hidden, as animators hide a hand or a prop): its
    orientation was read from a zero matrix and ``attend --physics`` stopped (SVD did not converge, exit
    1). Now the shot is simulated; by UsdSkel of the layer over the input, every rotation is finite and
    the hand is still scaled to nothing where the input hides it."""
    from pxr import UsdSkel as Skel

    rig = syn.make_rig(tmp_path / "rig.usda", convention="mixamo", frames=16, mesh=False)
    stage = Usd.Stage.Open(str(rig.path))
    scales = Skel.Animation(stage.GetPrimAtPath(rig.animation)).GetScalesAttr()
    k = rig.anim_joints.index(rig.joint("hand_r"))
    for t in scales.GetTimeSamples():
        if t >= 8:
            s = np.array(scales.Get(t), dtype=np.float16)
            s[k] = 0.0
            scales.Set(Vt.Vec3hArray.FromNumpy(s), t)
    stage.GetRootLayer().Save()
    out = tmp_path / "out.usda"
    assert main(["attend", str(rig.path), "--physics", "--out", str(out), "--retry-iterations", "0"]) == 0
    composed = _composed(tmp_path, out, rig)
    posed = measure.posed(str(composed), rig.skeleton, times=rig.times)
    assert np.isfinite(posed.world).all()
    hand = posed.world[:, posed.index(rig.leaf["hand_r"]), :3, :3]
    assert np.abs(hand[8:]).max() < 1e-6 and np.abs(np.linalg.det(hand[:8]) - 1.0).max() < 1e-3


@pytest.mark.parametrize("binding", [True, False])
def test_eyelids_and_brows_beside_the_eyes_do_not_move_where_the_body_sees_from(tmp_path, binding):
    """A UE-style rig with an eyelid and a brow joint over each eye (``FACIAL_L_EyeLidUpper``,
    ``FACIAL_L_EyeBrow``, 2 and 4 cm up): every joint named "eye" counted as an eye, and their midpoint,
    where the vision sees from, rose 2 cm. With the gaze binding's eyes, or by name without one, the
    model's eyes are the two eye joints, whose midpoint UsdSkel puts where MuJoCo does."""
    from usdgaze.characters import bind_root
    from usdgaze.physics import build
    from usdgaze.physics.dynamics import MujocoBody

    rig = syn.make_rig(tmp_path / "rig.usda", convention="ue", frames=8, mesh=False)
    pos = rig_extras._bind_positions(rig)
    extra = [(f"FACIAL_{s}_Eye{part}", "head", tuple(pos[rig.leaf[f"eye_{s.lower()}"]] + [0.0, up, 0.0]), False)
             for s in ("L", "R") for part, up in (("LidUpper", 0.02), ("Brow", 0.04))]
    rig_extras.add_joints(rig.path, extra)
    clip = build.load_clip(rig.path)
    if binding:
        stage = Usd.Stage.Open(str(rig.path))  # held: the SkelRoot prim lives as long as its stage
        root = next(p for p in stage.Traverse() if p.IsA(UsdSkel.Root))
        model, _ = build.body_model(clip, chain_frame=bind_root(clip, root))
    else:
        model, _ = build.body_model(clip)
    names = {model.names[b] for b in model.eyes}
    assert {model.joints[model.bodies[b]].rsplit("/", 1)[-1] for b in model.eyes} == {rig.leaf["eye_l"], rig.leaf["eye_r"]}
    body = MujocoBody(model, h=0.02)
    seen, _ = body.head_pose_batch(body.to_state(body.mj.qpos0)[None], 0)  # MuJoCo's kinematics at rest
    d = mujoco.MjData(body.mj)
    mujoco.mj_kinematics(body.mj, d)
    eyes = [d.xpos[mujoco.mj_name2id(body.mj, mujoco.mjtObj.mjOBJ_BODY, n)] for n in names]
    assert np.linalg.norm(seen[0] - np.mean(eyes, axis=0)) < 1e-6


def test_legs_hung_from_a_root_at_the_hips_beside_the_pelvis_are_its_legs(tmp_path, capsys):
    """``root > {pelvis > spine_01 > ..., thigh_l, thigh_r}``, the root at the hips carrying the walk and the
    pelvis below it the lower trunk: refused as having "no feet" (nothing below the pelvis reaches the
    ground). Now the root the legs hang from is the body's pelvis: by MuJoCo's reading of the MJCF, every
    joint within 1 cm of UsdSkel's over the walk and each leg de Leva's share; standing still 1 s it stays
    up (by UsdSkel FK of the written layer, the hips >= 80% of the reference's). The same legs hung from a
    root on the ground are refused in one line that says so, nothing written."""
    from usdgaze.physics import build, retarget

    rig = syn.make_rig(tmp_path / "rig.usda", convention="ue", frames=30, mesh=False, legs_on="root", root_height=0.98)
    assert rig.joint("thigh_l") == "root/thigh_l" and rig.joint("pelvis") == "root/pelvis"  # the premise
    mj, d, posed, rest = model_at_rest(tmp_path, rig, "Y", 1.0)
    body = lambda key: mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[key])  # noqa: E731
    assert mj.body_parentid[body("thigh_l")] == body("root") and mj.jnt_type[mj.body_jntadr[body("root")]] == 0
    for side in "lr":
        assert mj.body_subtreemass[body(f"thigh_{side}")] == pytest.approx(LEG * MASS, abs=1e-3)
    model, ref = build.body_model(build.load_clip(rig.path))
    ids = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name) for name in model.names]
    worst = 0.0
    for f, qpos in enumerate(retarget.to_qpos(model, ref)):
        d.qpos[:] = qpos
        mujoco.mj_kinematics(mj, d)
        expected = to_mujoco(posed.world[f][model.bodies, 3, :3], "Y", 1.0)
        worst = max(worst, float(np.linalg.norm(d.xpos[ids] - expected, axis=1).max()))
    assert worst < 0.01

    still = syn.make_rig(tmp_path / "still.usda", convention="ue", frames=31, time_codes_per_second=30.0, mesh=False,
                         walk_speed=0.0, legs_on="root", root_height=0.98)
    stage = Usd.Stage.Open(str(still.path))
    stage.GetPrimAtPath(still.skeleton).GetRelationship("skel:animationSource").ClearTargets(True)
    stage.GetRootLayer().Save()
    out = tmp_path / "out.usda"
    assert main(["attend", str(still.path), "--physics", "--retry-iterations", "0", "--out", str(out)]) == 0
    hips = [measure.posed(str(p), still.skeleton, times=still.times).position(still.leaf["root"])[:, 1]
            for p in (still.path, _composed(tmp_path, out, still))]
    assert (hips[1] / hips[0]).min() >= 0.8

    capsys.readouterr()
    ground = syn.make_rig(tmp_path / "ground.usda", convention="ue", frames=8, mesh=False, legs_on="root")
    assert main(["attend", str(ground.path), "--physics", "--out", str(tmp_path / "no.usda")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "hang from 'root', beside its pelvis 'pelvis'" in err[0], err
    assert not (tmp_path / "no.usda").exists()


def _neck_share_and_gear(tmp_path, convention: str) -> tuple[float, float]:
    """On MuJoCo's reading of the MJCF ``physics-model`` writes: the share of the mass from the rig's
    neck joint up (head and neck) and the largest gear of that joint's motors."""
    rig = syn.make_rig(tmp_path / f"{convention}.usda", convention=convention, up_axis="Z", meters_per_unit=1.0,
                       frames=6, mesh=False, walk_speed=0.0)
    xml = tmp_path / f"{convention}.xml"
    assert main(["physics-model", str(rig.path), "--out", str(xml)]) == 0
    mj = mujoco.MjModel.from_xml_path(str(xml))
    neck = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf["neck"].removeprefix("mixamorig_"))
    motors = [a for a in range(mj.nu) if mj.jnt_bodyid[mj.actuator_trnid[a, 0]] == neck]
    return float(mj.body_subtreemass[neck] / mj.body_subtreemass[0]), float(np.abs(mj.actuator_gear[motors, :3]).max())


def test_rigify_numbered_neck_weighs_and_pulls_as_a_neck(tmp_path):
    """Rigify's spine chain runs from the hips (``DEF-spine``) to the head (``DEF-spine.006``); its
    ``.004`` and ``.005`` are the neck, which the word ``spine`` had made trunk: 2.2 kg each with
    300 N m motors, head and neck 12.8% of the mass. Now head and neck weigh de Leva's 6.94%, and the
    neck's motor is the Mixamo rig's neck's."""
    share, gear = _neck_share_and_gear(tmp_path, "rigify")
    assert share == pytest.approx(HEAD, abs=0.01), share
    assert gear == _neck_share_and_gear(tmp_path, "mixamo")[1]
