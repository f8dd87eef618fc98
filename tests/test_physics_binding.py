"""``attend --physics`` binds the gaze chain as ``apply`` does (--bind/--forward, GazeMapAPI, names), and
its floating base is the pelvis also on a rig whose names say nothing.

On a rig with numbered joints: without hints nothing says which joint is the head, so the command
stops with one line before any simulation; a hint naming a joint the skeleton lacks is one line
naming it. The model's base is the joint where legs and spine part, found from the tree alone.

The body's segments (legs, arms, head) come from the skeleton's shape where names say nothing: the
CMU walk with every joint renamed ``j0``, ``j1``, ... builds the model its names build, and the
simulated walk is the same to the bit. Names wrapped in a DCC's prefixes and suffixes (Maya's
``C_head_jnt``, AdvancedSkeleton's ``Head_M``) are read as the binding reads them, and ``physics-model``
binds as ``attend --physics`` does, so both build one model."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pytest

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import synthetic as syn
from .test_attend_binding import _scene
from .test_physics_model import model_at_rest


def _rig(tmp_path):
    return syn.make_rig(tmp_path / "in.usda", convention="numbered", frames=6, time_codes_per_second=24,
                        mesh=False, walk_speed=0.0)


def test_physics_needs_a_binding_on_an_unnamed_rig_and_reads_the_hints(tmp_path, capsys):
    rig = _rig(tmp_path)
    scene, _ = _scene(tmp_path, rig)
    out = tmp_path / "none.usdc"
    assert main(["attend", str(scene), "--physics", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no gaze chain" in err[0] and "--bind" in err[0], err
    assert not out.exists()

    args = ["--bind", f"pelvis={rig.leaf['pelvis']}", "--bind", "head=NoSuchJoint"]
    assert main(["attend", str(scene), "--physics", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "NoSuchJoint" in err[0], err
    assert not out.exists()


def test_the_floating_base_is_where_the_legs_meet_when_no_name_says_pelvis(tmp_path):
    from usdgaze.physics import build

    # The numbered synthetic rig: a root joint on the ground above the pelvis.
    rig = _rig(tmp_path)
    from usdgaze.usd.skelio import read_clip, skeletons_under
    from usdgaze.usd.stage import open_stage

    stage = open_stage(str(rig.path))
    root = stage.GetPrimAtPath(rig.skel_root)
    clip = read_clip(stage, skeletons_under(root)[0], root, str(rig.path))
    model, _ = build.body_model(clip, 75.0)
    assert model.joints[model.bodies[0]].rsplit("/", 1)[-1] == rig.leaf["pelvis"]
    # Its segments from its shape; the bound eyes are welded and are the vision part's eyes.
    from usdgaze.characters import bind
    from usdgaze.core.hints import BindHints

    leaf = rig.leaf
    roles = ("pelvis", "pelvis"), ("head", "head"), ("leftEye", "eye_l"), ("rightEye", "eye_r")
    hints = BindHints(bindings=tuple((role, (leaf[k],)) for role, k in roles), forward=tuple(rig.forward))
    model, _ = build.body_model(clip, 75.0, chain_frame=bind(clip, None, hints))
    body = {clip.joints[j].rsplit("/", 1)[-1]: b for b, j in enumerate(model.bodies)}
    want = {"thigh_l": "thigh", "knee_l": "shank", "ankle_l": "foot", "toe_l": "foot", "arm_r": "upperArm",
            "forearm_r": "forearm", "hand_r": "hand", "neck": "head", "head": "head", "spine_c": "other"}
    assert {k: model.role[body[leaf[k]]] for k in want} == want
    assert model.eyes == sorted(body[leaf[k]] for k in ("eye_l", "eye_r"))
    assert all(model.kind[b] == "weld" for b in model.eyes)
    assert model.kind[body[leaf["knee_l"]]] == "hinge" and model.kind[body[leaf["forearm_r"]]] == "hinge"

    # By hand: root on the ground with the pelvis and a prop joint beside it, toes, a heel end site.
    from usdgaze.physics.model import _base_joint

    parents = np.array([-1, 0, 0, 1, 3, 4, 1, 6, 7, 1, 9, 4])
    heights = np.array([0.0, 1.0, 0.05, 0.5, 0.08, 0.0, 0.5, 0.08, 0.0, 1.3, 1.7, 0.0])
    names = [f"j{i}" for i in range(len(parents))]
    assert _base_joint(names, parents, heights) == 1
    # A name still wins: a joint called pelvis is the base wherever the legs meet.
    assert _base_joint(["root", "a", "b", "Pelvis", *names[4:]], parents, heights) == 3


def _renamed_cmu(path, start_s: float, end_s: float, names: bool = False, rename: dict | None = None):
    """CMU 131_01 cropped to ``[start_s, end_s]`` (every 4th sample), its joints renamed ``j<i>``
    unless ``names``, and those in ``rename`` as it says; returns (path, original leaf name -> new leaf name)."""
    from pathlib import Path

    from pxr import Sdf, Vt

    from .stone_stages import copy_animation

    cmu = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
    skel, anim = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_01"
    src = Sdf.Layer.FindOrOpen(str(cmu))
    joints = list(src.GetAttributeAtPath(skel + ".joints").default)
    leaf = {j.rsplit("/", 1)[-1]: (j.rsplit("/", 1)[-1] if names else f"j{i}") for i, j in enumerate(joints)}
    leaf.update(rename or {})
    renamed = {j: "/".join(leaf[p] for p in j.split("/")) for j in joints}
    tcps = src.timeCodesPerSecond
    first = src.startTimeCode + 4.0 * round(start_s * tcps / 4.0)
    codes = np.arange(first, first + (end_s - start_s) * tcps + 1e-6, 4.0)
    layer = Sdf.Layer.CreateNew(str(path))
    layer.subLayerPaths[:] = [str(cmu)]
    layer.startTimeCode, layer.endTimeCode = float(codes[0]), float(codes[-1])
    layer.timeCodesPerSecond = layer.framesPerSecond = tcps
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    copy_animation(layer, src, anim, codes)
    for prim_path in (skel, anim):
        prim = Sdf.CreatePrimInLayer(layer, prim_path)
        prim.specifier = Sdf.SpecifierOver
        spec = Sdf.AttributeSpec(prim, "joints", Sdf.ValueTypeNames.TokenArray, variability=Sdf.VariabilityUniform)
        spec.default = Vt.TokenArray([renamed[j] for j in src.GetAttributeAtPath(prim_path + ".joints").default])
    layer.Save()
    return path, leaf


def test_segments_from_the_skeletons_shape_are_the_ones_names_give(tmp_path):
    from usdgaze.characters import bind
    from usdgaze.core.hints import BindHints
    from usdgaze.physics import build

    named = build.load_clip(_renamed_cmu(tmp_path / "named.usda", 1.0, 1.6, names=True)[0])
    path, leaf = _renamed_cmu(tmp_path / "renamed.usda", 1.0, 1.6)
    clip = build.load_clip(path)
    forward = tuple(bind(named, None)[1].forward)
    hints = BindHints(bindings=(("pelvis", (leaf["Hips"],)), ("head", (leaf["Head"],))), forward=forward)
    by_names, _ = build.body_model(named, chain_frame=bind(named, None))
    by_shape, _ = build.body_model(clip, chain_frame=bind(clip, None, hints))
    inverse = {v: k for k, v in leaf.items()}
    assert [inverse[clip.joints[j].rsplit("/", 1)[-1]] for j in by_shape.bodies] == \
        [named.joints[j].rsplit("/", 1)[-1] for j in by_names.bodies]
    assert by_shape.role == by_names.role and by_shape.kind == by_names.kind
    assert set(by_names.role) >= {"thigh", "shank", "foot", "upperArm", "forearm", "hand", "head"}
    np.testing.assert_array_equal(by_shape.mass, by_names.mass)
    np.testing.assert_array_equal(by_shape.strength, by_names.strength)
    # Without the binding's forward, the feet (heel to toe) give it: within 12 deg of the names'.
    alone, _ = build.body_model(clip)
    assert alone.role == by_names.role
    assert np.degrees(np.arccos(np.clip(alone.forward @ by_names.forward, -1, 1))) < 12.0


def test_a_neck_no_name_calls_so_is_the_head_segment_as_by_its_names(tmp_path):
    """CMU's lowerneck and Neck renamed (no name says neck) below its named Head and above the joint its
    arms hang from: the head segment's neck, as by their names, where the arms come from names too.
    Before: only a rig whose arms came from its shape had them; here each was 2.7 kg of trunk with a
    300 N m motor (by their names: 1.35 kg of head each, 40 N m)."""
    from usdgaze.physics import build

    named = build.load_clip(_renamed_cmu(tmp_path / "named.usda", 1.0, 1.6, names=True)[0])
    rename = {"lowerneck": "CervicalLow", "Neck": "CervicalHigh"}
    path, _ = _renamed_cmu(tmp_path / "cervical.usda", 1.0, 1.6, names=True, rename=rename)
    by_names, _ = build.body_model(named)
    by_place, _ = build.body_model(build.load_clip(path))
    assert by_place.role == by_names.role and by_place.kind == by_names.kind
    np.testing.assert_array_equal(by_place.mass, by_names.mass)
    np.testing.assert_array_equal(by_place.strength, by_names.strength)


def test_a_rig_whose_names_say_nothing_walks_as_the_named_one(tmp_path):
    from pxr import Sdf

    from usdgaze.characters import bind
    from usdgaze.physics import build

    from . import measure

    named_src, _ = _renamed_cmu(tmp_path / "named.usda", 1.0, 1.6, names=True)
    src, leaf = _renamed_cmu(tmp_path / "renamed.usda", 1.0, 1.6)
    forward = ",".join(f"{v:.9g}" for v in bind(build.load_clip(named_src), None)[1].forward)
    hints = ["--bind", f"pelvis={leaf['Hips']}", "--bind", f"head={leaf['Head']}", "--forward", forward]
    outs = tmp_path / "named.usdc", tmp_path / "renamed.usdc"
    assert main(["attend", str(named_src), "--physics", "--window", "0.3", "--out", str(outs[0])]) == 0
    assert main(["attend", str(src), "--physics", "--window", "0.3", "--out", str(outs[1]), *hints]) == 0
    anim = "/root/Body/BodySkel/scaled_131_01"
    layers = [Sdf.Layer.FindOrOpen(str(o)) for o in outs]
    for name in ("rotations", "translations"):
        path = Sdf.Path(f"{anim}.{name}")
        times = layers[0].ListTimeSamplesForPath(path)
        assert times and times == layers[1].ListTimeSamplesForPath(path)
        for t in times:
            assert np.array_equal(np.array(layers[0].QueryTimeSample(path, t)), np.array(layers[1].QueryTimeSample(path, t)))
    # It stands: the pelvis by UsdSkel FK on the written layer against the reference's.
    composed = tmp_path / "composed.usda"
    top = Sdf.Layer.CreateNew(str(composed))
    top.subLayerPaths[:] = [str(outs[1]), str(src)]
    top.Save()
    sim, ref = measure.posed(str(composed), "/root/Body/BodySkel"), measure.posed(str(src), "/root/Body/BodySkel")
    up = ref.up
    ratio = (sim.position(leaf["Hips"]) @ up) / (ref.position(leaf["Hips"]) @ up)
    assert ratio.min() > 0.9, ratio.min()


def _head_and_neck(tmp_path, convention: str, up: str, mpu: float):
    """On MuJoCo's reading of the MJCF ``physics-model`` writes, posed at rest: the neck's subtree's share
    of the mass, how far above the head end joint (by UsdSkel FK) the head's shapes reach along their
    bones and with their radius, the head's radius, and the neck's motor gear."""
    rig = syn.make_rig(tmp_path / f"{convention}.usda", convention=convention, up_axis=up, meters_per_unit=mpu,
                       frames=6, mesh=False, walk_speed=0.0)
    (tmp_path / convention).mkdir()
    mj, d, posed, rest = model_at_rest(tmp_path / convention, rig, up, mpu)
    def body(key: str) -> int:
        return mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[key].removeprefix("mixamorig_"))

    neck, head = body("neck"), body("head")
    # Stood where the model stands (it is lifted onto the ground).
    end = rest[posed.index(rig.leaf["head_end"])] - rest[posed.index(rig.leaf["pelvis"])] + d.xpos[body("pelvis")]
    above = [g for g in range(mj.ngeom) if head in (mj.geom_bodyid[g], mj.body_parentid[mj.geom_bodyid[g]])]
    half = np.where(mj.geom_type[above] == mujoco.mjtGeom.mjGEOM_CAPSULE, mj.geom_size[above, 1], 0.0)
    reach = d.geom_xpos[above, 2] + np.abs(d.geom_xmat[above].reshape(-1, 3, 3)[:, 2, 2]) * half
    motors = [a for a in range(mj.nu) if mj.jnt_bodyid[mj.actuator_trnid[a, 0]] == neck]
    gear = np.abs(mj.actuator_gear[motors, :3]).max()
    return (mj.body_subtreemass[neck] / mj.body_subtreemass[0], reach.max() - end[2],
            (reach + mj.geom_size[above, 0]).max() - end[2], mj.geom_size[above, 0].max(), gear)


@pytest.mark.parametrize("convention, up, mpu", [("maya", "Z", 1.0), ("advanced", "Y", 0.01)])
def test_dcc_prefixes_and_suffixes_give_the_head_neck_and_end_site_the_mixamo_rig_has(tmp_path, convention, up, mpu):
    """Maya's ``C_neck01_jnt > C_head_jnt > C_headEnd_jnt`` and AdvancedSkeleton's ``Neck_M > Head_M >
    HeadEnd_M``: head and neck weigh de Leva's 6.94% of the mass, the head's bones end at the head end
    joint (its shapes reach it with their radius, as Mixamo's HeadTop_End), the neck's motor is the
    Mixamo rig's neck's. Before: the suffixes hid the head and the end site from whole-name patterns,
    and the head end was a 2.8 kg head, a 6.2 cm sphere centred 11.5 cm above the skull top, the neck
    4.4 kg of trunk with a 300 N m motor (head and neck 12.8%)."""
    share, reach, surface, radius, gear = _head_and_neck(tmp_path, convention, up, mpu)
    assert share == pytest.approx(0.0694, abs=0.015)
    assert abs(reach) < 0.03, reach
    assert surface <= radius + 1e-6, (surface, radius)
    assert gear == _head_and_neck(tmp_path, "mixamo", "Y", 0.01)[4]


def test_physics_model_writes_the_model_attend_simulates(tmp_path):
    """An unnamed rig bound by the GazeMapAPI on its SkelRoot: ``physics-model`` writes the MJCF of the body
    ``attend --physics`` builds, the map's eyes welded, without mass or shape of their own. Before: it read
    no binding, and each eye was a 1.7 kg body of the head with a sphere of its own."""
    from pxr import Usd

    from usdgaze.gaze.defaults import default_definition
    from usdgaze.passes.physics_shots import read_shots
    from usdgaze.physics import mjcf, mpc
    from usdgaze.usd import schema

    rig = _rig(tmp_path)
    keys = {"pelvis": "pelvis", "head": "head", "leftEye": "eye_l", "rightEye": "eye_r"}
    d = dataclasses.replace(default_definition(), forward=tuple(float(v) for v in rig.forward),
                            bindings={role: (rig.joint(k),) for role, k in keys.items()})
    stage = Usd.Stage.Open(str(rig.path))
    schema.write_map(stage.GetPrimAtPath(rig.skel_root), d)
    stage.GetRootLayer().Save()
    xml = tmp_path / "model.xml"
    assert main(["physics-model", str(rig.path), "--out", str(xml)]) == 0
    shot, = read_shots(Usd.Stage.Open(str(rig.path)), str(rig.path), None, mpc.Options(), None)
    assert xml.read_text() == mjcf.write(shot.body[0])
    mj = mujoco.MjModel.from_xml_path(str(xml))
    for key in ("eye_l", "eye_r"):
        b = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, rig.leaf[key])
        assert mj.body_mass[b] < 0.1 and mj.body_geomnum[b] == 0 and mj.body_jntnum[b] == 0, key


@pytest.mark.parametrize("name, step", [("ball_throw.usda", 0.03), ("stepping_stones_shot.usda", 0.02)])
def test_physics_model_writes_the_shot_at_its_step(tmp_path, name, step):
    """A shot with a ball to catch is simulated at 0.03 s, and a shot's root layer over a longer take
    simulates the shot's frames, whose hinge ranges are fitted to them: ``physics-model`` writes that
    body at that step, as MuJoCo reads it. Before: always 0.02 s and the whole take's ranges (the stones
    shot's left knee -53 to 77 deg where the shot's frames give -53 to 55)."""
    from pxr import Usd

    from usdgaze.passes.physics_shots import read_shots
    from usdgaze.physics import mjcf, mpc

    src = Path(__file__).resolve().parents[1] / "sample_stages" / "attend" / name
    xml = tmp_path / "model.xml"
    assert main(["physics-model", str(src), "--out", str(xml)]) == 0
    assert mujoco.MjModel.from_xml_path(str(xml)).opt.timestep == pytest.approx(step)
    shot, = read_shots(Usd.Stage.Open(str(src)), str(src), None, mpc.Options(), None)
    assert xml.read_text() == mjcf.write(shot.body[0], timestep=shot.options.h)
    assert main(["physics-model", str(src), "--out", str(xml), "--timestep", "0.025"]) == 0
    assert mujoco.MjModel.from_xml_path(str(xml)).opt.timestep == pytest.approx(0.025)
