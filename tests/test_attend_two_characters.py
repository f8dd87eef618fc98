"""``usdgaze attend`` on two characters (SkelRoots with a GazeMapAPI) and one ball: the report says,
per character, what that character saw. Before, the per-object figures were overwritten by each
character in turn, so the JSON and the printout held only the last character's view.

Two standing characters face the same way, the second 3 m ahead of the first; the ball is 1.5 m in
front of the first one's eyes, i.e. behind the second. Which of them has it in view (within 60 deg of its head's forward) is measured
independently by UsdSkel FK on the input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main
from usdgaze.errors import UsdGazeError
from usdgaze.passes import visuomotor

from . import measure
from . import synthetic as syn
from .attend_support import compose

MAP = Path(__file__).resolve().parents[1] / "sample_stages" / "shared_map" / "gaze_map.usda"


def _stage(tmp: Path, names=("A", "B"), place=((0.0, 0.0, 0.0), (0.0, 0.0, 3.0))) -> tuple[Path, syn.Rig]:
    """Two characters ``names`` (SkelRoot paths without the slash) at the translations ``place``."""
    rig = syn.make_rig(tmp / "rig.usda", frames=24, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    shutil.copy(MAP, tmp / "gaze_map.usda")
    layer = Sdf.Layer.CreateNew(str(tmp / "two.usda"))
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(layer, key, getattr(src, key))
    for key in ("upAxis", "metersPerUnit"):
        layer.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    cls = Sdf.CreatePrimInLayer(layer, "/Map")
    cls.specifier = Sdf.SpecifierClass
    cls.referenceList.Prepend(Sdf.Reference("./gaze_map.usda", "/GazeMap"))
    for name, at in zip(names, place):  # by default B stands 3 m ahead of A, its back to A
        prim = Sdf.CreatePrimInLayer(layer, f"/{name}")
        for parent in Sdf.Path(f"/{name}").GetParentPath().GetPrefixes():  # a character under a prim
            layer.GetPrimAtPath(parent).specifier = Sdf.SpecifierDef
        prim.specifier, prim.typeName = Sdf.SpecifierDef, "SkelRoot"
        prim.referenceList.Prepend(Sdf.Reference("./rig.usda", "/Character"))
        prim.inheritPathList.Prepend(Sdf.Path("/Map"))
        Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(*at)
        Sdf.AttributeSpec(prim, "xformOp:rotateY", Sdf.ValueTypeNames.Float).default = 0.0
        Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          variability=Sdf.VariabilityUniform).default = ["xformOp:translate", "xformOp:rotateY"]
    layer.Save()
    return tmp / "two.usda", rig


def _add_ball(stage: Path, at) -> None:
    layer = Sdf.Layer.FindOrOpen(str(stage))
    Sdf.CreatePrimInLayer(layer, "/Objects").specifier = Sdf.SpecifierDef
    ball = Sdf.CreatePrimInLayer(layer, "/Objects/Ball")
    ball.specifier, ball.typeName = Sdf.SpecifierDef, "Sphere"
    ball.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    Sdf.AttributeSpec(ball, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(*map(float, at))
    Sdf.AttributeSpec(ball, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    layer.Save()


def _off_head_deg(stage: Path, rig: syn.Rig, root: str, ball) -> float:
    p = measure.posed(str(stage), f"{root}/Skel")
    head = rig.leaf["head"]
    fwd = p.axis(head, measure.local_forward(p, head, rig.forward))[0]
    eyes = 0.5 * (p.position(rig.leaf["eye_l"])[0] + p.position(rig.leaf["eye_r"])[0])
    to = (ball - eyes) / np.linalg.norm(ball - eyes)
    return float(np.degrees(np.arccos(np.clip(fwd @ to, -1, 1))))


def test_each_character_reports_what_it_saw(tmp_path, capsys):
    stage, rig = _stage(tmp_path)
    p = measure.posed(str(stage), "/A/Skel")
    eyes_a = 0.5 * (p.position(rig.leaf["eye_l"])[0] + p.position(rig.leaf["eye_r"])[0])
    ball = eyes_a + np.array([0.2, 0.0, 1.5])
    _add_ball(stage, ball)
    assert _off_head_deg(stage, rig, "/A", ball) < 30.0  # in A's view
    assert _off_head_deg(stage, rig, "/B", ball) > 120.0  # behind B

    out = tmp_path / "attend.usdc"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.3", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    by_root = {c["skel_root"]: c["objects"] for c in report["characters"]}
    assert set(by_root) == {"/A", "/B"}
    assert by_root["/A"][0]["path"] == "/Objects/Ball" and by_root["/A"][0]["first_seen_s"] == 0.0
    assert by_root["/B"][0]["first_seen_s"] is None
    assert {(o["skel_root"], o["first_seen_s"]) for o in report["objects"]} == {("/A", 0.0), ("/B", None)}


def test_a_skelroot_with_two_skeletons_says_which_one_attend_plans(tmp_path, capsys):
    """attend plans one pair of eyes per SkelRoot: the first Skeleton. The others were left as they
    are without a word; now said, and the layer holds no opinion on them (muted or not, their poses
    are the input's, by UsdSkel FK)."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=24, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    Sdf.CopySpec(layer, rig.skeleton, layer, rig.skeleton + "2")
    Sdf.CopySpec(layer, rig.animation, layer, rig.animation + "2")
    layer.GetPrimAtPath(rig.skeleton + "2").relationships["skel:animationSource"].targetPathList.explicitItems = [
        Sdf.Path(rig.animation + "2")]
    ball = Sdf.CreatePrimInLayer(layer, "/World/Ball")
    ball.specifier, ball.typeName = Sdf.SpecifierDef, "Xform"
    layer.GetPrimAtPath("/World").specifier = Sdf.SpecifierDef
    layer.Save()
    out, preview = tmp_path / "gaze.usdc", tmp_path / "preview.usda"
    preview_layer = Sdf.Layer.CreateNew(str(preview))
    for sub in ("./gaze.usdc", "./in.usda"):
        preview_layer.subLayerPaths.append(sub)
    preview_layer.Save()
    assert main(["attend", str(rig.path), "--objects", "/World/Ball", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"2 Skeletons under this SkelRoot; attend plans the first, {rig.skeleton}" in err
    second = rig.skeleton + "2"
    before, after = measure.posed(str(rig.path), second), measure.posed(str(preview), second)
    assert np.array_equal(before.world, after.world)
    first_before, first_after = measure.posed(str(rig.path), rig.skeleton), measure.posed(str(preview), rig.skeleton)
    assert not np.array_equal(first_before.world, first_after.world)  # the first one is planned


def test_characters_whose_paths_spell_the_same_name_both_get_inspection_prims(tmp_path):
    """/A_B and /A/B both become ``A_B`` under /UsdGazeAttend: the second character's inspection prims
    were authored over the first's and the command failed (exit 1, an Sdf error). Each character now
    has its own scope, and both look at the ball (UsdSkel FK on the written layer)."""
    stage, rig = _stage(tmp_path, names=("A_B", "A/B"), place=((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)))
    p = measure.posed(str(stage), "/A_B/Skel")
    ball = 0.5 * (p.position(rig.leaf["eye_l"])[0] + p.position(rig.leaf["eye_r"])[0]) + np.array([0.5, 0.0, 2.0])
    _add_ball(stage, ball)
    out = tmp_path / "attend.usda"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.3"]) == 0
    layer = Sdf.Layer.FindOrOpen(str(out))
    scopes = layer.GetPrimAtPath("/UsdGazeAttend").nameChildren
    assert len(scopes) == 2 and all(s.attributes.get("gaze:attend:pointOfSight") for s in scopes)
    composed = compose(tmp_path, stage, out)
    for root in ("/A_B", "/A/B"):
        g = measure.posed(str(composed), f"{root}/Skel")
        eye_l, eye_r = rig.leaf["eye_l"], rig.leaf["eye_r"]
        line = measure.sight_line(g, eye_l, eye_r, measure.local_forward(g, eye_l, rig.forward),
                                  measure.local_forward(g, eye_r, rig.forward))
        to = ball - 0.5 * (g.position(eye_l) + g.position(eye_r))
        off = measure.angle_between(line, to / np.linalg.norm(to, axis=1, keepdims=True))
        assert off[-6:].max() < 5.0, (root, off)


def _facing(tmp_path) -> tuple[Path, syn.Rig]:
    """A and B 3 m apart along z and 1 m apart sideways, B turned to face A: each one's eyes look past
    the other's face (18 deg sideways) until it turns."""
    stage, rig = _stage(tmp_path, place=((0.0, 0.0, 0.0), (1.0, 0.0, 3.0)))
    layer = Sdf.Layer.FindOrOpen(str(stage))
    layer.GetPrimAtPath("/B").attributes["xformOp:rotateY"].default = 180.0  # turned to face A
    layer.Save()
    return stage, rig


def _off_face_deg(composed: Path, rig: syn.Rig, me: str, other: str) -> np.ndarray:
    """Per frame, degrees between ``me``'s line of sight and the direction from its eyes' midpoint to
    ``other``'s eyes' midpoint, both by UsdSkel FK on the composed result (where the other's face is)."""
    g, o = measure.posed(str(composed), f"{me}/Skel"), measure.posed(str(composed), f"{other}/Skel")
    eye_l, eye_r = rig.leaf["eye_l"], rig.leaf["eye_r"]
    line = measure.sight_line(g, eye_l, eye_r, measure.local_forward(g, eye_l, rig.forward),
                              measure.local_forward(g, eye_r, rig.forward))
    to = 0.5 * (o.position(eye_l) + o.position(eye_r)) - 0.5 * (g.position(eye_l) + g.position(eye_r))
    return measure.angle_between(line, to / np.linalg.norm(to, axis=1, keepdims=True))


def test_two_characters_look_at_each_other(tmp_path, capsys):
    """GazeObjectAPI on both SkelRoots, facing each other 3 m apart (1 m aside): each character looks at
    the other's face (refused before: "is the character /B or holds it", as if B's own object were A's
    too). Where the eyes end is measured by UsdSkel FK on the composed result, against the other's eyes'
    midpoint: 20 deg off at the start, 0.2-0.7 deg over the last 6 frames. Before, a character object
    was its bounds' centre, mid-body: the eyes ended 14.9-15.4 deg off the other's face (below it)."""
    stage, rig = _facing(tmp_path)
    layer = Sdf.Layer.FindOrOpen(str(stage))
    for name in ("/A", "/B"):
        layer.GetPrimAtPath(name).SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    layer.Save()
    out = tmp_path / "attend.usda"
    assert main(["attend", str(stage), "--out", str(out), "--window", "0.3", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert {c["skel_root"]: [o["path"] for o in c["objects"]] for c in report["characters"]} == {
        "/A": ["/B"], "/B": ["/A"]}
    assert all(o["first_seen_s"] == 0.0 for o in report["objects"])  # each face is in the other's view
    composed = compose(tmp_path, stage, out)
    for me, other in (("/A", "/B"), ("/B", "/A")):
        off = _off_face_deg(composed, rig, me, other)
        assert off[0] > 10.0 and off[-6:].max() < 3.0, (me, off)  # it turns to the other's face


def test_look_at_another_character_ends_on_its_face(tmp_path, capsys):
    """``apply --look-at /B@T``: A's line of sight ends on B's eyes' midpoint (UsdSkel FK on the composed
    result): 0-1 deg over the last 6 frames, from 20 deg; before, B's bounds' centre mid-body, 14-16 deg
    off B's face."""
    stage, rig = _facing(tmp_path)
    out = tmp_path / "gaze.usda"
    start = float(Sdf.Layer.FindOrOpen(str(stage)).startTimeCode)
    assert main(["apply", str(stage), "--skel-root", "/A", "--look-at", f"/B@{start:g}", "--out", str(out)]) == 0
    assert "cannot be found" not in capsys.readouterr().err
    off = _off_face_deg(compose(tmp_path, stage, out), rig, "/A", "/B")
    assert off[0] > 10.0 and off[-6:].max() < 3.0, off


def test_a_character_without_a_head_is_looked_at_in_its_bounds_and_said(tmp_path, capsys):
    """B a rig whose joints no name binds (``bone_000`` ..., no eyes): no head is found, so its bounds'
    centre stays the target (UsdGeom.BBoxCache on the input), said in one warning line naming /B."""
    from pxr import Usd, UsdGeom

    stage, rig = _facing(tmp_path)
    syn.make_rig(tmp_path / "bones.usda", frames=24, time_codes_per_second=24, mesh=False, walk_speed=0.0,
                 convention="generic", eyes=False, joint_names=False)
    layer = Sdf.Layer.FindOrOpen(str(stage))
    b = layer.GetPrimAtPath("/B")
    b.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    b.referenceList.prependedItems = [Sdf.Reference("./bones.usda", "/Character")]
    layer.Save()
    out = tmp_path / "attend.usda"
    assert main(["attend", str(stage), "--out", str(out), "--skel-root", "/A", "--window", "0.3"]) == 0
    said = [w for w in capsys.readouterr().err.splitlines() if "cannot be found" in w]
    assert len(said) == 1 and "two.usda:/B: a character whose eyes cannot be found" in said[0], said
    composed, source = compose(tmp_path, stage, out), Usd.Stage.Open(str(stage))
    g = measure.posed(str(composed), "/A/Skel")
    eye_l, eye_r = rig.leaf["eye_l"], rig.leaf["eye_r"]
    line = measure.sight_line(g, eye_l, eye_r, measure.local_forward(g, eye_l, rig.forward),
                              measure.local_forward(g, eye_r, rig.forward))
    centre = np.array([UsdGeom.BBoxCache(Usd.TimeCode(float(t)), [UsdGeom.Tokens.default_], useExtentsHint=True)
                       .ComputeWorldBound(source.GetPrimAtPath("/B")).ComputeCentroid() for t in g.times])
    to = centre - 0.5 * (g.position(eye_l) + g.position(eye_r))
    off = measure.angle_between(line, to / np.linalg.norm(to, axis=1, keepdims=True))
    assert off[-6:].max() < 3.0, off


def test_a_character_left_nothing_to_look_at_is_one_line(tmp_path, capsys):
    """B the only object: A looks at B, B has nothing to look at (it is not its own object)."""
    stage, _ = _stage(tmp_path)
    layer = Sdf.Layer.FindOrOpen(str(stage))
    layer.GetPrimAtPath("/B").SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    layer.Save()
    out = tmp_path / "attend.usda"
    assert main(["attend", str(stage), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("two.usda:/B: has nothing to look at: every object is this character or "
                                             "holds it; give it another object, or leave it out with --skel-root"), err
    assert not out.exists()
    assert main(["attend", str(stage), "--out", str(out), "--skel-root", "/A", "--window", "0.3"]) == 0


def test_two_simulated_characters_each_see_the_other(tmp_path):
    """``attend --physics`` reads each character's objects as ``attend`` does: with GazeObjectAPI on both
    SkelRoots, A's coupled loop sees B and B's sees A (the physics pass refused it, "is the character /A
    or holds it", since every object was checked against each character in turn); an object that is the
    only character simulated is one line."""
    stage, _ = _facing(tmp_path)
    layer = Sdf.Layer.FindOrOpen(str(stage))
    for name in ("/A", "/B"):
        layer.GetPrimAtPath(name).SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    layer.Save()
    opened = Usd.Stage.Open(str(stage))
    roots = [opened.GetPrimAtPath(p) for p in ("/A", "/B")]
    seen = {str(r.GetPath()): visuomotor.read_scene(r, str(stage), roots)[1] for r in roots}
    assert seen == {"/A": ["/B"], "/B": ["/A"]}
    # Only A simulated: it sees B; A itself, an object of nobody else, is refused in one line.
    with pytest.raises(UsdGazeError, match=r":/A: is the character /A or holds it"):
        visuomotor.read_scene(roots[0], str(stage), roots[:1])
