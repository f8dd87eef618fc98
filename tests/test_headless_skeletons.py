"""A face's (or a prop's) Skeleton beside the body's under one SkelRoot: no head, so no character.
``apply`` refused the whole SkelRoot ('1 of 2 skeleton(s) cannot bind'), ``attend`` planned whichever
came first (here the face's, and stopped), ``inspect`` exited 2. Now each leaves it as it is, says
so in a warning, and turns the body; alone, such a skeleton is still refused with its advice."""

from __future__ import annotations

from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from usdgaze.console.main import main
from usdgaze.passes.physics_shots import read_shots
from usdgaze.physics import mpc

from . import measure
from . import synthetic as syn


def _with_face(tmp_path, first: bool = True, body: bool = True):
    """The small rig with a 2-joint ``Face`` Skeleton (jaw, lip) under its SkelRoot, listed first."""
    r = syn.make_rig(tmp_path / "in.usda", frames=30, mesh=False)
    stage = Usd.Stage.Open(str(r.path))
    face = UsdSkel.Skeleton.Define(stage, f"{r.skel_root}/Face")
    face.CreateJointsAttr(Vt.TokenArray(["jaw", "jaw/lip"]))
    face.CreateBindTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1), Gf.Matrix4d(1)]))
    face.CreateRestTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1), Gf.Matrix4d(1)]))
    if not body:
        stage.RemovePrim(r.skeleton)
    ball = UsdGeom.Sphere.Define(stage, "/World/Ball")
    ball.AddTranslateOp().Set(Gf.Vec3d(0.6, 1.5, 1.0))
    stage.Save()
    if first:
        layer = Sdf.Layer.FindOrOpen(str(r.path))
        spec = layer.GetPrimAtPath(r.skel_root)
        spec.nameChildrenOrder = ["Face"] + [c.name for c in spec.nameChildren if c.name != "Face"]
        layer.Save()
    return r


def test_apply_turns_the_body_and_leaves_the_face(tmp_path, capsys):
    r = _with_face(tmp_path)
    before = measure.sha256(r.path)
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(r.path), "--shift", "0.2s:30:0", "--out", str(tmp_path / "g.usda"),
                 "--preview", str(preview)]) == 0
    err = capsys.readouterr().err
    assert f"{r.skel_root}/Face: no head among its joints, so no character: left as it is" in err, err
    out = Sdf.Layer.FindOrOpen(str(tmp_path / "g.usda"))
    assert out.GetPrimAtPath(f"{r.skel_root}/Face") is None  # nothing written for the face
    head = r.leaf["head"]
    base, new = measure.posed(str(r.path), r.skeleton), measure.posed(str(preview), r.skeleton)
    turned = measure.rotation_angle_deg(new.world[:, new.index(head), :3, :3], base.world[:, base.index(head), :3, :3])
    assert turned.max() > 5.0  # the body's head turned (its share of 30 deg)
    assert measure.sha256(r.path) == before
    assert main(["inspect", str(r.path)]) == 0
    assert "no character (no head" in capsys.readouterr().out


def test_attend_plans_the_body_though_the_face_comes_first(tmp_path, capsys):
    r = _with_face(tmp_path)
    assert main(["attend", str(r.path), "--objects", "/World/Ball", "--out", str(tmp_path / "a.usda")]) == 0
    err = capsys.readouterr().err
    assert f"{r.skel_root}/Face: no head among its joints" in err and "plans the first" not in err, err
    out = Sdf.Layer.FindOrOpen(str(tmp_path / "a.usda"))
    assert out.GetPrimAtPath(r.animation) is not None and out.GetPrimAtPath(f"{r.skel_root}/Face") is None


def test_the_physics_pass_reads_the_body_alone(tmp_path):
    r = _with_face(tmp_path)
    notes: list[str] = []
    shots = read_shots(Usd.Stage.Open(str(r.path)), str(r.path), None, mpc.Options(), None, notes=notes)
    assert [s.clip.skeleton for s in shots] == [r.skeleton]
    assert len(notes) == 1 and f"{r.skel_root}/Face: no head" in notes[0]


def test_a_face_skeleton_alone_is_still_refused(tmp_path, capsys):
    r = _with_face(tmp_path, body=False)
    assert main(["apply", str(r.path), "--shift", "0.2s:30:0", "--out", str(tmp_path / "g.usda")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Face: no gaze chain (pelvis and head) found by name: no head" in err[0], err
    assert not (tmp_path / "g.usda").exists()
    assert main(["inspect", str(r.path)]) == 2


def test_physics_model_builds_the_body_not_the_face(tmp_path, capsys):
    """It took the SkelRoot's first Skeleton, the face's: 'no feet ... the physics body stands on its feet'."""
    r = _with_face(tmp_path)
    assert main(["physics-model", str(r.path), "--out", str(tmp_path / "m.xml")]) == 0
    assert capsys.readouterr().out.strip().endswith(f"from {r.skeleton}")
    import mujoco

    assert mujoco.MjModel.from_xml_path(str(tmp_path / "m.xml")).njnt > 10


def test_a_skel_root_without_a_skeleton_is_one_line_for_the_physics_pass(tmp_path, capsys):
    """No Skeleton under the only SkelRoot: the headless rule's reader stopped on an IndexError (exit 1)."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "in.usda"))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdSkel.Root.Define(stage, "/Character")
    stage.Save()
    assert main(["attend", str(tmp_path / "in.usda"), "--physics", "--out", str(tmp_path / "o.usda")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"usdgaze: error: {tmp_path / 'in.usda'}: no Skeleton to simulate"], err
    assert not (tmp_path / "o.usda").exists()
