"""The whole build pipeline on data we did not make: the Qualisys walk (C3D) and the CMU walk (UsdSkel).

Neither is a gaze trial, so what is checked is what the pipeline reads from them: the landmark
frames and their rotation (against an independent least-squares fit with scipy), the report, the
exported per-frame series, and clear errors where Heck's automatic crop cannot work (a walk has no
rest period).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdgaze.ingest import BuildSettings, build
from usdgaze.ingest.c3dio import read_c3d
from usdgaze.ingest.report import write_series
from usdgaze.ingest.skelclips import read_skeleton_series

ROOT = Path(__file__).resolve().parent.parent
QUALISYS = ROOT / "tests" / "data" / "c3d" / "Qualisys.c3d"
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"
HEAD = ["L_HDF", "L_HDB", "R_HDB", "R_HDF"]
PELVIS = ["L_IAS", "L_IPS", "R_IPS", "R_IAS"]
QUALISYS_MARKERS = f"""
up_axis = "Z"
[markers]
lower_back = {PELVIS}
upper_back = ["TV8", "SXS", "CV7"]
neck_base = ["CV7", "SNJ", "R_SCAP"]
head = {HEAD}
base_of_spine = "L_IPS"
""".replace("'", '"')


def _independent_angles(labels: list[str]) -> np.ndarray:
    """Rotation (deg) of a marker group from frame 0 to every frame, by scipy's least-squares fit."""
    capture = read_c3d(QUALISYS)
    idx = [capture.labels.index(x) for x in labels]
    p = capture.points[:, idx]
    p = p - p.mean(axis=1, keepdims=True)
    return np.array([np.degrees(Rotation.align_vectors(p[i], p[0])[0].magnitude()) for i in range(len(p))])


@pytest.fixture(scope="module")
def qualisys(tmp_path_factory):
    d = tmp_path_factory.mktemp("qualisys")
    (d / "markers.toml").write_text(QUALISYS_MARKERS)
    (d / "sheet.csv").write_text(
        f"trial,file,yaw,pitch,crop_start,crop_end\nwalk,{QUALISYS},0,0,0,339\nwalk-auto,{QUALISYS},10,0,,\n"
    )
    settings = BuildSettings(min_trials=1, pose_window_s=0.0)  # single first/last frames, as the paper
    return d, build(d / "sheet.csv", d / "markers.toml", settings)


def test_qualisys_report_shows_head_and_pelvis_rotation(qualisys):
    _, result = qualisys
    walk = {r.trial: r for r in result.reports}["walk"]
    assert walk.status == "ok" and walk.rate == 200.0 and walk.units == "mm"
    expected = _independent_angles(HEAD)[-1]
    assert 5.0 < expected < 10.0  # the head turns visibly during the walk
    assert walk.row()["head_angle_deg"] == pytest.approx(expected, abs=0.05)
    assert walk.row()["pelvis_angle_deg"] == pytest.approx(_independent_angles(PELVIS)[-1], abs=0.05)
    assert walk.row()["duration_s"] == pytest.approx(339 / 200.0)


def test_qualisys_walk_cannot_be_cropped_automatically(qualisys):
    _, result = qualisys
    auto = {r.trial: r for r in result.reports}["walk-auto"]
    assert auto.status == "failed"
    assert auto.error.startswith("trial walk-auto (Qualisys.c3d): no rest period found")


def test_qualisys_series_export_matches_an_independent_fit(qualisys, tmp_path):
    _, result = qualisys
    (path,) = write_series(tmp_path, result)
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 340 and path.name == "walk.csv"
    for column, labels in (("head_angle_deg", HEAD), ("pelvis_angle_deg", PELVIS)):
        exported = np.array([float(r[column]) for r in rows])
        independent = _independent_angles(labels)
        assert np.abs(exported - independent).max() < 0.05, column
        assert exported.max() > 5.0
    q = np.array([[float(r[f"head_q{c}"]) for c in "xyzw"] for r in rows])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-5)


def test_cmu_skeleton_is_read_in_skeleton_space():
    series = read_skeleton_series(CMU)
    assert series.rate == pytest.approx(120.0048, abs=1e-3)
    assert series.mm_per_unit == pytest.approx(1000.0)
    assert series.orientations.shape == (994, 4, 4)
    # the rig is Z-up inside the skeleton (a root Xform turns it into the Y-up stage), facing about -Y
    frame = series.frame_at(0)
    from usdgaze.core import rotations as rot

    np.testing.assert_allclose(rot.rotate(frame, rot.UP), [0.0, 0.0, 1.0], atol=1e-9)
    assert rot.rotate(frame, rot.FORWARD)[1] < -0.9


def test_cmu_walk_builds_with_a_manual_crop_and_fails_clearly_without(tmp_path):
    (tmp_path / "sheet.toml").write_text(
        f'[[trial]]\nname = "walk"\nfile = "{CMU}"\nyaw = 20\npitch = 0\ncrop = [100, 400]\n'
        f'[[trial]]\nname = "auto"\nfile = "{CMU}"\nyaw = 30\npitch = 0\n'
    )
    result = build(tmp_path / "sheet.toml", settings=BuildSettings(min_trials=1))
    walk, auto = result.reports
    assert walk.status == "ok", walk.error
    assert walk.crop == (100, 400) and walk.crop_source == "manual"
    assert auto.status == "failed" and "give crop_start and crop_end in the sheet" in auto.error
