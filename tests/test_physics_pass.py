"""The physics pass on a short excerpt of the CMU walk's start, pushed from the side at the chest.

Everything is measured on the composed stage (input + the written override) with UsdSkel's forward
kinematics, against the same stage with the override muted (the reference): pelvis height, feet
above the ground, the chest driven sideways by the push, joint-angle error from the layer's own
local rotations, welded joints bit-identical, the input untouched.
"""

from __future__ import annotations

import importlib.metadata
import json
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import build, mpc
from usdgaze.physics.tasks import measure_tasks

from . import measure
from .attend_support import compose

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"
SKEL, ANIM, SKEL_ROOT = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_01", "/root/Body"
SECONDS = 0.5
PUSH = (0.1, 0.3, 150.0)  # start s, end s, newtons along the character's left


def excerpt(path: Path, seconds: float, push=None, vector=None) -> Path:
    """A copy of the CMU stage cut to its first ``seconds``, optionally with a push on the SkelRoot."""
    layer = Sdf.Layer.FindOrOpen(str(CMU))
    tcps = layer.timeCodesPerSecond
    out = Sdf.Layer.CreateNew(str(path))
    out.TransferContent(layer)
    start = out.startTimeCode
    end = start + seconds * tcps
    for name in ("rotations", "translations", "scales"):
        attr = Sdf.Path(f"{ANIM}.{name}")
        for t in out.ListTimeSamplesForPath(attr):
            if t > end:
                out.EraseTimeSample(attr, t)
    out.endTimeCode = end
    if push is not None:
        prim = out.GetPrimAtPath(SKEL_ROOT)
        force = Sdf.AttributeSpec(prim, physics_pass.PUSH_FORCE, Sdf.ValueTypeNames.Float3)
        joint = Sdf.AttributeSpec(prim, physics_pass.PUSH_JOINT, Sdf.ValueTypeNames.Token)
        joint.default = "Chest2"
        # The character's left in stage axes (Y up): from the rest hips, as the tests measure it.
        posed = measure.posed(str(CMU), SKEL)
        fwd = measure.character_forward_skel(posed, "LeftHip", "RightHip")
        left_skel = np.cross(np.array([0, 0, 1.0]), fwd)  # skeleton space is Z up here
        left = posed.skel_to_world[:3, :3].T @ left_skel
        left /= np.linalg.norm(left)
        a, b, newtons = push
        vec = newtons * left if vector is None else np.asarray(vector, dtype=float)
        out.SetTimeSample(force.path, start + a * tcps, Gf.Vec3f(*vec))
        out.SetTimeSample(force.path, start + b * tcps, Gf.Vec3f(0, 0, 0))
    out.Save()
    return path


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("physics")
    src = excerpt(tmp / "pushed.usda", SECONDS, PUSH)
    before = measure.sha256(src)
    out = tmp / "sim.usda"
    reports = physics_pass.run(src, out, mpc.Options(h=0.02, horizon_s=0.6))
    composed = compose(tmp, src, out)
    return dict(src=src, out=out, composed=composed, reports=reports, before=before)


def test_stays_up_with_the_feet_on_the_ground_and_tracks(shot):
    sim = measure.posed(str(shot["composed"]), SKEL)
    ref = measure.posed(str(shot["src"]), SKEL)
    up = lambda p, leaf: p.position(leaf) @ p.up  # noqa: E731
    ratio = up(sim, "Hips") / up(ref, "Hips")
    assert ratio.min() >= 0.8
    # No foot below the ground by more than 2 cm (the push bar): the model's foot capsules (ankle, sole,
    # toe bodies) fixed to the written joints, posed by UsdSkel FK.
    assert lowest_foot_point(shot["src"], sim).min() > -0.02
    # The push moved the chest toward the character's left, beyond the reference's own sway.
    fwd = measure.character_forward_skel(ref, "LeftHip", "RightHip")
    left = ref.skel_to_world[:3, :3].T @ np.cross(np.array([0, 0, 1.0]), fwd)
    drift = (sim.position("Chest2") - ref.position("Chest2")) @ (left / np.linalg.norm(left))
    assert drift.max() > 0.01
    report = shot["reports"][0]
    assert not report.fell and report.pushes == 1 and report.frames == len(sim.times)


def test_a_reference_that_starts_in_the_floor_starts_on_it(tmp_path):
    """The whole character lowered 6 cm, its feet 4 cm into the floor (as a capture whose floor is
    off): the simulated body's first frame stands on the ground, not in it (MuJoCo's soft contact
    would otherwise start by pushing it out), and it tracks the reference raised as it started, so
    the shot stays up with no foot 2 cm into the floor (tracked as it was, the body fell at 0.42 s
    with its feet 6.2 cm in the floor). By UsdSkel FK of the model's foot capsules."""
    src = excerpt(tmp_path / "low.usda", 0.6)
    layer = Sdf.Layer.FindOrOpen(str(src))
    root = layer.GetPrimAtPath("/root")
    op = Sdf.AttributeSpec(root, "xformOp:translate:floor", Sdf.ValueTypeNames.Double3)
    op.default = Gf.Vec3d(0.0, -0.06, 0.0)  # stage Y up: 6 cm down, outside every other transform
    order = root.attributes["xformOpOrder"]
    order.default = Vt.TokenArray(["xformOp:translate:floor", *order.default])
    layer.Save()
    ref = measure.posed(str(src), SKEL)
    assert lowest_foot_point(src, ref)[0] < -0.03  # the reference starts in the floor
    out = tmp_path / "sim.usda"
    report = physics_pass.run(src, out, mpc.Options(h=0.02, horizon_s=0.6))[0]
    composed = tmp_path / "composed.usda"
    top = Sdf.Layer.CreateNew(str(composed))
    top.timeCodesPerSecond, top.framesPerSecond = layer.timeCodesPerSecond, layer.framesPerSecond
    top.startTimeCode, top.endTimeCode = layer.startTimeCode, layer.endTimeCode
    top.subLayerPaths[:] = [str(out), str(src)]
    top.Save()
    low = lowest_foot_point(src, measure.posed(str(composed), SKEL))
    assert low[0] >= -0.002, low[0]
    assert not report.fell and low.min() >= -0.02, low.min()


def lowest_foot_point(src, posed: measure.Posed) -> np.ndarray:
    """Per frame, the height (m) of the lowest surface point of the body model's foot capsules."""
    model, _ = build.body_model(build.load_clip(src))
    mpu = UsdGeom.GetStageMetersPerUnit(Usd.Stage.Open(str(src)))
    heights = [measure.lowest_capsule_point(posed, model.joints[model.bodies[b]].rsplit("/", 1)[-1],
                                            [(v[:3], v[3:]) for k, v in model.geoms[b] if k == "capsule"],
                                            float(model.radius[b]), mpu)
               for b, role in enumerate(model.role) if role == "foot"]
    assert len(heights) == 4  # ankle and toe bodies of both feet
    return np.min(heights, axis=0)


def _locals(path):
    stage = Usd.Stage.Open(str(path))
    anim = UsdSkel.Animation(stage.GetPrimAtPath(ANIM))
    times = anim.GetRotationsAttr().GetTimeSamples()
    return [str(j) for j in anim.GetJointsAttr().Get()], np.array([np.array(anim.GetRotationsAttr().Get(t)) for t in times])


def test_joint_angles_follow_the_reference_and_welded_joints_are_untouched(shot):
    joints, sim = _locals(shot["composed"])
    _, ref = _locals(shot["src"])
    # Quaternion angle between simulated and reference local rotations (xyzw float arrays from USD).
    dot = np.abs(np.sum(sim.astype(float) * ref.astype(float), axis=-1)).clip(0, 1)
    err = np.degrees(2 * np.arccos(dot))
    moving = err.max(axis=0) > 0
    assert err[:, moving].mean() <= 10.0
    # CMU's hip and collar joints never move in the reference: the model welds them, bit for bit.
    for leaf in ("LHipJoint", "RHipJoint", "LeftCollar", "RightCollar"):
        j = next(i for i, n in enumerate(joints) if n.endswith(leaf))
        assert np.array_equal(sim[:, j], ref[:, j])


def test_input_untouched_and_the_layer_reports_per_frame_terms(shot):
    assert measure.sha256(shot["src"]) == shot["before"]
    layer = Sdf.Layer.FindOrOpen(str(shot["out"]))
    data = layer.customLayerData["usdgaze:physics"][SKEL]
    frames = data["frames"]
    assert len(frames["pelvisRatio"]) == len(frames["seconds"]) == round(SECONDS / 0.02) + 1
    assert list(data["problems"]) == ["none"]
    # Muting the override gives back the input exactly.
    stage = Usd.Stage.Open(str(shot["composed"]))
    stage.MuteLayer(layer.identifier)
    muted = UsdSkel.Animation(stage.GetPrimAtPath(ANIM)).GetRotationsAttr()
    source = Usd.Stage.Open(str(shot["src"]))
    original = UsdSkel.Animation(source.GetPrimAtPath(ANIM)).GetRotationsAttr()
    assert muted.GetTimeSamples() == original.GetTimeSamples()
    for t in original.GetTimeSamples():
        assert np.array_equal(np.array(muted.Get(t)), np.array(original.Get(t)))


@pytest.mark.parametrize("workers, stride", [(1, 1), (2, 3)])
def test_each_solve_decreases_the_cost(tmp_path, workers, stride):
    """Also with the window's derivatives split over two threads and interpolated between every third
    step: approximate derivatives change the steps the solver proposes, never what it accepts."""
    clip = build.load_clip(excerpt(tmp_path / "short.usda", 0.12))
    model, ref = build.body_model(clip)
    from usdgaze.physics import retarget

    options = mpc.Options(h=0.02, horizon_s=0.3, workers=workers, fd_stride=stride)
    result = mpc.simulate(model, retarget.to_qpos(model, ref), clip.seconds, options)
    assert len(result.solve_costs) == 6
    for costs in result.solve_costs:
        assert all(b <= a for a, b in zip(costs, costs[1:]))
    assert result.solve_costs[0][-1] < 0.9 * result.solve_costs[0][0]


def test_a_fall_that_stops_the_simulation_early_holds_its_last_pose_to_the_shots_end(tmp_path, capsys):
    """A crushed body falls and the simulation stops 0.2 s later; the layer still samples every frame
    of the input (the rest hold the last simulated pose), so validate finds no other take in it."""
    from usdgaze.console.main import main

    src = excerpt(tmp_path / "crushed.usda", 0.8, (0.0, 0.8, 0.0), vector=(0.0, -10000.0, 0.0))
    out = tmp_path / "sim.usda"
    assert main(["attend", str(src), "--out", str(out), "--physics", "--window", "0.3", "--retry-iterations", "0",
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)["shots"][0]
    layer, given = Sdf.Layer.FindOrOpen(str(out)), Sdf.Layer.FindOrOpen(str(src))
    path = f"{ANIM}.rotations"
    times = layer.ListTimeSamplesForPath(path)
    assert report["fell_at_s"] is not None and times == given.ListTimeSamplesForPath(path)
    seconds = (np.array(times) - given.startTimeCode) / given.timeCodesPerSecond
    after = [t for t, s in zip(times, seconds) if s > report["simulated_s"] + 1e-6]
    assert len(after) >= 0.2 * len(times)  # stopped well before the shot's end
    last = np.asarray(layer.QueryTimeSample(path, after[0]))
    assert all(np.array_equal(np.asarray(layer.QueryTimeSample(path, t)), last) for t in after)
    assert main(["validate", str(src), "--layer", str(out)]) in (0, 3)
    assert "OtherTake" not in capsys.readouterr().out


def test_attend_physics_says_a_fall_and_discards_it_when_told(tmp_path, capsys):
    from usdgaze.console.main import main

    # 10 kN straight down on the chest (stage Y up): no controller keeps the pelvis up.
    src = excerpt(tmp_path / "crushed.usda", 0.2, (0.0, 0.2, 0.0), vector=(0.0, -10000.0, 0.0))
    out = tmp_path / "sim.usda"
    once = ["--retry-iterations", "0"]  # a crushed body falls at any iterations: simulated once (retries: below)
    assert main(["attend", str(src), "--out", str(out), "--physics", "--window", "0.3", "--discard-failed", *once]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fell at" in err[0] and "nothing written" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crushed.usda"]
    assert main(["attend", str(src), "--out", str(out), "--physics", "--window", "0.3", *once]) == 0
    printed = capsys.readouterr().out
    assert "fell at" in printed and "(step 0.02 s, window 0.3 s)" in printed and out.is_file()
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert "fell at" in list(layer.customLayerData["usdgaze:physics"][SKEL]["problems"])[0]
    again = tmp_path / "again.usda"  # deterministic, and threads split the work without changing it
    assert main(["attend", str(src), "--out", str(again), "--physics", "--window", "0.3", "--threads", "2", *once]) == 0
    assert again.read_bytes() == out.read_bytes()
    capsys.readouterr()
    assert main(["attend", str(src), "--out", str(tmp_path / "x.usda"), "--physics", "--fd-stride", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--fd-stride" in err[0] and not (tmp_path / "x.usda").exists()
    # The step and the window: the layer's simulated steps are --timestep apart, the window
    # defaults to the physics planner's 0.6 s, and both are recorded with the other settings.
    assert main(["attend", str(src), "--out", str(tmp_path / "x.usda"), "--physics", "--timestep", "0.2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--timestep" in err[0] and not (tmp_path / "x.usda").exists()
    coarse = tmp_path / "coarse.usda"
    assert main(["attend", str(src), "--out", str(coarse), "--physics", "--timestep", "0.03"]) == 0
    printed = capsys.readouterr().out
    data = Sdf.Layer.FindOrOpen(str(coarse)).customLayerData
    steps = np.diff(list(data["usdgaze:physics"][SKEL]["frames"]["seconds"]))
    assert len(steps) >= 5 and np.allclose(steps, 0.03)
    assert dict(data["usdgaze"]["planner"]) == {"mujoco": importlib.metadata.version("mujoco"), "timestep": 0.03,
                                                "window": 0.6, "stonesWindow": 1.0, "iterations": 1,
                                                "retryIterations": 2, "firstIterations": 5, "fdStride": 1,
                                                "fdReuse": 1, "groundFeet": True}
    assert data["usdgaze:physics"][SKEL]["report"]["window_s"] == 0.6  # no stones here
    # --window is every shot's window, stones or not: no stones' window is left to record
    chosen = Sdf.Layer.FindOrOpen(str(again)).customLayerData
    assert chosen["usdgaze"]["planner"]["window"] == 0.3 and "stonesWindow" not in chosen["usdgaze"]["planner"]
    assert chosen["usdgaze:physics"][SKEL]["report"]["window_s"] == 0.3
    # With the defaults the fall was simulated again with two iterations a step and, falling again,
    # with four, and the report says so (the one kept and the others, each of which fell);
    # --retry-iterations 0 simulated the first three runs once; --iterations sets the first.
    assert "otherAttempt" not in layer.customLayerData["usdgaze:physics"][SKEL]
    shot = data["usdgaze:physics"][SKEL]
    others = list(shot["otherAttempt"])
    iterations = {int(a.split(" iteration(s)")[0].split()[-1]) for a in others}
    assert shot["problems"][0].startswith("fell at") and {shot["report"]["iterations"], *iterations} == {1, 2, 4}
    assert len(iterations) == 2 and all(any(a.startswith(f"with {i} iteration(s) a step: fell at") for a in others)
                                        for i in iterations)
    assert "simulated again" in printed
    assert main(["attend", str(src), "--out", str(coarse), "--physics", "--timestep", "0.03", "--iterations", "3",
                 "--retry-iterations", "0"]) == 0
    data = Sdf.Layer.FindOrOpen(str(coarse)).customLayerData
    assert data["usdgaze"]["planner"]["iterations"] == 3 and data["usdgaze"]["planner"]["retryIterations"] == 0
    assert data["usdgaze:physics"][SKEL]["report"]["iterations"] == 3 and "otherAttempt" not in data["usdgaze:physics"][SKEL]


def test_two_tasks_of_one_kind_report_under_their_own_keys():
    """Two balls to catch must not append into one series (it would be twice the shot's length)."""

    class Fake:
        def __init__(self, name, value):
            self.name, self.value = name, value

        def measure(self, k, data):
            return {"m": self.value * k}

    tasks = [Fake("catch", 1.0), Fake("catch", 2.0), Fake("stones", 3.0)]
    measured: dict = {}
    for k in (1, 2, 3):
        measure_tasks(tasks, k, None, measured)
    assert sorted(measured) == ["catch.m", "catch2.m", "stones.m"]
    assert np.array_equal(measured["catch2.m"], [np.nan, 2.0, 4.0, 6.0], equal_nan=True)
    assert all(len(v) == 4 for v in measured.values())


def test_the_lunge_lands_with_no_foot_in_the_floor_where_the_reference_puts_one(tmp_path):
    """The walk's bar on a landing (CMU 131_01, 2.6-3.2 s: the lunge, where the reference's own back
    toe goes 5 cm into the floor), at the walk's h 0.02: no foot point of the written body below the
    ground by more than 2 cm, by UsdSkel FK of the model's foot capsules; the shot's per-step
    ``footBelowGroundM`` (MuJoCo's geoms) agrees with it where their times meet. (The model before the
    foot contacts stiffened with depth also kept this excerpt within 2 cm, 1.5 cm; it failed the whole
    walk on push-offs: docs/physics.md.)"""
    from .obstacle_stages import cut

    src = cut(tmp_path / "lunge.usda", 2.6, 3.2)
    out = tmp_path / "landed.usda"
    report = physics_pass.run(src, out, mpc.Options(h=0.02, horizon_s=0.6))[0]
    composed = compose(tmp_path, src, out)
    src_layer = Sdf.Layer.FindOrOpen(str(src))
    sim, ref = measure.posed(str(composed), SKEL), measure.posed(str(src), SKEL)
    assert not report.fell and ((sim.position("Hips") @ sim.up) / (ref.position("Hips") @ ref.up)).min() >= 0.8
    low, ref_low = lowest_foot_point(src, sim), lowest_foot_point(src, ref)
    assert ref_low.min() < -0.04  # the reference's foot in the floor
    assert low.min() >= -0.02, low.min()
    frames = Sdf.Layer.FindOrOpen(str(out)).customLayerData["usdgaze:physics"][SKEL]["frames"]
    steps = np.array(frames["seconds"]) - frames["seconds"][0]
    t = (sim.times - sim.times[0]) / src_layer.timeCodesPerSecond
    near = np.abs(t[:, None] - steps[None]) < 1e-4  # a frame on a step (within 0.1 ms)
    at, said = near.any(axis=1), np.array(frames["footBelowGroundM"])[near.any(axis=0)]
    assert at.sum() >= 5 and np.abs(np.maximum(0.0, -low[at]) - said).max() < 1e-3
    assert abs(max(frames["footBelowGroundM"]) - max(0.0, -low.min())) < 2e-3  # between steps: interpolated


def test_a_run_that_stops_early_without_a_fall_is_said_to_diverge_not_to_fall():
    """The shot's verdict from its states: a pelvis below 80% of the reference is a fall at that
    frame; a run cut short with the pelvis up (MuJoCo's step blew up) diverged; a whole run with
    the pelvis up is neither. The report says which, in its own words, and a foot deeper than 2 cm."""
    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    from usdgaze.physics import retarget

    q = retarget.to_qpos(model, ref)[:10]
    seconds = np.arange(len(q)) / 50.0
    empty = dict(ctrl=np.zeros((len(q), 1)), depth=np.zeros(len(q)), costs=[], measured={}, h=0.02)
    whole = mpc.shot_result(model, q, q, seconds, steps=len(q) - 1, **empty)
    cut = mpc.shot_result(model, q[:6], q, seconds, steps=len(q) - 1, **empty)
    low = q.copy()
    low[4:, 2] *= 0.5
    fell = mpc.shot_result(model, low, q, seconds, steps=len(q) - 1, **empty)
    assert (whole.fell, whole.diverged) == (False, False)
    assert (cut.fell, cut.diverged, cut.fell_at) == (True, True, seconds[5])
    assert (fell.fell, fell.diverged, fell.fell_at) == (True, False, seconds[4])
    said = lambda r: physics_pass.shot_summary(clip, r, len(r.seconds), 0, 0.0)[0].problems  # noqa: E731
    assert said(whole) == [] and "diverged at 0.10 s" in said(cut)[0] and "fell at 0.08 s" in said(fell)[0]
    assert physics_pass.shot_summary(clip, cut, 6, 0, 0.0)[0].diverged
    # A foot more than 2 cm below the ground is a problem: its depth, when, and on how many steps.
    depth = np.zeros(len(q))
    depth[5:8] = [0.021, 0.025, 0.012]
    sunk = mpc.shot_result(model, q, q, seconds, steps=len(q) - 1, **{**empty, "depth": depth})
    assert said(sunk) == ["a foot 2.5 cm below the ground at 0.12 s (over 2 cm on 2 step(s))"]
    depth[5:8] = 0.0199
    assert said(mpc.shot_result(model, q, q, seconds, steps=len(q) - 1, **{**empty, "depth": depth})) == []


def test_a_rigs_helper_and_secondary_joints_are_written_as_the_reference_has_them(tmp_path):
    """UE5's helpers and chains off the body's frame on a walk (tests/rig_extras.py): twist joints,
    a jaw, a ponytail and a skirt ride welded and the IK joints are not simulated, so the written
    layer holds their animated rotations bit for bit, while the simulated joints' differ from the
    reference; the walk does not fall."""
    from . import synthetic as syn
    from .rig_extras import add_joints, secondary_chains, ue5_helpers

    rig = syn.make_rig(tmp_path / "ue.usda", convention="ue", frames=15, time_codes_per_second=30, mesh=False,
                       joints=50)
    add_joints(rig.path, ue5_helpers(rig) + secondary_chains(rig))
    out = tmp_path / "walked.usda"
    report = physics_pass.run(rig.path, out, mpc.Options(h=0.02))[0]
    assert not report.fell
    src, written = Sdf.Layer.FindOrOpen(str(rig.path)), Sdf.Layer.FindOrOpen(str(out))
    anim = Sdf.Path("/Character/Anim")
    joints = [str(j).rsplit("/", 1)[-1] for j in src.GetAttributeAtPath(anim.AppendProperty("joints")).default]
    helpers = [i for i, j in enumerate(joints) if "twist" in j or j.startswith(("ik_", "jaw", "chin", "hair", "skirt"))]
    moved = [joints.index(j) for j in ("spine_02", "upperarm_l", "thigh_r")]
    path = anim.AppendProperty("rotations")
    times = written.ListTimeSamplesForPath(path)
    assert len(helpers) == 23 and len(times) == 15
    for t in times:
        a, b = np.array(written.QueryTimeSample(path, t)), np.array(src.QueryTimeSample(path, t))
        assert np.array_equal(a[helpers], b[helpers])
    assert any(not np.array_equal(np.array(written.QueryTimeSample(path, t))[moved],
                                  np.array(src.QueryTimeSample(path, t))[moved]) for t in times)


def test_a_shot_with_a_problem_is_simulated_again_and_the_best_attempt_kept():
    """The choice between attempts (``_simulate_shot``), on reports made here: a shot without a
    problem is simulated once; a fall is simulated again with ``retry_iterations``, and while the
    attempt kept still has a problem, once more with twice that; an attempt is kept when it stands,
    or when it fails no worse; a retry that falls where the kept one only missed a stone is dropped.
    The kept report names the other attempts' problems. A problem another simulation cannot mend is
    not simulated again."""
    from usdgaze.passes.physics import ShotReport, _simulate_shot, retry_ladder

    def attempts(outcomes: dict[int, list[str]], depths: dict[int, float] | None = None):
        calls = []

        def attempt(opts):
            calls.append(opts.iterations)
            problems = outcomes[opts.iterations]
            report = ShotReport("s", "a", 10, 1.0, any(p.startswith("fell") for p in problems), None, 1.0, 1.0,
                                (depths or {}).get(opts.iterations, 0.0), 0, 1.0, list(problems),
                                unmendable=[p for p in problems if "never" in p])
            return report, f"override {opts.iterations}", {}, None
        return attempt, calls

    opts = mpc.Options()
    assert retry_ladder(opts) == [2, 4] and retry_ladder(mpc.Options(retry_iterations=6)) == [6, 10]
    assert retry_ladder(mpc.Options(retry_iterations=0)) == [] == retry_ladder(mpc.Options(iterations=2))
    attempt, calls = attempts({1: [], 2: ["fell at 0.5 s"]})
    assert _simulate_shot(attempt, opts)[1] == "override 1" and calls == [1]
    attempt, calls = attempts({1: ["fell at 1.5 s"], 2: []})
    report, override, _, _ = _simulate_shot(attempt, opts)
    assert (override, calls, report.iterations) == ("override 2", [1, 2], 2)
    assert report.other_attempt == ["with 1 iteration(s) a step: fell at 1.5 s"] and report.wall_s == 2.0
    # The second fails too: a third, with twice its iterations, rescues the shot.
    attempt, calls = attempts({1: ["fell at 1.5 s"], 2: ["fell at 1.3 s"], 4: []})
    report, override, _, _ = _simulate_shot(attempt, opts)
    assert (override, calls, report.iterations, report.wall_s) == ("override 4", [1, 2, 4], 4, 3.0)
    assert report.other_attempt == ["with 1 iteration(s) a step: fell at 1.5 s",
                                    "with 2 iteration(s) a step: fell at 1.3 s"]
    attempt, calls = attempts({1: ["toe 6 cm from its stone"], 2: ["fell at 0.9 s"], 4: ["fell at 1.0 s"]})
    report, override, _, _ = _simulate_shot(attempt, opts)
    assert (override, report.iterations, report.problems, calls) == ("override 1", 1, ["toe 6 cm from its stone"],
                                                                     [1, 2, 4])
    assert report.other_attempt == ["with 2 iteration(s) a step: fell at 0.9 s",
                                    "with 4 iteration(s) a step: fell at 1.0 s"]
    attempt, calls = attempts({1: ["fell at 1.5 s"], 2: []})
    assert _simulate_shot(attempt, mpc.Options(retry_iterations=0))[1] == "override 1" and calls == [1]
    # As many problems: the shallower foot is kept (the walk's retry sank 3.6 cm where the first 2.2).
    below = {1: ["a foot 2.2 cm below"], 2: ["a foot 3.6 cm below"], 4: ["a foot 3.0 cm below"]}
    attempt, calls = attempts(below, {1: 0.022, 2: 0.036, 4: 0.030})
    assert _simulate_shot(attempt, opts)[1] == "override 1" and calls == [1, 2, 4]
    attempt, calls = attempts(below, {1: 0.036, 2: 0.030, 4: 0.022})
    assert _simulate_shot(attempt, opts)[1] == "override 4"
    # A problem another simulation cannot mend (a ball never reached for) is not simulated again,
    # unless a mendable one comes with it.
    attempt, calls = attempts({1: ["ball never reached for"], 2: []})
    assert _simulate_shot(attempt, opts)[1] == "override 1" and calls == [1]
    attempt, calls = attempts({1: ["ball never reached for", "fell at 1.5 s"], 2: ["ball never reached for"]})
    assert _simulate_shot(attempt, opts)[1] == "override 2" and calls == [1, 2]


def test_the_simulated_steps_are_a_bar_on_a_terminal_and_nothing_in_a_log(tmp_path):
    """``attend --physics``'s step bar (``StepBar``) through the pass: a crushed shot falls, is
    simulated again twice, and the bar shows the three simulations; off a terminal (where the shot is
    simulated once, to save two simulations) nothing is written for a simulation shorter than a minute
    (tests/test_pipeline.py: a plain line a minute for a longer one)."""
    import io

    from usdgaze.batch.progress import StepBar

    src = excerpt(tmp_path / "crushed.usda", 0.2, (0.0, 0.2, 0.0), vector=(0.0, -10000.0, 0.0))
    term, log = io.StringIO(), io.StringIO()
    for stream, on, retry in ((term, True, 2), (log, None, 0)):
        bar = StepBar(stream, bar=on)
        options = mpc.Options(horizon_s=0.3, retry_iterations=retry)
        report = physics_pass.run(src, tmp_path / f"out{on}.usda", options, progress=bar)[0]
        bar.close()
        assert report.fell and bool(report.other_attempt) == bool(retry) and bar.runs == (3 if on else 1)
    assert all(f"simulation {n}" in term.getvalue() for n in (1, 2, 3)) and "step" in term.getvalue()
    assert log.getvalue() == ""


def test_feet_the_soft_ground_let_sink_are_written_lifted_out_by_their_legs(tmp_path):
    """MuJoCo's soft contacts let a loaded foot sink (docs/physics.md); the pass writes each such foot
    lifted out by its leg. The lunge excerpt simulated twice, with the lift and with ``ground_feet``
    off (``--raw-contacts``), measured by UsdSkel FK of the written layers: the raw feet sink, the
    lifted ones are on the ground (within what nlerp between steps gives); the two layers differ only
    in the thighs and shanks (every other joint, the root's motion included, bit-identical: the same
    simulation); the report's sink is the raw run's depth."""
    from .obstacle_stages import cut

    src = cut(tmp_path / "lunge.usda", 2.6, 3.2)
    reports, lows, rotations = [], [], []
    for ground in (True, False):
        out = tmp_path / f"ground_{ground}.usda"
        reports.append(physics_pass.run(src, out, mpc.Options(h=0.02, horizon_s=0.6, retry_iterations=0,
                                                               ground_feet=ground))[0])
        composed = compose(tmp_path, src, out, f"composed_{ground}.usda")
        lows.append(lowest_foot_point(src, measure.posed(str(composed), SKEL)))
        joints, rot = _locals(composed)
        rotations.append(rot)
        assert Sdf.Layer.FindOrOpen(str(out)).customLayerData["usdgaze"]["planner"]["groundFeet"] is ground
    lifted, raw = lows
    print(f"raw {-raw.min():.4f} lifted {-lifted.min():.4f} report {reports[0].contact_depth_m:.4f}")
    assert raw.min() < -0.005  # the soft ground let a foot sink (0.9 cm when written)
    assert lifted.min() > -0.002
    assert reports[0].contact_depth_m == pytest.approx(reports[1].max_foot_below_ground_m, abs=1e-9)
    assert reports[0].max_foot_below_ground_m < 1e-6
    changed = {joints[j].rsplit("/", 1)[-1] for j in np.flatnonzero((rotations[0] != rotations[1]).any(axis=(0, 2)))}
    legs = {"LeftHip", "LeftKnee", "RightHip", "RightKnee"}  # each foot's parent and grandparent
    assert changed and changed <= legs, changed
