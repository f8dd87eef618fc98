"""Binding on real-world rigs with no hints, the neutral pose from the bind pose, and hints for the rest.

Rigs (tests/synthetic.py, names from tests/synthetic_names.py) carry the naming schemes studios
have: Mixamo (``mixamorig:Spine1``), a game rig numbering every joint (``b_Spine01_02``,
``b_Neck_04``, ``b_Head_05``), Rigify (``DEF-spine.003``), 3ds Max Biped (``Bip01 Head``), Character
Creator (``CC_Base_NeckTwist01``), VRoid (``J_Bip_C_Head``), DAZ Genesis (``abdomenLower``, ``lEye``),
Unreal (``spine_01``), Maya AdvancedSkeleton (``Root_M``, ``Hip_L`` a thigh), and a quadruped whose
spine runs horizontally, Z up and Y up. Every number is
measured with UsdSkel's forward kinematics on the composed result, head and eye axes taken from
UsdSkel's bind pose (tests/measure.py), never from usdgaze's math.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Vt

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.core.hints import parse_hints
from usdgaze.errors import UsdGazeError
from usdgaze.passes.shift import PassOptions

from . import measure
from . import synthetic as syn
from .test_pass_rigs import hold_windows, sight_change

SHIFTS = ["0.3s:40:0", "2.1s:-40:-10"]
SECONDS, RATE = 3.9, 30

SCHEMES = {
    "mixamo": dict(convention="mixamo"),
    "indexed-b_": dict(convention="indexed", up_axis="Z"),
    "rigify": dict(convention="rigify", up_axis="Z"),
    "biped-Bip01-cm": dict(convention="biped", eyes=False, up_axis="Z", meters_per_unit=0.01),
    "biped-legs-off-the-spine": dict(convention="biped", eyes=False, legs_on="spine_a"),
    "cc-base": dict(convention="cc"),
    "vroid": dict(convention="vroid"),
    "daz": dict(convention="daz", meters_per_unit=0.01),
    "unreal": dict(convention="ue", up_axis="Z", meters_per_unit=0.01),
    "advancedskeleton": dict(convention="advanced"),
    "quadruped-Z": dict(convention="quadruped", body="quadruped", up_axis="Z", turn_deg_per_s=6),
    "quadruped-Y": dict(convention="quadruped", body="quadruped", up_axis="Y"),
}


def _measured(rig: syn.Rig, report, preview: Path):
    base = measure.posed(str(rig.path), rig.skeleton)
    new = measure.posed(str(preview), rig.skeleton)
    change, _ = sight_change(base, new, rig)
    errors = []
    for s, hold in hold_windows(dict(rig=rig, base=base, report=report)):
        assert hold.sum() >= 10, s
        errors.append(np.abs(change[hold] - [s["yaw"], s["pitch"]]).max())
    return base, new, max(errors)


@pytest.fixture(scope="module", params=sorted(SCHEMES))
def run(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    rig = syn.make_rig(d / "in.usda", frames=int(SECONDS * RATE), time_codes_per_second=RATE, mesh=False,
                       **SCHEMES[request.param])
    report = api.apply(rig.path, SHIFTS, d / "gaze.usdc", preview=d / "preview.usda")
    return dict(name=request.param, rig=rig, report=report, dir=d)


def test_binds_with_no_hints_to_the_right_joints(run):
    rig, c = run["rig"], run["report"].characters[0]
    leaves = {role: [j.rsplit("/", 1)[-1] for j in joints] for role, joints in c.chain.items()}
    # Legs hanging off the first spine joint make it turn with the pelvis (3ds Max Biped).
    pelvis = ["pelvis", "spine_a"] if SCHEMES[run["name"]].get("legs_on") == "spine_a" else ["pelvis"]
    assert leaves["head"] == [rig.leaf["head"]] and leaves["pelvis"] == [rig.leaf[k] for k in pelvis]
    spine = [rig.leaf[k] for k in ("spine_a", "spine_b", "spine_c") if k in rig.leaf and k not in pelvis]
    neck = [rig.leaf[k] for k in ("neck", "neck_b") if k in rig.leaf]
    assert leaves["lowerSpine"] + leaves["upperSpine"] == spine and leaves["lowerSpine"] and leaves["upperSpine"]
    assert leaves["neck"] == neck
    if rig.has_eyes:
        assert (leaves["leftEye"], leaves["rightEye"]) == ([rig.leaf["eye_l"]], [rig.leaf["eye_r"]])
        assert c.added_joints == []
    assert np.allclose(c.forward, rig.forward, atol=1e-6)
    assert run["report"].warnings == []


def test_a_40_degree_shift_holds_within_half_a_degree_and_the_feet_stay(run):
    rig = run["rig"]
    base, new, error = _measured(rig, run["report"], run["dir"] / "preview.usda")
    assert error <= 0.5, error
    for k in ("knee_l", "ankle_r", "toe_l"):  # the hind feet, on the quadruped
        moved_m = np.linalg.norm(new.position(rig.leaf[k]) - base.position(rig.leaf[k]), axis=1) * rig.meters_per_unit
        assert moved_m.max() < 1e-3, (k, moved_m.max())


# -- the neutral pose -------------------------------------------------------------------------------

def test_neutral_is_the_bind_pose_when_rest_is_the_first_frame(tmp_path):
    """Blender writes restTransforms as the export frame; the actor looks 12 deg aside and 8 deg down there."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=int(SECONDS * RATE), time_codes_per_second=RATE, mesh=False,
                       rest_pose="first_frame", look_aside_deg=(12.0, 8.0))
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda")
    _, _, error = _measured(rig, report, tmp_path / "preview.usda")
    assert error <= 0.5, error
    # The test can tell: the same result measured against the rest pose is off by degrees.
    base = measure.posed(str(rig.path), rig.skeleton, neutral="rest")
    new = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton, neutral="rest")
    change, _ = sight_change(base, new, rig)
    off = [np.abs(change[hold] - [s["yaw"], s["pitch"]]).max() for s, hold in
           hold_windows(dict(rig=rig, base=base, report=report))]
    assert max(off) > 2.0, off


def _edit_bind(rig: syn.Rig, kind: str) -> None:
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    if kind == "missing":
        del layer.GetPrimAtPath(rig.skeleton).properties["bindTransforms"]
    else:
        spec = layer.GetAttributeAtPath(rig.skeleton + ".bindTransforms")
        mats = list(spec.default)
        if kind == "short":
            mats = mats[:-3]
        elif kind == "one-point":  # an exporter's placeholder: every joint at the origin
            mats = [Sdf.ValueTypeNames.Matrix4d.defaultValue] * len(mats)
        else:
            mats[3] = Sdf.ValueTypeNames.Matrix4d.defaultValue * (0.0 if kind == "singular" else float("nan"))
        spec.default = Vt.Matrix4dArray(mats)
    layer.Save()


@pytest.mark.parametrize("kind", ["missing", "one-point"])
def test_a_bind_pose_that_says_nothing_falls_back_to_the_rest_pose(tmp_path, kind):
    rig = syn.make_rig(tmp_path / "in.usda", frames=int(SECONDS * RATE), time_codes_per_second=RATE, mesh=False)
    _edit_bind(rig, kind)
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda")
    if kind == "one-point":  # authored but unusable: said
        assert len(report.warnings) == 1 and "neutral pose from restTransforms (bindTransforms puts every joint" \
            in report.warnings[0]
    else:
        assert report.warnings == []
    base = measure.posed(str(rig.path), rig.skeleton, neutral="rest")
    new = measure.posed(str(tmp_path / "preview.usda"), rig.skeleton, neutral="rest")
    change, _ = sight_change(base, new, rig)
    for s, hold in hold_windows(dict(rig=rig, base=base, report=report)):
        assert np.abs(change[hold] - [s["yaw"], s["pitch"]]).max() <= 0.5


def test_added_eyes_extend_only_the_poses_the_input_authors(tmp_path):
    """A rest-only skeleton without eyes: the layer adds the eye joints and extends restTransforms,
    but authors no bindTransforms (a bind pose the input lacks would change how meshes skin)."""
    rig = syn.make_rig(tmp_path / "in.usda", eyes=False, frames=int(SECONDS * RATE), time_codes_per_second=RATE,
                       mesh=False)
    _edit_bind(rig, "missing")
    api.apply(rig.path, SHIFTS, tmp_path / "gaze.usda")
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "gaze.usda"))
    skel = layer.GetPrimAtPath(rig.skeleton)
    joints = list(skel.attributes["joints"].default)
    assert len(joints) == len(rig.joints) + 2 and joints[:len(rig.joints)] == rig.joints
    assert len(skel.attributes["restTransforms"].default) == len(joints)
    assert "bindTransforms" not in skel.attributes


@pytest.mark.parametrize("kind", ["short", "singular", "nan"])
def test_broken_bind_transforms_are_refused(tmp_path, kind):
    rig = syn.make_rig(tmp_path / "in.usda", frames=30, mesh=False)
    _edit_bind(rig, kind)
    with pytest.raises(UsdGazeError) as err:
        api.apply(rig.path, SHIFTS[:1], tmp_path / "gaze.usdc")
    assert f"{rig.skeleton}.bindTransforms: " in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "gaze.usdc").exists()


def test_a_mirrored_skelroot_turns_head_and_eyes_the_same_way(tmp_path):
    """A SkelRoot scaled (-1, 1, 1), as a mirrored crowd copy is: its skeleton's left is the world's
    right. A yaw is toward the character's left as the world sees it, for the eyes and the head alike."""
    from pxr import Gf, Usd, UsdGeom

    rig = syn.make_rig(tmp_path / "in.usda", frames=int(SECONDS * RATE), time_codes_per_second=RATE, mesh=False)
    stage = Usd.Stage.Open(str(rig.path))
    UsdGeom.Xformable(stage.GetPrimAtPath(rig.skel_root)).AddScaleOp().Set(Gf.Vec3f(-1.0, 1.0, 1.0))
    stage.GetRootLayer().Save()
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda")
    base, new, error = _measured(rig, report, tmp_path / "preview.usda")
    assert error <= 0.5, error  # the line of sight: both shifts reached, eyes within their range
    head = rig.leaf["head"]
    axis = measure.local_forward(base, head, rig.forward)
    turn = measure.wrap(measure.az_el(new.axis(head, axis), new.up)[:, 0] - measure.az_el(base.axis(head, axis), base.up)[:, 0])
    for s, hold in hold_windows(dict(rig=rig, base=base, report=report)):
        assert np.all(np.sign(turn[hold]) == np.sign(s["yaw"])) and np.abs(turn[hold]).min() > 5.0, (s, turn[hold])


def test_an_animation_bound_on_the_skelroot_is_the_skeletons(tmp_path):
    """``skel:animationSource`` authored on the SkelRoot: UsdSkel's binding inherits it down to the
    Skeleton, and so does the pass."""
    from pxr import Usd, UsdSkel

    rig = syn.make_rig(tmp_path / "in.usda", frames=int(SECONDS * RATE), time_codes_per_second=RATE, mesh=False)
    stage = Usd.Stage.Open(str(rig.path))
    UsdSkel.BindingAPI(stage.GetPrimAtPath(rig.skeleton)).GetAnimationSourceRel().ClearTargets(True)
    UsdSkel.BindingAPI.Apply(stage.GetPrimAtPath(rig.skel_root)).CreateAnimationSourceRel().SetTargets([rig.animation])
    stage.GetRootLayer().Save()
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda")
    base, new, error = _measured(rig, report, tmp_path / "preview.usda")
    assert error <= 0.5, error
    assert not np.allclose(base.world, new.world)  # UsdSkel poses the skeleton with the override


# -- hints ------------------------------------------------------------------------------------------

def _numbered(d: Path) -> syn.Rig:
    return syn.make_rig(d / "in.usda", convention="numbered", frames=int(SECONDS * RATE), time_codes_per_second=RATE,
                        mesh=False)


def test_an_unnamed_rig_binds_with_hints(tmp_path):
    rig = _numbered(tmp_path)
    with pytest.raises(UsdGazeError) as err:  # no hints: the error lists what it considered
        api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc")
    assert "no gaze chain" in str(err.value) and "joints: j0, j1, j2" in str(err.value) and "--bind" in str(err.value)
    assert not (tmp_path / "gaze.usdc").exists()
    leaf = rig.leaf
    hints = parse_hints([f"pelvis={leaf['pelvis']}", f"head={leaf['head']}", f"leftEye={leaf['eye_l']}",
                         f"rightEye={leaf['eye_r']}"], ",".join(f"{v:g}" for v in rig.forward))
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda",
                       options=PassOptions(binding=hints))
    c = report.characters[0]
    assert [j.rsplit("/", 1)[-1] for j in c.chain["neck"]] == [leaf["neck_b"]]  # the last joint before the head
    assert np.allclose(c.forward, rig.forward)
    _, _, error = _measured(rig, report, tmp_path / "preview.usda")
    assert error <= 0.5, error


@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_a_forward_of_any_length_is_its_direction(tmp_path, scale):
    """``--forward`` is a direction: 1e300 or 1e-300 times it gives the layer the unit vector gives
    (its squared length would overflow or vanish if taken as given)."""
    rig = _numbered(tmp_path)
    leaf = rig.leaf
    bind = [f"pelvis={leaf['pelvis']}", f"head={leaf['head']}", f"leftEye={leaf['eye_l']}", f"rightEye={leaf['eye_r']}"]
    unit = rig.forward / np.linalg.norm(rig.forward)
    for name, vec in (("unit", unit), ("scaled", unit * scale)):
        api.apply(rig.path, SHIFTS, tmp_path / f"{name}.usdc",
                  options=PassOptions(binding=parse_hints(bind, ",".join(repr(float(v)) for v in vec))))
    assert (tmp_path / "unit.usdc").read_bytes() == (tmp_path / "scaled.usdc").read_bytes()


@pytest.mark.parametrize("bind, forward, message", [
    (["head=j99"], None, "--bind head=j99: 'j99' is not a joint of this skeleton"),
    (["pelvis=j1", "head=j5"], None, "cannot tell the character's forward"),
    (["pelvis=j1", "head=j5"], "0,1,0", "--forward is parallel to the stage up axis"),
])
def test_bad_hints_are_one_line_errors(tmp_path, bind, forward, message):
    rig = _numbered(tmp_path)
    with pytest.raises(UsdGazeError) as err:
        api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", options=PassOptions(binding=parse_hints(bind, forward)))
    assert message in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "gaze.usdc").exists()


@pytest.mark.parametrize("bind, forward, message", [
    (["head"], None, "--bind 'head': expected ROLE=JOINT[+JOINT...]"),
    (["head="], None, "--bind 'head=': expected ROLE=JOINT[+JOINT...]"),
    (["neck=a+"], None, "--bind 'neck=a+'"),
    (["skull=j5"], None, "unknown role 'skull'"),
    (["head=j5", "head=j6"], None, "role given twice"),
    (None, "0,0", "expected three finite numbers"),
    (None, "0,0,nan", "expected three finite numbers"),
    (None, "0,0,0", "the zero vector is no direction"),
    ({"neck": []}, None, "--bind.neck: expected a joint name or a list of joint names"),
])
def test_hint_syntax_errors(bind, forward, message):
    with pytest.raises(UsdGazeError) as err:
        parse_hints(bind, forward)
    assert message in str(err.value)


def test_hints_from_a_table_and_a_list_mean_the_same():
    a = parse_hints(["neck=j3+j4", "head=j5"], "0,0,1")
    b = parse_hints({"neck": ["j3", "j4"], "head": "j5"}, [0, 0, 1])
    assert a.as_dict() == b.as_dict() == {"neck": ("j3", "j4"), "head": ("j5",)} and a.forward == b.forward == (0, 0, 1)


# -- the command line and batch manifests -------------------------------------------------------------

CLI = [sys.executable, "-m", "usdgaze"]
ROOT = Path(__file__).resolve().parents[1]


def _without_batch_key(path: Path) -> str:
    """The layer as text, less the resume key the batch records (everything else must match the API's)."""
    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    data = dict(layer.customLayerData)
    assert data["usdgaze"].pop("batchKey")
    layer.customLayerData = data
    return layer.ExportToString()


def test_bind_and_forward_on_the_command_line_and_in_a_manifest_give_the_api_layer(tmp_path):
    rig = _numbered(tmp_path)
    leaf = rig.leaf
    flags = [f"pelvis={leaf['pelvis']}", f"head={leaf['head']}", f"neck={leaf['neck']}+{leaf['neck_b']}"]
    forward = ",".join(f"{v:g}" for v in rig.forward)
    api.apply(rig.path, SHIFTS, tmp_path / "api.usdc", options=PassOptions(binding=parse_hints(flags, forward)))

    argv = ["apply", str(rig.path), *(a for s in SHIFTS for a in ("--shift", s)), "--out", str(tmp_path / "cli.usdc")]
    p = subprocess.run([*CLI, *argv, *(a for f in flags for a in ("--bind", f)), "--forward", forward],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "cli.usdc").read_bytes() == (tmp_path / "api.usdc").read_bytes()
    # The layer records the hints, so the review tools bind the chain as the pass did.
    from usdgaze.review.composed import read_review

    record = Sdf.Layer.FindOrOpen(str(tmp_path / "cli.usdc")).customLayerData["usdgaze"]
    assert list(record["bind"]) == flags and list(record["forward"]) == list(map(float, rig.forward))
    (character,) = read_review(rig.path, tmp_path / "cli.usdc").characters
    assert character.chain.head == rig.joints.index(rig.joint("head"))

    table = ", ".join(f'{r} = "{j[0]}"' for r, j in parse_hints(flags[:2]).bindings)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text(
        f'[[job]]\nname = "good"\ninput = "in.usda"\nout = "batch.usdc"\nshifts = {SHIFTS!r}\n'.replace("'", '"')
        + f'bind = {{ {table}, neck = ["{leaf["neck"]}", "{leaf["neck_b"]}"] }}\nforward = {list(map(float, rig.forward))}\n'
        + '\n[[job]]\nname = "absent"\ninput = "in.usda"\nout = "absent.usdc"\nshifts = ["0.3s:40:0"]\n'
        + 'bind = ["head=j99"]\nforward = "0,0,1"\n')
    p = subprocess.run([*CLI, "batch", str(manifest)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr  # the second job names an absent joint
    assert _without_batch_key(tmp_path / "batch.usdc") == Sdf.Layer.OpenAsAnonymous(str(tmp_path / "api.usdc")).ExportToString()
    assert not (tmp_path / "absent.usdc").exists()
    assert "bind head=j99: 'j99' is not a joint of this skeleton" in p.stderr

    manifest.write_text('[[job]]\ninput = "in.usda"\nout = "x.usdc"\nshifts = ["1:2:3"]\nbind = ["skull=j5"]\n')
    p = subprocess.run([*CLI, "batch", str(manifest)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stderr.strip().count("\n") == 0 and "job 0: bind skull=...: unknown role" in p.stderr


# -- names, without a stage ----------------------------------------------------------------------------

@pytest.mark.parametrize("name, words", [
    ("b_Spine01_02", ("b", "spine", "01", "02")),
    ("mixamorig_Spine1", ("mixamorig", "spine", "1")),
    ("DEF_spine_003", ("def", "spine", "003")),
    ("Bip01_Head", ("bip", "01", "head")),
    ("CC_Base_NeckTwist01", ("cc", "base", "neck", "twist", "01")),
    ("J_Bip_C_Head", ("j", "bip", "c", "head")),
    ("LHipJoint", ("l", "hip", "joint")),
    ("lowerback", ("lower", "back")),
    ("Hips/Spine/lEye", ("l", "eye")),
])
def test_joint_names_split_into_words(name, words):
    from usdgaze.core.names import tokens

    assert tokens(name) == words


def _chain(paths: list[str], **bindings):
    from usdgaze.core.rig import bind_chain

    parents = np.array([paths.index(p.rsplit("/", 1)[0]) if "/" in p else -1 for p in paths])
    chain = bind_chain(paths, parents, {r: (j,) for r, j in bindings.items()})
    return {r: [paths[i].rsplit("/", 1)[-1] for i in idx] for r, idx in chain.roles.items()}, chain


def test_pelvis_is_the_named_joint_above_the_head_where_the_legs_hang():
    # Character Creator: legs under CC_Base_Pelvis, a sibling of the spine under CC_Base_Hip.
    cc = ["Root", "Root/Hip", "Root/Hip/Pelvis", "Root/Hip/Pelvis/L_Thigh", "Root/Hip/Pelvis/R_Thigh",
          "Root/Hip/Waist", "Root/Hip/Waist/Spine01", "Root/Hip/Waist/Spine01/Spine02",
          "Root/Hip/Waist/Spine01/Spine02/NeckTwist01", "Root/Hip/Waist/Spine01/Spine02/NeckTwist01/Head"]
    roles, chain = _chain(cc)
    assert roles["pelvis"] == ["Hip"] and roles["lowerSpine"] == ["Waist"] and roles["upperSpine"] == ["Spine01", "Spine02"]
    assert [cc[i].rsplit("/", 1)[-1] for i in chain.leg_roots] == ["Pelvis"]  # it counter-rotates, legs and all
    # Hips > Pelvis > Spine: the legs hang off the deeper one.
    nested = ["Hips", "Hips/Pelvis", "Hips/Pelvis/thigh_l", "Hips/Pelvis/thigh_r", "Hips/Pelvis/Spine",
              "Hips/Pelvis/Spine/Spine1", "Hips/Pelvis/Spine/Spine1/Neck", "Hips/Pelvis/Spine/Spine1/Neck/Head"]
    roles, chain = _chain(nested)
    assert roles["pelvis"] == ["Pelvis"] and len(chain.leg_roots) == 2


def test_shape_finds_what_names_do_not_say():
    # No head or pelvis by name: the head is the eyes' parent, the pelvis where mirrored legs branch off.
    paths = ["a", "a/b", "a/b/leg_L", "a/b/leg_R", "a/b/c", "a/b/c/d", "a/b/c/d/e", "a/b/c/d/e/f",
             "a/b/c/d/e/f/eye_L", "a/b/c/d/e/f/eye_R", "a/b/c/d/e/f/eyelid_L"]
    roles, chain = _chain(paths)
    assert roles["head"] == ["f"] and roles["pelvis"] == ["b"]
    assert roles["lowerSpine"] == ["c"] and roles["upperSpine"] == ["d"] and roles["neck"] == ["e"]
    assert roles["leftEye"] == ["eye_L"] and roles["rightEye"] == ["eye_R"]
    assert "parent of the eye joints" in chain.reasons["head"] and "legs" in chain.reasons["pelvis"]


def test_bind_names_a_joint_by_its_path_or_any_spelling_of_its_name():
    paths = ["mixamorig_Hips", "mixamorig_Hips/x1", "mixamorig_Hips/x1/x2", "mixamorig_Hips/x1/x2/x3",
             "mixamorig_Hips/x1/x2/x3/x4"]
    for head in ("x4", "mixamorig_Hips/x1/x2/x3/x4", "X4"):
        roles, chain = _chain(paths, head=head)
        assert roles["head"] == ["x4"] and chain.reasons["head"] == "gaze:binding:head"
    roles, _ = _chain(paths, head="x4", pelvis="mixamorig:Hips")  # the DCC's spelling
    assert roles["pelvis"] == ["mixamorig_Hips"]
