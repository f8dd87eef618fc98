"""``attend --physics`` on a character with no animation bound, and on an animation that lists only
some of the skeleton's joints.

UsdSkel poses an unbound Skeleton at its rest pose (CMU's: Blender's export frame, a standing
pose). The physics pass must keep that character standing under its own controller, define the
animation it writes and bind it, and leave the input unbound when the layer is muted. Measured by
UsdSkel's forward kinematics on the composed stage.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel

from usdgaze.core import rotations as rot
from usdgaze.passes import physics as physics_pass
from usdgaze.physics import build, mpc

from . import measure
from .test_physics_pass import lowest_foot_point

ROOT = Path(__file__).resolve().parents[1]
SKEL = "/root/Body/BodySkel"
FPS, END = 24.0, 12.0  # 0.5 s


@pytest.fixture(scope="module")
def rest_shot(tmp_path_factory):
    d = tmp_path_factory.mktemp("rest_physics")
    src = d / "rest.usdc"
    shutil.copy(ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc", src)
    layer = Sdf.Layer.FindOrOpen(str(src))
    with Sdf.ChangeBlock():
        del layer.GetPrimAtPath(SKEL).properties["skel:animationSource"]
        layer.timeCodesPerSecond = layer.framesPerSecond = FPS
        layer.startTimeCode, layer.endTimeCode = 0.0, END
    layer.Save()
    before = measure.sha256(src)
    out = d / "sim.usda"
    reports = physics_pass.run(src, out, mpc.Options(h=0.02, horizon_s=0.6))
    composed = d / "composed.usda"
    root = Sdf.Layer.CreateNew(str(composed))
    root.timeCodesPerSecond = root.framesPerSecond = FPS
    root.startTimeCode, root.endTimeCode = 0.0, END
    root.subLayerPaths[:] = [str(out), str(src)]
    root.Save()
    return dict(src=src, out=out, composed=composed, reports=reports, before=before)


def test_the_rest_pose_stands_under_the_controller(rest_shot):
    frames = np.arange(0.0, END + 1.0)
    sim = measure.posed(str(rest_shot["composed"]), SKEL)
    ref = measure.posed(str(rest_shot["src"]), SKEL, times=frames)
    assert np.array_equal(sim.times, frames)
    up = lambda p: p.position("Hips") @ p.up  # noqa: E731
    assert (up(sim) / up(ref)).min() >= 0.8
    assert lowest_foot_point(rest_shot["src"], sim).min() > -0.02
    assert not rest_shot["reports"][0].fell


def test_the_new_animation_is_defined_bound_and_gone_when_muted(rest_shot):
    stage = Usd.Stage.Open(str(rest_shot["composed"]))
    skel = stage.GetPrimAtPath(SKEL)
    anim = stage.GetPrimAtPath(SKEL + "/gazeAnimation")
    assert anim.IsA(UsdSkel.Animation) and anim.IsDefined()
    assert UsdSkel.BindingAPI(skel).GetAnimationSourceRel().GetTargets() == [anim.GetPath()]
    joints = list(UsdSkel.Skeleton(skel).GetJointsAttr().Get())
    assert list(UsdSkel.Animation(anim).GetJointsAttr().Get()) == joints
    stage.MuteLayer(str(rest_shot["out"]))
    assert not stage.GetPrimAtPath(SKEL + "/gazeAnimation")
    assert not UsdSkel.BindingAPI(skel).GetAnimationSourceRel().GetTargets()
    assert measure.sha256(rest_shot["src"]) == rest_shot["before"]


def test_joints_the_animation_does_not_list_are_appended_with_their_simulated_values():
    # Three joints of a five-joint chain animated, in an order of their own, and one joint the
    # skeleton lacks ("zz"): the layer lists the animation's first, as the input does ("zz" written
    # through), then the two missing ones in skeleton order.
    from usdgaze.core.clip import SkelClip

    joints = ["a", "a/b", "a/b/c", "a/b/c/d", "a/b/c/d/e"]
    rest = np.tile(np.eye(4), (5, 1, 1))
    rest[:, :3, :3] *= np.array([1.0, 2.0, 1.0, 1.0, 0.5])[:, None, None]  # rest scales 1, 2, 1, 1, 0.5
    listed = [3, 0, -1, 2]
    frames = 6
    rng = np.random.default_rng(3)
    own_rot = rot.normalize(rng.normal(size=(frames, 4, 4))).astype(np.float32)
    own_trans = rng.normal(size=(frames, 4, 3)).astype(np.float32)
    clip = SkelClip(
        source="s.usda", skel_root="/R", skeleton="/R/S", animation="/R/A", joints=joints,
        parents=np.array([-1, 0, 1, 2, 3]), rest_local=rest, bind_world=rest,
        anim_joints=["a/b/c/d", "a", "zz", "a/b/c"], anim_to_skel=np.array(listed), times=np.arange(frames, dtype=float),
        rotations=own_rot, translations=own_trans,
        scales=np.full((frames, 4, 3), 3.0, np.float16), skel_to_world=np.eye(4)[None], up_axis="Y",
        meters_per_unit=1.0, time_codes_per_second=24.0, frames_per_second=24.0, start_time=0.0, end_time=5.0)
    simulated = rot.normalize(np.random.default_rng(1).normal(size=(frames, 5, 4)))
    moved = np.random.default_rng(2).normal(size=(frames, 5, 3))
    o = physics_pass._body_override(clip, simulated, moved)
    assert o.joints == ["a/b/c/d", "a", "zz", "a/b/c", "a/b", "a/b/c/d/e"]
    for column, joint in ((0, 3), (1, 0), (3, 2), (4, 1), (5, 4)):
        assert np.array_equal(o.rotations[:, column], simulated[:, joint].astype(np.float32))
        assert np.array_equal(o.translations[:, column], moved[:, joint].astype(np.float32))
    assert o.rotations[:, 2].tobytes() == own_rot[:, 2].tobytes()
    assert o.translations[:, 2].tobytes() == own_trans[:, 2].tobytes()
    assert o.scales.shape == (frames, 6, 3)
    assert np.all(o.scales[:, :4] == 3.0)
    assert np.allclose(o.scales[:, 4], [2.0, 2.0, 2.0]) and np.allclose(o.scales[:, 5], [0.5, 0.5, 0.5])
    assert o.write_joints and not o.define and np.array_equal(o.times, np.arange(frames))


def test_a_shot_range_shorter_than_the_take_is_all_that_is_simulated_and_the_rest_keeps_the_take(tmp_path):
    """Only the range is simulated; outside it the layer holds the take's own samples, bit for bit,
    so composed over the take the frames the shot does not play are the input's (a layer of the
    range alone left USD holding its first and last pose over them)."""
    from .test_physics_pass import ANIM, excerpt

    src = excerpt(tmp_path / "walk.usda", 1.0)
    layer = Sdf.Layer.FindOrOpen(str(src))
    start, tcps = layer.startTimeCode, layer.timeCodesPerSecond
    layer.startTimeCode, layer.endTimeCode = start + 0.2 * tcps, start + 0.5 * tcps  # the shot: 0.2-0.5 s
    layer.Save()
    take = layer.ListTimeSamplesForPath(Sdf.Path(ANIM + ".rotations"))
    in_shot = [t for t in take if layer.startTimeCode <= t <= layer.endTimeCode]
    (report,) = physics_pass.run(src, tmp_path / "sim.usda", mpc.Options(h=0.02, horizon_s=0.6))
    out = Sdf.Layer.FindOrOpen(str(tmp_path / "sim.usda"))
    assert len(take) > 2 * len(in_shot) and abs(report.simulated_s - 0.3) <= 0.02 + 1e-9
    for name in ("rotations", "translations"):
        path = Sdf.Path(f"{ANIM}.{name}")
        assert out.ListTimeSamplesForPath(path) == take
        for t in take:
            written, given = np.asarray(out.QueryTimeSample(path, t)), np.asarray(layer.QueryTimeSample(path, t))
            if t in in_shot[1:]:  # the simulated frames (the first is the reference's pose it starts from)
                assert not np.array_equal(written, given), (name, t)
            elif t not in in_shot:
                assert written.dtype == given.dtype and np.array_equal(written.view(np.uint32), given.view(np.uint32)), (name, t)


def test_a_child_size_body_stands_still(tmp_path):
    """The synthetic biped at half size (its SkelRoot scaled 0.5: 0.9 m tall, the hips 0.5 m up) at 20 kg,
    standing still 1.5 s through ``attend --physics``: the ground's 1.5 cm contact margin, tuned on
    adults, held its whole sole at rest, and the first simulation jumped off the ground and fell at
    0.48 s (pelvis 62%), where the same rig at full size stands. By UsdSkel FK of the written layer
    over the input, the hips stay at >= 80% of the reference's height and no foot sinks 2 cm."""
    from pxr import Gf, UsdGeom

    from usdgaze.console.main import main

    from . import synthetic as syn
    from .test_physics_rig_variants import _composed

    rig = syn.make_rig(tmp_path / "rig.usda", convention="mixamo", frames=46, mesh=False, walk_speed=0.0,
                       time_codes_per_second=30.0)
    stage = Usd.Stage.Open(str(rig.path))
    UsdGeom.Xformable(stage.GetPrimAtPath(rig.skel_root)).AddScaleOp().Set(Gf.Vec3f(0.5, 0.5, 0.5))
    stage.GetPrimAtPath(rig.skeleton).GetRelationship("skel:animationSource").ClearTargets(True)  # standing still
    stage.GetRootLayer().Save()
    out = tmp_path / "out.usda"
    assert main(["attend", str(rig.path), "--physics", "--mass", "20", "--retry-iterations", "0", "--out", str(out)]) == 0
    composed = _composed(tmp_path, out, rig)
    sim = measure.posed(str(composed), rig.skeleton, times=rig.times)
    ref = measure.posed(str(rig.path), rig.skeleton, times=rig.times)
    hips = lambda p: p.position(rig.leaf["pelvis"]) @ p.up  # noqa: E731
    assert 0.45 < hips(ref).min() and hips(ref).max() < 0.55  # the premise: a child's hips, by UsdSkel
    assert (hips(sim) / hips(ref)).min() >= 0.8
    model, _ = build.body_model(build.load_clip(rig.path), 20.0)
    feet = [measure.lowest_capsule_point(sim, model.joints[model.bodies[b]].rsplit("/", 1)[-1], capsules,
                                         float(model.radius[b]), rig.meters_per_unit) for b, role in enumerate(model.role)
            if role == "foot" and (capsules := [(v[:3], v[3:]) for k, v in model.geoms[b] if k == "capsule"])]
    assert len(feet) == 4 and np.min(feet) > -0.02  # ankles and toes, their capsules in metres
