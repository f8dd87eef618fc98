"""What ``attend --physics`` reads of a shot's scene besides the character: stones inside instances,
and pushes only where they act within the shot (a third sweep, 2026-12-06)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, Vt

from usdgaze.passes import physics as physics_pass
from usdgaze.passes import physics_options
from usdgaze.passes.pushes import read_pushes
from usdgaze.physics import build, retarget, stones

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
STONES = {"A": (0.3, 0.0, 0.5), "B": (-0.2, 0.0, 1.1)}


def _shot(path: Path, instanced: bool) -> Path:
    """A shot over the CMU walk with two stones, plain prims or instances of one prototype each."""
    layer = Sdf.Layer.CreateNew(str(path))
    layer.subLayerPaths.append(str(CMU))
    root = Sdf.PrimSpec(layer, "Stones", Sdf.SpecifierDef, "Xform")
    if instanced:
        proto = Sdf.PrimSpec(layer, "StoneProto", Sdf.SpecifierClass, "Xform")
        task = Sdf.PrimSpec(proto, "Stone", Sdf.SpecifierDef, "Xform")
        Sdf.AttributeSpec(task, "usdgaze:physics:task", Sdf.ValueTypeNames.Token).default = "stone"
    for name, at in STONES.items():
        holder = Sdf.PrimSpec(root, name, Sdf.SpecifierDef, "Xform")
        Sdf.AttributeSpec(holder, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = at
        Sdf.AttributeSpec(holder, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:translate"])
        if instanced:
            holder.instanceable = True
            holder.referenceList.prependedItems.append(Sdf.Reference("", "/StoneProto"))
        else:
            stone = Sdf.PrimSpec(holder, "Stone", Sdf.SpecifierDef, "Xform")
            Sdf.AttributeSpec(stone, "usdgaze:physics:task", Sdf.ValueTypeNames.Token).default = "stone"
    layer.Save()
    return path


@pytest.fixture(scope="module")
def walk():
    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    return clip, model, retarget.to_qpos(model, ref)


def _stones_read(path: Path, walk, monkeypatch) -> np.ndarray:
    clip, model, qpos = walk
    seen = []
    monkeypatch.setattr(stones, "factory", lambda centres, *a, **k: seen.append(centres) or (lambda *a: None))
    stage = Usd.Stage.Open(str(path))
    found = physics_pass.task_prims(stage, str(path), clip.skel_root)
    physics_pass.read_tasks(stage, clip, model, str(path), qpos, task_found=found)
    assert len(seen) == 1
    return seen[0]


def test_stones_inside_instances_are_the_stones_the_plain_prims_are(tmp_path, walk, monkeypatch):
    plain = _stones_read(_shot(tmp_path / "plain.usda", False), walk, monkeypatch)
    instanced = _stones_read(_shot(tmp_path / "instanced.usda", True), walk, monkeypatch)
    assert plain.shape == (2, 3) and np.array_equal(instanced, plain)  # were ignored: no stone at all
    # In the model's frame, metres: the authored points, turned (the CMU stage is Y-up, the model Z-up).
    assert np.allclose(sorted(np.linalg.norm(plain, axis=1)), sorted(np.linalg.norm(list(STONES.values()), axis=1)))


def test_a_push_outside_the_shot_is_not_a_push_of_the_shot(walk):
    clip, model, _ = walk
    shot = clip.frames(100, 200)  # time codes 101-200
    stage = Usd.Stage.CreateInMemory()
    root = stage.DefinePrim("/Body", "SkelRoot")
    root.CreateAttribute("usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).Set("Chest")
    force = root.CreateAttribute("usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3)
    for t, f in ((10.0, (150.0, 0.0, 0.0)), (20.0, (0.0, 0.0, 0.0)),  # before the shot
                 (90.0, (0.0, 0.0, 80.0)), (110.0, (0.0, 0.0, 0.0)),  # held into it
                 (150.0, (0.0, 60.0, 0.0)), (160.0, (0.0, 0.0, 0.0)),  # within it
                 (300.0, (40.0, 0.0, 0.0))):  # after it
        force.Set(f, t)
    pushes = read_pushes(root, shot, model, "shot")
    # start_s counts from the shot's first frame (101), where its simulation starts: counted from the
    # stage's start, every push came 100 time codes late.
    starts = [round(p.start_s * clip.time_codes_per_second + shot.times[0], 6) for p in pushes]
    assert starts == [90.0, 150.0]


def test_a_shot_gets_its_tasks_window_and_step_unless_they_are_chosen(tmp_path):
    """The paper sets the window and the step by task: a shot with stepping stones is simulated with
    ``stones_horizon_s`` (1.0 s), any other with ``horizon_s`` (0.6 s); one with a ball to catch or
    obstacles and no stones at ``moving_h`` (0.03 s), any other at ``h`` (0.02 s); a window or step the
    user chooses (``--window``, ``--timestep``, a manifest's keys) is every shot's. A bad stones' window is
    one line naming it."""
    from usdgaze.errors import UsdGazeError
    from usdgaze.physics import mpc

    stage = Usd.Stage.Open(str(_shot(tmp_path / "plain.usda", False)))
    found = physics_pass.task_prims(stage, "plain.usda", "/root")
    assert [len(found["stone"]), len(found["obstacle"])] == [2, 0]
    bare = {"stone": [], "obstacle": []}
    default = mpc.Options()
    assert (default.horizon_s, default.stones_horizon_s) == (0.6, 1.0)
    assert physics_options.shot_options(default, found).horizon_s == 1.0
    assert physics_options.shot_options(default, bare) is default
    chosen = physics_options.with_window(default, 0.7)
    assert physics_options.shot_options(chosen, found).horizon_s == 0.7 == physics_options.shot_options(chosen, bare).horizon_s
    assert physics_options.with_window(default, None) is default
    # The step by task (the paper's 0.02 or 0.03 s): a ball to catch or obstacles without stones get 0.03.
    moving = {"stone": [], "obstacle": ["an obstacle"]}
    assert physics_options.shot_options(default, moving).h == 0.03 == physics_options.shot_options(default, bare, True).h
    assert physics_options.shot_options(default, found, True).h == 0.02 == physics_options.shot_options(default, bare).h
    fixed = physics_options.with_timestep(default, 0.025)  # --timestep: every shot's
    assert physics_options.shot_options(fixed, moving).h == 0.025 == physics_options.shot_options(fixed, found).h
    assert physics_options.with_timestep(default, None) is default
    # A window holds two of the longest step a shot may get.
    with pytest.raises(UsdGazeError, match=r"^--window 0\.05 s: expected 0\.06 to 5 s"):
        physics_options.check_window(mpc.Options(stones_horizon_s=0.05), "--window")
    physics_options.check_window(physics_options.with_timestep(mpc.Options(stones_horizon_s=0.05), 0.02), "--window")


def test_a_push_names_its_joint_by_the_skeletons_joint_names_too(tmp_path):
    """``pushJoint = "mixamorig:Spine1"``, the DCC's name (the Skeleton's jointNames), which no joint
    token can spell: "is not a simulated joint", where ``--bind`` takes that name. It pushes the body of
    the joint whose token is ``mixamorig_Spine1``, as the token itself does."""
    from tests import synthetic as syn
    from usdgaze.usd.skelio import read_clip

    rig = syn.make_rig(tmp_path / "rig.usda", frames=20, mesh=False, walk_speed=0.0)
    stage = Usd.Stage.Open(str(rig.path))
    root = stage.GetPrimAtPath(rig.skel_root)
    clip = read_clip(stage, stage.GetPrimAtPath(rig.skeleton), root, str(rig.path))
    model, _ = build.body_model(clip)
    names = list(stage.GetPrimAtPath(rig.skeleton).GetAttribute("jointNames").Get())
    token = rig.joint("spine_b")
    dcc = names[rig.joints.index(token)]
    assert ":" in dcc and not Sdf.Path.IsValidPathString(dcc)  # a name no token can be
    force = root.CreateAttribute("usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3)
    force.Set((150.0, 0.0, 0.0), 5.0)
    force.Set((0.0, 0.0, 0.0), 10.0)
    joint = root.CreateAttribute("usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token)
    bodies = []
    for name in (dcc, token.rsplit("/", 1)[-1]):
        joint.Set(name)
        (push,) = read_pushes(root, clip, model, "rig")
        bodies.append(push.body)
    assert bodies[0] == bodies[1] == model.body_of(rig.joints.index(token)) >= 0
