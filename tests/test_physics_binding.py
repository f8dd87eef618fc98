"""``attend --physics`` binds the gaze chain as ``apply`` does (--bind/--forward, GazeMapAPI, names), and
its floating base is the pelvis also on a rig whose names say nothing.

On a rig with numbered joints: without hints nothing says which joint is the head, so the command
stops with one line before any simulation; a hint naming a joint the skeleton lacks is one line
naming it. The model's base is the joint where legs and spine part, found from the tree alone."""

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

    # By hand: root on the ground with the pelvis and a prop joint beside it, toes, a heel end site.
    from usdgaze.physics.model import _base_joint

    parents = np.array([-1, 0, 0, 1, 3, 4, 1, 6, 7, 1, 9, 4])
    heights = np.array([0.0, 1.0, 0.05, 0.5, 0.08, 0.0, 0.5, 0.08, 0.0, 1.3, 1.7, 0.0])
    names = [f"j{i}" for i in range(len(parents))]
    assert _base_joint(names, parents, heights) == 1
    # A name still wins: a joint called pelvis is the base wherever the legs meet.
    assert _base_joint(["root", "a", "b", "Pelvis", *names[4:]], parents, heights) == 3
