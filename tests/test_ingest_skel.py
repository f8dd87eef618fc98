"""UsdSkel example clips: binding the chain by name or explicitly, and clear errors when it cannot be."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from usdgaze.core import rotations as rot
from usdgaze.ingest import BuildSettings, build

from . import ingest_synth as syn

TARGETS = np.array([[108.0, 12.0], [-144.0, 0.0], [36.0, -12.0]])
CUSTOM = {"Hips": "root", "Spine": "sA", "Spine1": "sB", "Spine2": "sC", "Neck": "nk", "Head": "skull",
          "LeftUpLeg": "thighA", "RightUpLeg": "thighB", "LeftShoulder": "armA", "RightShoulder": "armB"}


def _session(directory, rename=None, extra=""):
    motions = syn.known_motions(TARGETS)
    rows = [extra]
    for i, (yaw, pitch) in enumerate(TARGETS):
        m = motions[i]
        frames = 40 + int(round((float(m.duration) + 0.8) * syn.RATE))
        syn.write_skel_clip(directory / f"t{i}.usda", m, 40, frames, rename=rename)
        rows.append(f'[[trial]]\nname = "t{i}"\nfile = "t{i}.usda"\nyaw = {yaw:g}\npitch = {pitch:g}\n')
    (directory / "sheet.toml").write_text("\n".join(rows))
    return motions, directory / "sheet.toml"


def _pose_errors(motions, result):
    assert all(r.status == "ok" for r in result.reports), [r.error for r in result.reports]
    return np.degrees(rot.angle(rot.relative(motions.offsets, result.definition.motions.offsets)))


def test_mixamo_prefixed_names_bind_by_themselves(tmp_path):
    rename = {k: f"mixamorig_{k}" for k in CUSTOM}
    motions, sheet = _session(tmp_path, rename)
    result = build(sheet)
    assert _pose_errors(motions, result).max() <= 0.5
    # start times at the known t_j wherever a segment clearly moves (the shifts begin at frame 40); a
    # start is not before the crop, whose first still frame can come a frame or two after the neck's t_j
    checked = 0
    for i, report in enumerate(result.reports):
        m = motions[i]
        truth = syn.TrialTruth(report.trial, *TARGETS[i], m, 40, 0, syn.RATE)
        clear = truth.local_speeds()[1].max(axis=0) >= 2 * BuildSettings().start_speed_deg_s
        known = np.maximum(truth.frame_of(m.starts[:4]) - report.crop[0], 0.0)
        starts = report.extraction.start_frames
        assert np.all(np.abs(starts - known)[clear] <= 1.0), (report.trial, starts, known)
        checked += int(clear.sum())
    assert checked >= 6


def test_unknown_names_are_a_clear_error_until_bound(tmp_path):
    motions, sheet = _session(tmp_path, CUSTOM)
    result = build(sheet, settings=BuildSettings(min_trials=1))
    assert result.definition is None
    for report in result.reports:
        assert report.error.startswith(f"trial {report.trial} ({report.trial}.usda): no gaze chain (pelvis and head) found by name")
        assert "\n" not in report.error
    # bound in the sheet, with the forward given since no joint says left or right
    text = sheet.read_text()
    sheet.write_text('[skeleton]\npelvis = "root"\nlower_spine = "sA"\nupper_spine = "sC"\nneck = "nk"\nhead = "skull"\n'
                     "forward = [0.0, -1.0, 0.0]\n" + text)
    assert _pose_errors(motions, build(sheet)).max() <= 0.5


def test_binding_a_missing_joint_names_it(tmp_path):
    _, sheet = _session(tmp_path, extra='[skeleton]\nhead = "Skull"\n')
    result = build(sheet, settings=BuildSettings(min_trials=1))
    assert all("skeleton.head = 'Skull' is not a joint of the skeleton" in r.error for r in result.reports)


def test_a_stage_without_an_animated_skeleton(tmp_path):
    stage = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    UsdGeom.Xform.Define(stage, "/World")
    stage.Save()
    (tmp_path / "sheet.csv").write_text("file,yaw,pitch\nempty.usda,36,0\n")
    (report,) = build(tmp_path / "sheet.csv", settings=BuildSettings(min_trials=1)).reports
    assert report.error == "trial empty (empty.usda): no Skeleton with a bound SkelAnimation"


def test_sparse_keyframes_are_sampled_every_time_code(tmp_path):
    """An artist's clip keyed every 4th frame reads at the stage's rate, not a quarter of it."""
    from pxr import Sdf

    from usdgaze.ingest.skelclips import read_skeleton_series

    motions = syn.known_motions(TARGETS[:1])
    frames = 40 + int(round((float(motions.duration[0]) + 0.8) * syn.RATE))
    frames += (4 - (frames - 1) % 4) % 4  # keep the last frame a key
    path = tmp_path / "keys.usda"
    syn.write_skel_clip(path, motions[0], 40, frames)
    dense = read_skeleton_series(path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    for attr in ("rotations", "translations"):
        spec = Sdf.Path(f"/Rig/Skel/Anim.{attr}")
        for t in range(frames):
            if t % 4:
                layer.EraseTimeSample(spec, float(t))
    layer.Save()
    sparse = read_skeleton_series(path)
    assert sparse.rate == dense.rate == syn.RATE
    assert sparse.frames == dense.frames == frames
    # keys agree exactly; in between UsdSkel interpolates the keys
    keys = np.arange(0, frames, 4)
    np.testing.assert_allclose(np.degrees(rot.angle(rot.relative(sparse.orientations[keys], dense.orientations[keys]))), 0.0, atol=1e-3)


def _generic_tokens(path) -> None:
    """Joint tokens j0/j1/... on the Skeleton and its SkelAnimation, the names moved to jointNames
    (how some exporters write a rig)."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(path))
    joints = [str(j) for j in layer.GetAttributeAtPath("/Rig/Skel.joints").default]
    index = {j: i for i, j in enumerate(joints)}
    tokens = ["/".join(f"j{index['/'.join(j.split('/')[:k + 1])]}" for k in range(j.count("/") + 1)) for j in joints]
    layer.GetAttributeAtPath("/Rig/Skel.joints").default = tokens
    Sdf.AttributeSpec(layer.GetPrimAtPath("/Rig/Skel"), "jointNames", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = [j.rsplit("/", 1)[-1] for j in joints]
    anim = layer.GetAttributeAtPath("/Rig/Skel/Anim.joints")
    anim.default = [tokens[index[str(j)]] for j in anim.default]
    layer.Save()


def test_generic_joint_tokens_bind_by_joint_names(tmp_path):
    """A rig whose joint tokens say nothing (j0/j1/...) binds by the Skeleton's jointNames and
    builds the same map as the named rig."""
    rename = {k: f"mixamorig_{k}" for k in CUSTOM}
    motions, sheet = _session(tmp_path, rename)
    named = build(sheet)
    for i in range(len(TARGETS)):
        _generic_tokens(tmp_path / f"t{i}.usda")
    assert "j0/j1" in (tmp_path / "t0.usda").read_text()
    generic = build(sheet)
    errors = _pose_errors(motions, generic)
    assert errors.max() <= 0.5
    np.testing.assert_allclose(generic.definition.motions.offsets, named.definition.motions.offsets, atol=1e-12)


def test_colon_namespaced_joints_are_said_as_apply_says_them(tmp_path, capfd):
    """Joint tokens with Maya's namespace colon ('mixamorig:Hips') are no paths to UsdSkel: the trial's
    error says so, as apply does, and USD does not warn once per joint first (it said 'no pelvis above
    head', after six 'Ill-formed SdfPath' warnings)."""
    _, sheet = _session(tmp_path, {k: f"mixamorig:{k}" for k in CUSTOM})
    result = build(sheet, settings=BuildSettings(min_trials=1))
    assert result.definition is None
    for report in result.reports:
        assert report.error.startswith(f"trial {report.trial} ({report.trial}.usda): /"), report.error
        assert ".joints: 'mixamorig:Hips' is not a valid joint path" in report.error
    assert "Ill-formed SdfPath" not in capfd.readouterr().err


def test_a_rig_turned_by_its_animated_skelroot_keeps_that_turn(tmp_path):
    """A DCC's root or world control exports as an animated transform above the Skeleton: the body turns
    with it. Each clip here turns its SkelRoot 15 deg about the stage's up (Z) over the shift, on top of
    the joints' known motion: the pelvis' P+ (a world displacement) holds that turn and the segments
    above it, relative to their parents, are as they were. Measured in skeleton space alone, the turn
    was lost (the pelvis off by 15 deg, the eyes asked to make it up)."""
    from pxr import UsdGeom

    motions, sheet = _session(tmp_path)
    turn = 15.0
    for i in range(len(TARGETS)):
        stage = Usd.Stage.Open(str(tmp_path / f"t{i}.usda"))
        op = UsdGeom.Xformable(stage.GetPrimAtPath("/Rig")).AddRotateZOp()
        span = float(motions[i].duration) * syn.RATE
        for frame in range(int(stage.GetEndTimeCode()) + 1):
            u = np.clip((frame - 40) / span, 0.0, 1.0)
            op.Set(turn * u * u * (3.0 - 2.0 * u), frame)
        stage.Save()
    result = build(sheet)
    assert all(r.status == "ok" for r in result.reports), [r.error for r in result.reports]
    built = result.definition.motions.offsets
    yaw = rot.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.radians(turn))  # canonical up: a turn to the left
    expected = motions.offsets.copy()
    expected[:, 0] = rot.multiply(yaw, expected[:, 0])
    errors = np.degrees(rot.angle(rot.relative(expected[:, :4], built[:, :4])))
    assert errors.max() <= 0.5, errors


def test_a_rig_hidden_by_a_zero_scale_for_a_while_builds_as_it_was(tmp_path):
    """A SkelRoot scaled to nothing over a clip's last frames (hidden) has no turn there: the map is the
    one of the clip left visible (the turn of a singular transform was an internal error)."""
    from pxr import UsdGeom

    motions, sheet = _session(tmp_path)
    before = build(sheet).definition.motions
    for i in range(len(TARGETS)):
        stage = Usd.Stage.Open(str(tmp_path / f"t{i}.usda"))
        op = UsdGeom.Xformable(stage.GetPrimAtPath("/Rig")).AddScaleOp()
        end = int(stage.GetEndTimeCode())
        op.Set((1.0, 1.0, 1.0), end - 3)
        op.Set((0.0, 0.0, 0.0), end - 2)
        stage.Save()
    after = build(sheet).definition.motions
    np.testing.assert_allclose(after.offsets, before.offsets, atol=1e-9)
    np.testing.assert_allclose(after.timing, before.timing, atol=1e-9)


def test_a_sheet_row_naming_an_earlier_rows_file_and_crop_is_warned_of(tmp_path):
    """A row copied and its file left unchanged stored one motion for two targets without a word (the
    eyes made up the difference); another crop of the same file is another motion and is not warned of."""
    _session(tmp_path)
    (tmp_path / "sheet.csv").write_text(
        "trial,file,yaw,pitch,crop_start,crop_end\na,t0.usda,108,12,,\nb,t0.usda,100,12,,\nc,t0.usda,90,12,30,70\n")
    result = build(tmp_path / "sheet.csv", settings=BuildSettings(min_trials=1))
    assert [r.status for r in result.reports] == ["ok", "ok", "ok"], [r.error for r in result.reports]
    same = [[w for w in r.warnings if "same file and crop" in w] for r in result.reports]
    assert same == [[], ["the same file and crop as trial a: one motion stored for two targets"], []]
    assert result.reports[1].crop == result.reports[0].crop != result.reports[2].crop


def test_a_clip_whose_animation_usdskel_cannot_pose_is_refused_as_apply_refuses_it(tmp_path, capfd):
    """UsdSkel poses the rest pose (with a C++ warning) where an animation lacks an array, or a sample
    holds the wrong count: one clip was refused as 'no motion', another stored 'ok' with a frame of its
    crop in the rest pose. Each is now the line apply gives for it."""
    from pxr import Vt

    _session(tmp_path)
    stage = Usd.Stage.Open(str(tmp_path / "t0.usda"))
    stage.GetPrimAtPath("/Rig/Skel/Anim").RemoveProperty("scales")
    stage.Save()
    stage = Usd.Stage.Open(str(tmp_path / "t1.usda"))
    rotations = stage.GetPrimAtPath("/Rig/Skel/Anim").GetAttribute("rotations")
    rotations.Set(Vt.QuatfArray(list(rotations.Get(60))[:5]), 60)
    stage.Save()
    reports = build(tmp_path / "sheet.toml", settings=BuildSettings(min_trials=1)).reports
    assert [r.status for r in reports] == ["failed", "failed", "ok"]
    assert reports[0].error == (f"trial t0 (t0.usda): {tmp_path / 't0.usda'}:/Rig/Skel/Anim.scales: not authored "
                                "(UsdSkel needs translations, rotations and scales for every animated joint)")
    assert reports[1].error.startswith(f"trial t1 (t1.usda): {tmp_path / 't1.usda'}:/Rig/Skel/Anim.rotations: 5 entries at time 60")
    assert "Warning" not in capfd.readouterr().err


def test_an_animation_bound_on_the_skelroot_is_read_as_usdskel_binds_it(tmp_path):
    """skel:animationSource on the SkelRoot is inherited by its Skeleton (UsdSkel poses it; apply reads
    it): build-map said 'no Skeleton with a bound SkelAnimation'. The map is the one bound on the Skeleton."""
    from pxr import UsdSkel

    _, sheet = _session(tmp_path)
    before = build(sheet).definition.motions
    for i in range(len(TARGETS)):
        stage = Usd.Stage.Open(str(tmp_path / f"t{i}.usda"))
        stage.GetPrimAtPath("/Rig/Skel").RemoveProperty("skel:animationSource")
        UsdSkel.BindingAPI.Apply(stage.GetPrimAtPath("/Rig")).CreateAnimationSourceRel().SetTargets(["/Rig/Skel/Anim"])
        stage.Save()
    result = build(sheet)
    assert [r.status for r in result.reports] == ["ok"] * len(TARGETS), [r.error for r in result.reports]
    np.testing.assert_array_equal(result.definition.motions.offsets, before.offsets)


def test_a_mirrored_clip_turns_as_the_world_shows_it(tmp_path):
    """A clip mirrored by a negative scale on its SkelRoot (a right turn made a left one, to double a
    session) turns the head the other way in the world: with the sheet's yaws negated to match, its map
    is the unmirrored map's mirror image (each P+ reflected across the character's left axis). Read in
    skeleton space, its head turned the other way from its target (stored 'ok', eyes past their range)."""
    from pxr import UsdGeom

    motions, sheet = _session(tmp_path)
    rows = []
    for i, (yaw, pitch) in enumerate(TARGETS):
        stage = Usd.Stage.Open(str(tmp_path / f"t{i}.usda"))
        xform = UsdGeom.Xformable(stage.GetPrimAtPath("/Rig"))
        xform.AddRotateZOp().Set(40.0)
        xform.AddScaleOp().Set((-1.0, 1.0, 1.0))
        stage.Save()
        rows.append(f'[[trial]]\nname = "t{i}"\nfile = "t{i}.usda"\nyaw = {-yaw:g}\npitch = {pitch:g}\n')
    sheet.write_text("\n".join(rows))
    result = build(sheet)
    assert all(r.status == "ok" and not any("other way" in w for w in r.warnings) for r in result.reports), \
        [(r.error, r.warnings) for r in result.reports]
    mirrored = motions.offsets[:, :4] * np.array([1.0, -1.0, -1.0, 1.0])  # (x, y, z, w) across canonical X (left)
    errors = np.degrees(rot.angle(rot.relative(mirrored, result.definition.motions.offsets[:, :4])))
    assert errors.max() <= 0.5, errors


def test_a_skeleton_table_may_name_a_generic_rigs_joint_by_its_token(tmp_path):
    """On a rig bound by its jointNames, ``[skeleton] head = "jN"`` (the token, as ``inspect`` lists
    it) was looked for among the names alone: 'not a joint of the skeleton'."""
    rename = {k: f"mixamorig_{k}" for k in CUSTOM}
    motions, sheet = _session(tmp_path, rename)
    named = build(sheet)
    for i in range(len(TARGETS)):
        _generic_tokens(tmp_path / f"t{i}.usda")
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "t0.usda"))
    names = list(layer.GetAttributeAtPath("/Rig/Skel.jointNames").default)
    sheet.write_text(f'[skeleton]\nhead = "j{names.index("mixamorig_Head")}"\n' + sheet.read_text())
    generic = build(sheet)
    assert _pose_errors(motions, generic).max() <= 0.5
    np.testing.assert_allclose(generic.definition.motions.offsets, named.definition.motions.offsets, atol=1e-12)
