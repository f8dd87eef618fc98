"""build-map on the C3D format's other forms, written byte by byte (tests/c3d_bytes.py), and the crop's
frame numbering.

* Integer points (``POINT:SCALE`` > 0, coordinates = integer x scale), DEC floats, analog channels
  between frames, a header numbering its frames from 705, missing samples as residual -1: the map
  equals the one from the float (Intel, ezc3d-written) twin holding the same numbers (every
  coordinate a multiple of 1/8 mm, exact in both forms). This held before this file; it is here
  because nothing checked it.
* A MIPS (big-endian) file, which ezc3d cannot read: one line saying so, naming the trial.
* A crop given in the file's own numbers (C3D's 705-1044, a clip's time codes 1001-...) is refused
  saying how the crop counts and how the file numbers its frames.
"""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.console.main import main
from usdgaze.ingest.build import build

from . import ingest_synth as syn
from .c3d_bytes import DEC, INTEL, MIPS, write_c3d_bytes

PARAMS = np.array([[0.0, 0.0], [72.0, 12.0], [-108.0, 0.0]])
STEP_MM = 0.125  # exact in float32 and as an int16 count for a lab within +-4 m

FORMS = {
    "integer": dict(integer=True, scale=STEP_MM),
    "integer DEC, analogs, first frame 705": dict(integer=True, scale=STEP_MM, processor=DEC, analog_channels=3,
                                                  analog_per_frame=4, first_frame=705),
    "float DEC": dict(processor=DEC),
    "float Intel": dict(processor=INTEL, analog_channels=2, analog_per_frame=1),
}


@pytest.fixture(scope="module")
def captures():
    """The session's trials: (truth, lab points on a 1/8 mm grid, NaN in occlusion gaps)."""
    motions = syn.known_motions(PARAMS)
    rng = np.random.default_rng(3)
    out = []
    for i, (yaw, pitch) in enumerate(PARAMS):
        points, onset = syn.simulate_trial(motions[i], rng)
        points = np.round(points / STEP_MM) * STEP_MM
        truth = syn.TrialTruth(syn.trial_name(yaw, pitch), float(yaw), float(pitch), motions[i], onset, len(points),
                               syn.RATE)
        if yaw == 0 and pitch == 0:
            truth.crop = (onset, len(points) - 1)
        out.append((truth, points))
    assert all(np.isnan(p).any() for _, p in out)  # gaps: residual -1 in the byte-written files
    return out


def _session(d, captures, form: dict | None):
    """Sheet, marker set and trial files in ``d``, each written by ezc3d (``None``) or byte by byte."""
    d.mkdir()
    trials = []
    for truth, points in captures:
        trial = syn.TrialTruth(**vars(truth))
        trial.file = d / f"{trial.name}.c3d"
        if form is None:
            syn.write_points(trial.file, syn.LABELS, points, syn.RATE)
        else:
            write_c3d_bytes(trial.file, list(syn.LABELS), points, syn.RATE, **form)
        trials.append(trial)
    syn.write_sheet(d / "sheet.csv", trials)
    (d / "markers.toml").write_text(syn.MARKERSET_TOML)
    return d / "sheet.csv", d / "markers.toml"


@pytest.fixture(scope="module")
def float_map(captures, tmp_path_factory):
    result = build(*_session(tmp_path_factory.mktemp("float") / "s", captures, None))
    assert [r.status for r in result.reports] == ["ok"] * len(PARAMS)
    return result


@pytest.mark.parametrize("form", sorted(FORMS))
def test_every_form_gives_the_float_files_map(captures, float_map, tmp_path, form):
    result = build(*_session(tmp_path / "s", captures, FORMS[form]))
    assert [r.status for r in result.reports] == ["ok"] * len(PARAMS), [r.error for r in result.reports]
    assert [r.crop for r in result.reports] == [r.crop for r in float_map.reports]
    np.testing.assert_array_equal(result.definition.motions.offsets, float_map.definition.motions.offsets)
    np.testing.assert_array_equal(result.definition.motions.timing, float_map.definition.motions.timing)


def test_a_mips_file_is_one_line_naming_the_trial(captures, tmp_path, capsys):
    sheet, markers = _session(tmp_path / "s", captures[1:2], dict(processor=MIPS))
    code = main(["build-map", str(sheet), "--markers", str(markers), "--out", str(tmp_path / "map.usda"),
                 "--min-trials", "1", "--quiet"])
    err = capsys.readouterr().err.splitlines()
    name = captures[1][0].name
    assert code == 2 and err == [
        f"usdgaze: error: only 0 of 1 trials gave an example, a map needs at least 1; first failure: trial {name} "
        f"({name}.c3d): written for a MIPS processor (C3D processor type 86, big-endian), which the C3D reader "
        "(ezc3d) cannot read; save it again for Intel or DEC (types 84, 85)"]
    assert not (tmp_path / "map.usda").exists()


def test_a_crop_in_the_c3d_files_own_frame_numbers_says_how_crops_count(captures, tmp_path):
    """The header numbers the frames 705-...: a crop in those numbers is refused, saying how crops count;
    the same crop counted from 0 is taken as given."""
    truth, points = captures[1]
    n, start = len(points), truth.onset - 10  # from a little before the shift to the last frame
    sheet, markers = _session(tmp_path / "s", [(truth, points)], dict(first_frame=705))
    rows = sheet.read_text().splitlines()
    for offset in (705, 0):
        sheet.write_text(f"{rows[0]}\n{rows[1].rsplit(',', 2)[0]},{offset + start},{offset + n - 1}\n")
        report = build(sheet, markers).reports[0]
        if offset:
            assert report.error == (f"trial {truth.name} ({truth.name}.c3d): crop_end {705 + n - 1} is past the last "
                                    f"frame {n - 1}; crop frames count the trial's samples from 0 (the file numbers "
                                    f"them 705-{705 + n - 1})")
        else:
            assert report.error == "" and report.crop == (start, n - 1), report.error


def test_a_crop_in_a_clips_time_codes_says_how_crops_count(tmp_path):
    """A clip whose samples sit at time codes 1001-...: crop_end 1001 + n - 1 is refused, naming them."""
    from pxr import Sdf

    motion = syn.known_motions(PARAMS[1:2])[0]
    clip = tmp_path / "clip.usda"
    syn.write_skel_clip(clip, motion, 40, 150)
    layer = Sdf.Layer.FindOrOpen(str(clip))
    for attr in ("translations", "rotations"):
        path = Sdf.Path(f"/Rig/Skel/Anim.{attr}")
        samples = {t: layer.QueryTimeSample(path, t) for t in layer.ListTimeSamplesForPath(path)}
        for t, value in samples.items():
            layer.EraseTimeSample(path, t)
        for t, value in samples.items():
            layer.SetTimeSample(path, t + 1001, value)
    layer.startTimeCode, layer.endTimeCode = 1001, 1150
    layer.Save()
    sheet = tmp_path / "sheet.toml"
    sheet.write_text('[[trial]]\nname = "a"\nfile = "clip.usda"\nyaw = 72\npitch = 12\ncrop = [1041, 1149]\n')
    report = build(sheet).reports[0]
    assert report.error == ("trial a (clip.usda): crop_end 1149 is past the last frame 149; crop frames count the "
                            "trial's samples from 0 (their time codes run 1001-1150)")


@pytest.mark.parametrize("factor, units, likely", [(1e-3, " ", "m"), (1e-3, "mm", "m"), (1.0, "m", "mm"), (0.1, "mm", "cm")])
def test_points_in_another_unit_than_the_files_are_said_so(captures, tmp_path, factor, units, likely):
    """Metres in a file whose POINT:UNITS says mm, or says nothing (read as mm; ezc3d writes none by
    default), were refused as 'no motion (the whole trial is one rest period)'; mm labelled m as 'no rest
    period found'. The head's distance from the base of the spine, measured here from the points, names it."""
    truth, points = captures[1]
    sheet, markers = _session(tmp_path / "s", [(truth, points * factor)], dict(units=units))
    (report,) = build(sheet, markers).reports
    head = points[:, [syn.LABELS.index(x) for x in ("HLF", "HLB", "HRB", "HRF")]].mean(axis=1)
    reach = np.nanmedian(np.linalg.norm(head - points[:, syn.LABELS.index("BOS")], axis=-1))  # mm
    said_mm = reach * factor * {"m": 1000.0, "mm": 1.0}[units.strip() or "mm"]
    assert report.status == "failed" and "\n" not in report.error
    assert report.error.startswith(f"trial {truth.name} ({truth.name}.c3d): the head is {said_mm:.3g} mm from the "
                                   "base of the spine by the file's POINT:UNITS"), report.error
    assert report.error.endswith(f"its points look like {likely} ({reach * factor:.3g} {likely}): correct POINT:UNITS in the file")


def test_metres_labelled_as_metres_give_the_mm_files_map(captures, float_map, tmp_path):
    sheet, markers = _session(tmp_path / "s", [(t, p / 1000.0) for t, p in captures], dict(units="m", scale=1.0))
    result = build(sheet, markers)
    assert [r.crop for r in result.reports] == [r.crop for r in float_map.reports]
    angle = np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(result.definition.motions.offsets
                                                          * float_map.definition.motions.offsets, axis=-1)), 0, 1)))
    assert angle.max() < 0.01
