"""A marker set whose up_axis is not the capture's (a Y-up export, read with the
default Z): every trial was stored 'ok' with the eyes past their range and a map written, exit 0.
The subject stands upright at rest, so the head lies above the base of the spine in the capture's
true up: a marker set that says otherwise is bad input, refused before anything is written."""

from __future__ import annotations

import numpy as np

from usdgaze.console.main import main

from . import ingest_synth as syn

PARAMS = np.array([[-72.0, 0.0], [108.0, 0.0], [36.0, 12.0]])


def _session(tmp_path, capture_up: str, markerset_up: str):
    session = syn.write_c3d_session(tmp_path, seed=2, params=PARAMS)
    if capture_up == "Y":  # the same lab, exported Y-up: (x, y, z) -> (x, z, -y)
        for tr in session.trials:
            import ezc3d

            c3d = ezc3d.c3d(str(tr.file))
            p = np.array(c3d["data"]["points"][:3])
            residual = np.asarray(c3d["data"]["meta_points"]["residuals"])[0]
            p[:, residual < 0] = np.nan
            points = np.transpose(np.stack([p[0], p[2], -p[1]]), (2, 1, 0))
            syn.write_points(tr.file, syn.LABELS, points, syn.RATE)
    session.markerset.write_text(syn.MARKERSET_TOML.replace('up_axis = "Z"', f'up_axis = "{markerset_up}"'))
    return session


def test_a_y_up_capture_read_as_z_up_is_refused_naming_up_axis(tmp_path, capsys):
    session = _session(tmp_path, "Y", "Z")
    out = tmp_path / "map.usda"
    code = main(["build-map", str(session.sheet), "--markers", str(session.markerset), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "up_axis" in err and "+Y" in err, err


def test_the_same_capture_with_its_up_axis_builds(tmp_path, capsys):
    session = _session(tmp_path, "Y", "Y")
    out = tmp_path / "map.usda"
    assert main(["build-map", str(session.sheet), "--markers", str(session.markerset), "--out", str(out), "--quiet"]) == 0
    assert out.exists()


def _clips(tmp_path, stage_up: str, sheet_extra: str = ""):
    """Z-up UsdSkel clips (tests/ingest_synth.py) whose stage says ``stage_up``, and a TOML sheet."""
    from pxr import Usd, UsdGeom

    motions = syn.known_motions(PARAMS)
    rows = [sheet_extra]
    for i, (yaw, pitch) in enumerate(PARAMS):
        path = tmp_path / f"{syn.trial_name(yaw, pitch)}.usda"
        frames = 40 + int(round((float(motions[i].duration) + 0.8) * syn.RATE)) + 1
        syn.write_skel_clip(path, motions[i], 40, frames)
        stage = Usd.Stage.Open(str(path))
        UsdGeom.SetStageUpAxis(stage, stage_up)
        stage.Save()
        rows.append(f'[[trial]]\nfile = "{path.name}"\nyaw = {yaw:g}\npitch = {pitch:g}\n')
    sheet = tmp_path / "sheet.toml"
    sheet.write_text("\n".join(rows))
    return sheet


def test_a_clip_whose_stage_up_axis_is_not_its_rigs_is_refused(tmp_path, capsys):
    """A Z-up rig in a stage that says Y (an export without axis conversion): stored 'ok' before, exit 0."""
    sheet, out = _clips(tmp_path, "Y"), tmp_path / "map.usda"
    code = main(["build-map", str(sheet), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "upAxis Y" in err and "+Z" in err, err


def test_the_same_clips_with_up_axis_bound_build(tmp_path, capsys):
    sheet, out = _clips(tmp_path, "Y", '[skeleton]\nup_axis = "Z"\n'), tmp_path / "map.usda"
    assert main(["build-map", str(sheet), "--out", str(out), "--quiet"]) == 0
    assert out.exists()


def _tilt(sheet, degrees: float) -> None:
    """Stand every clip's character on a slope: its SkelRoot pitched ``degrees`` about X."""
    from pxr import Usd, UsdGeom

    for path in sheet.parent.glob("*.usda"):
        stage = Usd.Stage.Open(str(path))
        UsdGeom.Xformable(stage.GetPrimAtPath("/Rig")).AddRotateXOp().Set(float(degrees))
        stage.Save()


def test_clips_of_a_character_on_a_slope_build_the_level_map(tmp_path):
    """A rig is modelled upright in its own space: the stage's up carried in through a 10 deg slope is
    snapped to the skeleton's axis, as apply does, so the examples are the level clips' (the tilted
    vector turned every example's offsets about a tilted axis)."""
    from usdgaze.ingest import build

    level = build(_clips(tmp_path / "level", "Z"), None).definition
    sloped_sheet = _clips(tmp_path / "sloped", "Z")
    _tilt(sloped_sheet, 10.0)
    sloped = build(sloped_sheet, None).definition
    np.testing.assert_array_equal(sloped.params, level.params)
    for field in ("offsets", "timing"):
        a, b = getattr(level.motions, field), getattr(sloped.motions, field)
        np.testing.assert_allclose(b, a, atol=1e-6, err_msg=field)


def test_clips_of_a_scaled_rig_build_the_map_of_the_same_motion_in_metres(tmp_path):
    """The same clips with the rig scaled 100 under its SkelRoot in a stage of centimetres, as a
    centimetre rig is often brought into a metre scene and back: the motion in metres is the same, so
    is the map. The Skeleton's own scale was ignored: its rest was found in the wrong units (crops 2-4
    frames early, durations 0.13 s off, exit 0)."""
    from pxr import Usd, UsdGeom

    from usdgaze.ingest import build

    plain = build(_clips(tmp_path / "plain", "Z"), None).definition
    sheet = _clips(tmp_path / "scaled", "Z")
    for path in sheet.parent.glob("*.usda"):
        stage = Usd.Stage.Open(str(path))
        UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.GetStageMetersPerUnit(stage) / 100.0)
        UsdGeom.Xformable(stage.GetPrimAtPath("/Rig")).AddScaleOp().Set((100.0, 100.0, 100.0))
        stage.Save()
    scaled = build(sheet, None).definition
    np.testing.assert_array_equal(scaled.params, plain.params)
    for field in ("offsets", "timing"):
        np.testing.assert_allclose(getattr(scaled.motions, field), getattr(plain.motions, field), atol=1e-6, err_msg=field)
