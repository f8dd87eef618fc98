"""``physics-model`` on rigs that mirror one joint by a negative scale (an eye, a leg), measured
against UsdSkel's own forward kinematics.

Some rigs mirror one side's joints (a scale of -1 along an axis in the rest and bind transforms and
the animation's scales). Before, any such joint made ``physics-model`` (and ``attend --physics``) fail
with exit 1, an internal error ("non-positive determinant ... in a rotation matrix"). A mirrored eye
is welded in the body and now rides as the input has it: the model's joints stand where UsdSkel puts
them. A mirrored leg, whose knee and foot the body would turn the other way round than the skeleton,
is refused in one line naming the joints, exit 2.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np

from . import measure, rig_extras
from . import synthetic as syn


def _rig(tmp: Path, leaf_key: str):
    rig = syn.make_rig(tmp / "rig.usda", convention="mixamo", up_axis="Y", meters_per_unit=0.01, frames=12,
                       mesh=False, walk_speed=0.0, time_codes_per_second=30.0)
    rig_extras.mirror_joint(rig.path, rig.skeleton, rig.animation, rig.leaf[leaf_key])
    return rig


def _physics_model(stage: Path, out: Path):
    return subprocess.run([sys.executable, "-m", "usdgaze", "physics-model", str(stage), "--out", str(out),
                           "--mass", "80"], capture_output=True, text=True)


def test_a_mirrored_eye_is_modelled_where_usdskel_puts_the_joints(tmp_path):
    rig = _rig(tmp_path, "eye_r")
    p = measure.posed(str(rig.path), rig.skeleton)
    eye = p.index(rig.leaf["eye_r"])
    assert np.linalg.det(p.rest_skel[eye, :3, :3]) < 0  # the rig really is mirrored there
    before = measure.sha256(rig.path)
    r = _physics_model(rig.path, tmp_path / "model.xml")
    assert r.returncode == 0, r.stderr
    assert measure.sha256(rig.path) == before
    mj = mujoco.MjModel.from_xml_path(str(tmp_path / "model.xml"))
    d = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, d)
    assert abs(mj.body_mass[1:].sum() - 80.0) < 1e-3  # the MJCF prints 6 digits
    # Expected: UsdSkel rest FK in stage units -> MuJoCo's Z-up metres ((x, y, z) -> (x, -z, y)).
    rest_world = p.rest_skel @ p.skel_to_world
    leaves = [j.rsplit("/", 1)[-1] for j in p.joints]
    names = {mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b): b for b in range(1, mj.nbody)}
    got, want = [], []
    for name, b in names.items():
        hits = [i for i, leaf in enumerate(leaves) if leaf.replace(":", "_").endswith(name)]
        if len(hits) == 1:
            got.append(d.xpos[b])
            x = rest_world[hits[0], 3, :3] * 0.01
            want.append([x[0], -x[2], x[1]])
    got, want = np.array(got), np.array(want)
    assert len(got) >= 20 and np.isfinite(got).all()
    err = np.linalg.norm((got - got.mean(0)) - (want - want.mean(0)), axis=1)
    assert err.max() < 0.01, err.max()


def test_a_mirrored_leg_is_refused_in_one_line(tmp_path):
    rig = _rig(tmp_path, "thigh_r")
    r = _physics_model(rig.path, tmp_path / "model.xml")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "mirrored" in lines[0] and rig.leaf["thigh_r"] in lines[0], lines
    assert not (tmp_path / "model.xml").exists()
