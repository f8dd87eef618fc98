"""The MuJoCo body model of a skeleton, measured against UsdSkel's own forward kinematics.

The expected joint positions come from UsdSkel (tests/measure.py) mapped to MuJoCo's Z-up metres by
the conversion the model documents, written out here: metres = metersPerUnit * stage units, and on
Y-up stages (x, y, z) -> (x, -z, y). The model's positions are MuJoCo's own ``mj_kinematics`` of
the MJCF file the command writes, so usdgaze's math is on one side only.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdgaze.console.main import main
from usdgaze.physics import build, retarget, shapes

from . import measure
from . import synthetic as syn

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"


def to_mujoco(p: np.ndarray, up: str, mpu: float) -> np.ndarray:
    p = np.asarray(p, dtype=float) * mpu
    return p if up == "Z" else np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


@pytest.fixture(scope="module", params=["cmu", "mixamo"])
def case(request, tmp_path_factory):
    tmp = tmp_path_factory.mktemp(request.param)
    if request.param == "cmu":
        stage, skeleton, up, mpu = CMU, "/root/Body/BodySkel", "Y", 1.0
    else:  # Mixamo-style: Y up, centimetres, bone-aligned joint frames, fingers, eyes, end sites
        rig = syn.make_rig(tmp / "mixamo.usda", convention="mixamo", up_axis="Y", meters_per_unit=0.01,
                           frames=48, joints=70, turn_deg_per_s=20.0)
        stage, skeleton, up, mpu = rig.path, rig.skeleton, "Y", 0.01
    xml = tmp / "model.xml"
    assert main(["physics-model", str(stage), "--out", str(xml)]) == 0
    mj = mujoco.MjModel.from_xml_path(str(xml))
    clip = build.load_clip(stage)
    model, ref = build.body_model(clip)
    posed = measure.posed(str(stage), skeleton)
    return dict(stage=stage, mj=mj, model=model, ref=ref, clip=clip, posed=posed, up=up, mpu=mpu)


def _body_ids(case) -> list[int]:
    mj, model = case["mj"], case["model"]
    return [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name) for name in model.names]


def test_joint_positions_match_usdskel_fk_at_rest(case):
    mj, model, posed = case["mj"], case["model"], case["posed"]
    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)  # qpos0: the rest pose, stood on the ground
    ids = _body_ids(case)
    rest_world = posed.rest_skel @ posed.skel_to_world  # row vectors
    expected = to_mujoco(rest_world[model.bodies, 3, :3], case["up"], case["mpu"])
    got = d.xpos[ids]
    # The model stands the rest pose on the ground: compare relative to the base joint.
    err = np.linalg.norm((got - got[0]) - (expected - expected[0]), axis=1)
    assert err.max() < 0.01, f"{model.names[int(err.argmax())]} off by {err.max():.4f} m"
    lowest = np.array([d.geom_xpos[g, 2] for g in range(1, mj.ngeom)])
    assert lowest.min() > -0.2 and (got[:, 2] > -1e-6).all()


def test_joint_positions_match_usdskel_fk_over_the_animation(case):
    mj, model, posed, ref = case["mj"], case["model"], case["posed"], case["ref"]
    qpos = retarget.to_qpos(model, ref)
    assert qpos.shape == (len(posed.times), mj.nq)
    d = mujoco.MjData(mj)
    ids = _body_ids(case)
    # Welded bodies (fingers, eyes, end sites) drop their own rotation; their children would move.
    kept = [b for b in range(len(model.bodies)) if b == 0 or model.kind[model.body_parent[b]] != "weld"]
    worst = 0.0
    for f in range(0, len(qpos), max(1, len(qpos) // 25)):
        d.qpos[:] = qpos[f]
        mujoco.mj_kinematics(mj, d)
        expected = to_mujoco(posed.world[f][model.bodies, 3, :3], case["up"], case["mpu"])
        worst = max(worst, float(np.linalg.norm(d.xpos[ids][kept] - expected[kept], axis=1).max()))
    assert worst < 0.01


def _fk(joints_parents, t, q, s2w):
    """Plain FK with scipy (not usdgaze): world positions (F, J, 3) from local TR and skel_to_world."""
    parents = joints_parents
    f, j = q.shape[:2]
    r = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(f, j, 3, 3)
    wr = np.zeros_like(r)
    wp = np.zeros((f, j, 3))
    for k, p in enumerate(parents):
        if p < 0:
            wr[:, k], wp[:, k] = r[:, k], t[:, k]
        else:
            wr[:, k] = wr[:, p] @ r[:, k]
            wp[:, k] = wp[:, p] + np.einsum("fij,fj->fi", wr[:, p], t[:, k])
    m = s2w[:, :3, :3]
    return np.einsum("fij,fkj->fki", m, wp) + s2w[:, None, :3, 3]


def test_round_trip_moves_no_joint_more_than_a_centimetre(case):
    model, ref, clip = case["model"], case["ref"], case["clip"]
    qpos = retarget.to_qpos(model, ref)
    rotations, translations = retarget.from_qpos(model, qpos, ref)
    s2w = np.broadcast_to(ref.skel_to_world, (len(qpos), 4, 4))
    before = _fk(clip.parents, ref.translations, ref.rotations, s2w)
    after = _fk(clip.parents, translations, rotations, s2w)
    moved = np.linalg.norm(after - before, axis=-1).max() * case["mpu"]
    assert moved < 0.01
    assert np.allclose(np.linalg.norm(rotations, axis=-1), 1.0, atol=1e-6)


def test_model_is_physically_plausible(case):
    mj, model = case["mj"], case["model"]
    assert abs(mj.body_mass.sum() - 75.0) < 1e-3
    names = [mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, k) for k in range(mj.njnt)]
    kinds = [int(t) for t in mj.jnt_type]
    hinges = [n for n, t in zip(names, kinds) if t == mujoco.mjtJoint.mjJNT_HINGE]
    # Hinges at the knees and elbows (the paper's model) and at the toes (one flexion axis each).
    limbs = [n for n in hinges if any(w in n.lower() for w in ("knee", "leg", "elbow", "forearm"))]
    toes = [n for n in hinges if "toe" in n.lower()]
    assert len(limbs) == 4 and len(toes) <= 2 and len(limbs) + len(toes) == len(hinges)
    _hinges_flex_forward(mj, [names.index(n) for n in limbs])
    assert kinds[0] == mujoco.mjtJoint.mjJNT_FREE and mj.nu == mj.nv - 6
    # Standing at rest, the centre of mass is laterally between the feet and at 45-65% of the height.
    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)
    mujoco.mj_comPos(mj, d)
    com = d.subtree_com[1]
    ids = _body_ids(case)
    feet = d.xpos[[ids[b] for b in model.feet]]
    top = d.xpos[ids].max(axis=0)[2]
    assert feet[:, 0].min() - 0.05 < com[0] < feet[:, 0].max() + 0.05
    assert 0.4 < com[2] / top < 0.7
    # Only spheres and capsules, the shapes the measures and task costs know (by MuJoCo's codes).
    body_geoms = np.flatnonzero(mj.geom_bodyid > 0)
    assert set(mj.geom_type[body_geoms]) <= {shapes.SPHERE, shapes.CAPSULE}
    assert (shapes.SPHERE, shapes.CAPSULE) == (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE)


def _geom_extremes(mj, d, axis: np.ndarray) -> np.ndarray:
    """Per geom, its farthest surface point along ``axis`` (MuJoCo's own geometry, world frame)."""
    out = []
    for g in range(mj.ngeom):
        if mj.geom_bodyid[g] == 0:
            continue  # the ground
        half = mj.geom_size[g, 1] if mj.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0
        along = d.geom_xmat[g].reshape(3, 3)[:, 2] @ axis
        out.append(d.geom_xpos[g] @ axis + abs(along) * half + mj.geom_size[g, 0])
    return np.array(out)


def model_at_rest(tmp_path, rig, up: str, mpu: float):
    """The MJCF ``physics-model`` writes for ``rig``, posed at rest by MuJoCo, and the rig's rest joint
    positions by UsdSkel in MuJoCo's axes: (mj, data, posed, rest)."""
    xml = tmp_path / "model.xml"
    assert main(["physics-model", str(rig.path), "--out", str(xml)]) == 0
    mj = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)
    posed = measure.posed(str(rig.path), rig.skeleton)
    return mj, d, posed, to_mujoco((posed.rest_skel @ posed.skel_to_world)[:, 3, :3], up, mpu)


def test_an_end_site_ends_its_segment_and_adds_no_shape_beyond_it(tmp_path):
    """Mixamo's HeadTop_End and Toe_End mark where the head and the toes end: the body reaches them
    with its segments' own radius and no farther (a continued bone there made a horn above the head
    and toes 12 cm too long)."""
    rig = syn.make_rig(tmp_path / "mixamo.usda", convention="mixamo", up_axis="Z", meters_per_unit=0.01,
                       frames=6, mesh=False, walk_speed=0.0)
    mj, d, posed, rest = model_at_rest(tmp_path, rig, "Z", 0.01)
    base = rest[posed.index("mixamorig_Hips")]
    at = lambda leaf: rest[posed.index(leaf)] - base + d.xpos[1]  # noqa: E731  (stood where the model stands)
    radius = mj.geom_size[1:, 0].max()
    top = _geom_extremes(mj, d, np.array([0.0, 0.0, 1.0])).max()
    assert top <= at("mixamorig_HeadTop_End")[2] + radius + 1e-6, top - at("mixamorig_HeadTop_End")[2]
    toe_tip = at("mixamorig_LeftToe_End")
    forward = toe_tip - at("mixamorig_LeftFoot")
    forward[2] = 0.0
    forward /= np.linalg.norm(forward)
    front = _geom_extremes(mj, d, forward).max()
    foot_radius = max(mj.geom_size[g, 0] for g in range(mj.ngeom)
                      if "Toe" in (mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_GEOM, g) or ""))
    assert front <= toe_tip @ forward + foot_radius + 1e-6, front - toe_tip @ forward


def test_a_skeleton_without_names_gets_the_named_ones_shapes_and_fingers_end_at_their_tips(tmp_path):
    """The Mixamo-style skeleton with every joint named ``bone_NNN`` and its chain bound by hand builds
    the named rig's bodies: the same shapes, radii and masses (the skull's top, the toe tips and the
    eyes found from the binding and the limbs' depth, not from ``_End``). With fingers: Mixamo's
    fingertip joints (``LeftHandIndex4``) have no shape; a UE-style last phalanx (``index_03_l``, a
    real joint) is as long as the phalanx before it, by UsdSkel FK, not a tenth of the body."""
    from usdgaze.characters import bind
    from usdgaze.core.hints import BindHints

    named = syn.make_rig(tmp_path / "named.usda", convention="mixamo", frames=6, mesh=False)
    bare = syn.make_rig(tmp_path / "bare.usda", convention="generic", frames=6, mesh=False)
    by_name, _ = build.body_model(build.load_clip(named.path))
    leaf = {j.rsplit("/", 1)[-1]: b.rsplit("/", 1)[-1] for j, b in zip(named.joints, bare.joints)}
    roles = {"pelvis": "Hips", "lowerSpine": "Spine", "upperSpine": "Spine1", "neck": "Neck", "head": "Head",
             "leftEye": "LeftEye", "rightEye": "RightEye"}
    hints = BindHints(bindings=tuple((r, (leaf["mixamorig_" + j],)) for r, j in roles.items()),
                      forward=tuple(bare.forward))
    clip = build.load_clip(bare.path)
    by_shape, _ = build.body_model(clip, chain_frame=bind(clip, None, hints))
    assert by_shape.role == by_name.role and by_shape.kind == by_name.kind
    assert [[k for k, _ in g] for g in by_shape.geoms] == [[k for k, _ in g] for g in by_name.geoms]
    for a, b in zip(by_shape.geoms, by_name.geoms):
        for (_, va), (_, vb) in zip(a, b):
            np.testing.assert_allclose(va, vb, atol=1e-9)
    np.testing.assert_allclose(by_shape.mass, by_name.mass, rtol=1e-9)
    np.testing.assert_allclose(by_shape.radius, by_name.radius, rtol=1e-9)

    for convention, tip, before in (("mixamo", "LeftHandIndex4", "LeftHandIndex3"), ("ue", "index_03_l", "index_02_l")):
        rig = syn.make_rig(tmp_path / f"{convention}70.usda", convention=convention, frames=6, mesh=False, joints=70)
        model, _ = build.body_model(build.load_clip(rig.path))
        body = {model.joints[j].rsplit("/", 1)[-1].removeprefix("mixamorig_"): b for b, j in enumerate(model.bodies)}
        geoms = model.geoms[body[tip]]
        posed = measure.posed(str(rig.path), rig.skeleton)
        prefix = "mixamorig_" if convention == "mixamo" else ""
        bone = np.linalg.norm(posed.rest_skel[posed.index(prefix + tip), 3, :3]
                              - posed.rest_skel[posed.index(prefix + before), 3, :3])
        if convention == "mixamo":
            assert geoms == []
        else:
            (kind, v), = geoms
            assert kind == "capsule" and np.linalg.norm(v[3:] - v[:3]) == pytest.approx(bone, rel=1e-6)


@pytest.mark.parametrize("convention", ["mixamo", "ue", "rigify"])
def test_both_hands_catch_each_on_its_side_with_the_palm_before_the_knuckles(tmp_path, convention):
    """The catch's hands on rigs with fingers: one per side, found by the character's left at rest
    (UE's ``hand_r`` and Rigify's ``DEF-hand.R`` do not start with r), and each palm point halfway
    from the wrist to the fingers' bases, by MuJoCo's own kinematics against UsdSkel's joints."""
    from usdgaze.physics import catch

    rig = syn.make_rig(tmp_path / "rig.usda", convention=convention, frames=6, mesh=False, joints=70)
    model, _ = build.body_model(build.load_clip(rig.path))
    sites = catch._hand_sites(model)
    assert sorted(sites) == ["left", "right"]
    mj, d, posed, rest = model_at_rest(tmp_path, rig, "Y", 1.0)
    left = np.cross([0.0, 0.0, 1.0], model.forward)
    hips = d.xpos[1]
    for side, (body, palm) in sites.items():
        wrist = d.xpos[body]
        point = wrist + d.xmat[body].reshape(3, 3) @ palm
        assert ((point - hips) @ left > 0.1) == (side == "left")
        hand = model.bodies[body - 1]
        bases = [i for i, p in enumerate(posed.joints) if p.rsplit("/", 1)[0] == posed.joints[hand]
                 and any(f in p.rsplit("/", 1)[-1].lower() for f in ("index", "middle", "ring", "pinky"))]
        knuckles = (rest[bases] - rest[hand]).mean(axis=0) + wrist  # the same offsets, stood where MuJoCo stands
        assert np.linalg.norm(point - (wrist + 0.5 * (knuckles - wrist))) < 0.02


def test_which_leaves_end_their_segment():
    """By place, where names say nothing: every leaf below the head (a face's jaw and chin, an ear,
    the skull's top) ends its segment; a foot's leaf one joint below the ankle is the toes' start
    (CMU's), two below it the toes' tip (Mixamo's); a finger's leaf three below the hand is a last
    phalanx (UE's), four below it a fingertip (Mixamo's)."""
    from usdgaze.physics import segments

    tree = [  # (name, parent, role)
        ("pelvis", -1, "other"), ("spine", 0, "other"), ("neck", 1, "head"), ("head", 2, "head"),
        ("jaw", 3, "head"), ("chin", 4, "head"), ("ear", 3, "head"), ("crown", 3, "head"),
        ("ankle", 0, "foot"), ("toe", 8, "foot"),
        ("ankle2", 0, "foot"), ("ball", 10, "foot"), ("tip", 11, "foot"),
        ("hand", 1, "hand"), ("f1", 13, "hand"), ("f2", 14, "hand"), ("f3", 15, "hand"),
        ("g1", 13, "hand"), ("g2", 17, "hand"), ("g3", 18, "hand"), ("g4", 19, "hand"),
    ]
    names, parents, roles = (list(c) for c in zip(*tree))
    parents = np.array(parents)
    children = [[c for c in range(len(tree)) if parents[c] == b] for b in range(len(tree))]
    tips, phalanges = segments.leaf_ends(names, roles, parents, children, head=3)
    assert {names[j] for j in tips} == {"chin", "ear", "crown", "tip", "g4"}
    assert {names[j] for j in phalanges} == {"f3"}
    # No head known: the ear and the crown still sit beside the jaw, a joint the chain goes on through.
    tips, _ = segments.leaf_ends(names, roles, parents, children, head=None)
    assert {names[j] for j in tips} == {"tip", "g4", "ear", "crown"}


def test_attachments_on_a_bone_or_beside_a_chain_end_no_segment():
    """A twist joint halfway along a forearm whose hand is a leaf (UE's lowerarm_twist_01_l) and
    helper leaves beside a joint the chain goes on through (a breast beside the chest, a pad beside
    a hand with fingers) sit on their parent's segment; a leaf off the bone beside only leaves, a
    hand's leaf beside its fingers (CMU's thumb), a foot beside a twist chain and the hands
    themselves do not."""
    from usdgaze.physics import segments

    tree = [  # (name, parent, role, position)
        ("pelvis", -1, "other", (0, 0, 1.0)), ("spine", 0, "other", (0, 0, 1.2)), ("chest", 1, "other", (0, 0, 1.4)),
        ("breast", 1, "other", (0, 0.1, 1.3)),
        ("forearm_l", 2, "forearm", (0.3, 0, 1.4)), ("hand_l", 4, "hand", (0.55, 0, 1.4)),
        ("twist_l", 4, "other", (0.42, 0.01, 1.4)), ("pad_l", 4, "other", (0.3, -0.1, 1.4)),
        ("forearm_r", 2, "forearm", (-0.3, 0, 1.4)), ("hand_r", 8, "hand", (-0.55, 0, 1.4)),
        ("pad_r", 8, "other", (-0.3, -0.1, 1.4)), ("fingers_r", 9, "hand", (-0.6, 0, 1.4)),
        ("finger2_r", 11, "hand", (-0.65, 0, 1.4)), ("thumb_r", 9, "hand", (-0.58, 0.05, 1.4)),
        ("weapon_r", 9, "hand", (-0.6, -0.05, 1.4)),
        # A foot that ends its leg beside a two-joint twist chain is the foot, not an attachment.
        ("calf", 0, "shank", (0.1, 0, 0.5)), ("foot", 15, "foot", (0.1, 0, 0.08)),
        ("calf_twist_01", 15, "other", (0.1, 0.01, 0.35)), ("calf_twist_02", 17, "other", (0.1, 0.01, 0.2)),
    ]
    names, parents, roles, pos = (list(c) for c in zip(*tree))
    parents, pos = np.array(parents), np.array(pos, dtype=float)
    children = [[c for c in range(len(tree)) if parents[c] == b] for b in range(len(tree))]
    tips, _ = segments.leaf_ends(names, roles, parents, children, head=None, pos=pos)
    assert {names[j] for j in tips} == {"breast", "twist_l", "pad_r", "weapon_r"}
    tips, _ = segments.leaf_ends(names, roles, parents, children, head=None)  # no places: chains and names
    assert {names[j] for j in tips} == {"breast", "pad_r", "weapon_r"}


def test_a_catch_model_frees_the_still_arms_but_not_the_pelvis_bones():
    """Without welding still joints (a catch: the standing reference holds the arms still), the CMU
    rig's pelvis pieces between the hips and the thighs, held still by the walk, stay welded: the
    pelvis is one bone. The collars, also still, get their ball joints: MuJoCo's own count of the
    degrees of freedom is the welded model's plus the collars' six (before: plus the pieces' six too)."""
    from usdgaze.physics import mjcf

    clip = build.load_clip(CMU)
    still, _ = build.body_model(clip)
    free, _ = build.body_model(clip, weld_still=False)
    kind = dict(zip(free.names, free.kind))
    assert dict(zip(still.names, still.kind))["LeftCollar"] == "weld"
    assert (kind["LHipJoint"], kind["RHipJoint"], kind["LeftCollar"], kind["RightCollar"]) == ("weld", "weld", "ball", "ball")
    nv_still, nv_free = (mujoco.MjModel.from_xml_string(mjcf.write(m)).nv for m in (still, free))
    assert nv_free == nv_still + 2 * 3


def test_twist_ik_and_secondary_joints_add_no_body_degrees_of_freedom_or_mass(tmp_path):
    """UE5's helpers (a twist joint on each limb bone, animated; ``ik_foot_*`` and ``ik_hand_*``
    under the root) and chains off the body's frame (a jaw, a ponytail, a skirt panel) change
    nothing a simulation feels: MuJoCo's compiled model has the plain rig's degrees of freedom and
    motors, every plain body keeps its mass within 1% (the trunk had lent 1.5 kg to each of eight
    twist bodies and 11 kg to the skirt, the head 2.1 kg to the hair, each a ball joint), the added
    joints weigh under 0.1 kg with no shape, and the catch's hands and the upper spine's segment are
    the plain rig's."""
    from usdgaze.physics import catch, mjcf

    from .rig_extras import add_joints, secondary_chains, ue5_helpers

    rigs = {}
    for name in ("plain", "helpers"):
        rig = syn.make_rig(tmp_path / f"{name}.usda", convention="ue", frames=24, mesh=False, joints=50)
        if name == "helpers":
            add_joints(rig.path, ue5_helpers(rig) + secondary_chains(rig))
        model, _ = build.body_model(build.load_clip(rig.path))
        rigs[name] = (model, mujoco.MjModel.from_xml_string(mjcf.write(model)))
    (plain, mj_plain), (full, mj_full) = rigs["plain"], rigs["helpers"]
    assert (mj_full.nv, mj_full.nu) == (mj_plain.nv, mj_plain.nu)
    assert mj_full.body_mass.sum() == pytest.approx(mj_plain.body_mass.sum(), abs=1e-4)  # MJCF writes 6 digits
    mass = {mj_full.body(b).name: mj_full.body_mass[b] for b in range(1, mj_full.nbody)}
    for b in range(1, mj_plain.nbody):
        if mj_plain.body_mass[b] > 0.01:  # token masses (tips) are shares of the body count: grams
            assert mass[mj_plain.body(b).name] == pytest.approx(mj_plain.body_mass[b], rel=0.01, abs=0.002), mj_plain.body(b).name
    added = [b for b in range(1, mj_full.nbody) if mj_full.body(b).name not in {mj_plain.body(c).name for c in range(mj_plain.nbody)}]
    assert len(added) == 8 + 8
    for b in added:
        assert mj_full.body_mass[b] < 0.1 and mj_full.body_geomnum[b] == 0 and mj_full.body_jntnum[b] == 0
    chest = [b for b, n in enumerate(plain.names) if n == "spine_03"][0]
    assert np.allclose(full.com[full.names.index("spine_03")], plain.com[chest])
    # The upper spine's segment runs to the neck (MuJoCo's body frames), not to a fingered arm's clavicle.
    neck = mj_plain.body("neck_01").id
    to_neck = mj_plain.body_pos[neck] / np.linalg.norm(mj_plain.body_pos[neck])
    com = mj_plain.body_ipos[mj_plain.body("spine_03").id]
    assert com @ to_neck > 0.999 * np.linalg.norm(com)
    hands_plain, hands_full = catch._hand_sites(plain), catch._hand_sites(full)
    for side, (body, palm) in hands_plain.items():
        assert full.names[hands_full[side][0]] == plain.names[body] and np.allclose(hands_full[side][1], palm)


def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "m.xml"
    assert main(["physics-model", str(tmp_path / "missing.usda"), "--out", str(out)]) == 2
    assert main(["physics-model", str(CMU), "--out", str(tmp_path / "m.usda")]) == 2
    assert main(["physics-model", str(CMU), "--out", str(out), "--mass", "-3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(line.startswith("usdgaze: error:") for line in err)
    assert list(tmp_path.iterdir()) == []


def _hinges_flex_forward(mj, limbs: list[int]) -> None:
    """A positive angle at a knee or elbow flexes it, by MuJoCo's kinematics: 30 deg more from the rest
    pose bends the limb about 30 deg more, flexion measured between the bones, signed by the knee's ankle
    behind and the elbow's wrist in front of the line of the bone above (forward = left x up, left from
    the thighs' sides); at the range's ends the limb is flexed at least 5 deg more than at rest and
    over-straightened at most 45 deg (the synthetic clip's own knees go 38 deg past straight; a knee
    could bend 150 deg backwards before)."""
    d = mujoco.MjData(mj)
    body = lambda k: mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, int(mj.jnt_bodyid[k])).lower()  # noqa: E731
    knees = [k for k in limbs if any(w in body(k) for w in ("knee", "leg"))]
    side = {("left" in body(k) or body(k).startswith("l")): k for k in knees}
    mujoco.mj_kinematics(mj, d)
    thigh = {s: d.xpos[mj.body_parentid[mj.jnt_bodyid[k]]] for s, k in side.items()}
    forward = np.cross(thigh[True] - thigh[False], [0.0, 0.0, 1.0])
    forward /= np.linalg.norm(forward)
    for k in limbs:
        b = int(mj.jnt_bodyid[k])
        parent, child = int(mj.body_parentid[b]), int(np.flatnonzero(mj.body_parentid == b)[0])
        sense = -1.0 if k in knees else 1.0  # a knee flexes backwards, an elbow forwards

        def flexion(angle: float) -> float:
            d.qpos[:] = mj.qpos0
            d.qpos[mj.jnt_qposadr[k]] = angle
            mujoco.mj_kinematics(mj, d)
            u, v = d.xpos[b] - d.xpos[parent], d.xpos[child] - d.xpos[b]
            u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
            bent = np.degrees(np.arccos(np.clip(u @ v, -1.0, 1.0)))
            return bent * np.sign(sense * ((v - (v @ u) * u) @ forward))

        rest, more = flexion(0.0), flexion(np.radians(30.0))
        assert 25.0 < more - rest < 35.0, (body(k), rest, more)
        lo, hi = (flexion(end) for end in mj.jnt_range[k])
        assert hi >= rest + 4.9 and lo >= -45.0, (body(k), lo, hi)
