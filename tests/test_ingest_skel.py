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
