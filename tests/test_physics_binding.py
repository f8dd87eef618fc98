"""``attend --physics`` binds the gaze chain as ``apply`` does (--bind/--forward, GazeMapAPI, names), and
its floating base is the pelvis also on a rig whose names say nothing.

On a rig with numbered joints: without hints nothing says which joint is the head, so the command
stops with one line before any simulation; a hint naming a joint the skeleton lacks is one line
naming it. The model's base is the joint where legs and spine part, found from the tree alone.

The body's segments (legs, arms, head) come from the skeleton's shape where names say nothing: the
CMU walk with every joint renamed ``j0``, ``j1``, ... builds the model its names build, and the
simulated walk is the same to the bit."""

from __future__ import annotations

import numpy as np

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import synthetic as syn
from .test_attend_binding import _scene


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


def _renamed_cmu(path, start_s: float, end_s: float, names: bool = False):
    """CMU 131_01 cropped to ``[start_s, end_s]`` (every 4th sample), its joints renamed ``j<i>``
    unless ``names``; returns (path, original leaf name -> new leaf name)."""
    from pathlib import Path

    from pxr import Sdf, Vt

    from .stone_stages import copy_animation

    cmu = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
    skel, anim = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_01"
    src = Sdf.Layer.FindOrOpen(str(cmu))
    joints = list(src.GetAttributeAtPath(skel + ".joints").default)
    leaf = {j.rsplit("/", 1)[-1]: (j.rsplit("/", 1)[-1] if names else f"j{i}") for i, j in enumerate(joints)}
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
