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


def test_the_floating_base_is_where_the_tree_branches_below_a_root_on_the_ground(tmp_path):
    from usdgaze.physics import model as body_model

    rig = _rig(tmp_path)
    joints = list(rig.joints)  # the tokens the rig generator wrote, skeleton order
    parents = np.array([joints.index(j.rsplit("/", 1)[0]) if "/" in j else -1 for j in joints])
    base = body_model._base_joint(joints, parents)
    # Independently: the pelvis the rig generator placed, whose children are the legs and the spine.
    assert joints[base].rsplit("/", 1)[-1] == rig.leaf["pelvis"], (joints[base], rig.leaf["pelvis"])
    assert (parents == base).sum() >= 2
