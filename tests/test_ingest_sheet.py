"""Trial sheets (CSV, TOML) and marker sets: parsing, paths, and one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from usdgaze.ingest.markers import LANDMARKS, MarkerSetError, load_markerset
from usdgaze.ingest.sheet import SheetError, load_sheet

from . import ingest_synth as syn

EXAMPLES = Path(__file__).resolve().parent.parent / "pipeline" / "examples"


def test_csv_sheet(tmp_path):
    (tmp_path / "s.csv").write_text(
        "# comment line\nTrial,File,Yaw,Pitch,crop_start,crop_end\n"
        "A,a.c3d,0,0,10,90\nB, sub/b.c3d ,-180,12,,\n,c.usda,36,-12,,\n"
    )
    sheet = load_sheet(tmp_path / "s.csv")
    assert [t.name for t in sheet.trials] == ["A", "B", "c"]  # no name: the file's stem
    assert sheet.trials[0].crop == (10, 90) and sheet.trials[1].crop is None
    assert sheet.trials[1].file == tmp_path / "sub" / "b.c3d"
    assert (sheet.trials[1].yaw, sheet.trials[1].pitch) == (-180.0, 12.0)
    assert sheet.trials[2].is_skeletal and not sheet.trials[0].is_skeletal


def test_a_spreadsheets_empty_columns_and_rows_are_skipped(tmp_path):
    """Spreadsheets save columns and rows they once formatted as empty cells (``,,``): the sheet reads
    as without them (it was refused as "row 2: unknown key ''")."""
    (tmp_path / "s.csv").write_text("trial,file,yaw,pitch,,\r\nA,a.c3d,36,0,,\r\n,,,,,\r\nB,b.c3d,-36,12,,\r\n,,,,,\r\n")
    sheet = load_sheet(tmp_path / "s.csv")
    assert [(t.name, t.file.name, t.yaw, t.pitch) for t in sheet.trials] == [("A", "a.c3d", 36.0, 0.0), ("B", "b.c3d", -36.0, 12.0)]


def test_toml_sheet_with_markers_and_skeleton(tmp_path):
    (tmp_path / "s.toml").write_text(
        'markers = "ms.toml"\n[skeleton]\npelvis = "Hips"\nlower_spine = "Spine"\nforward = [0, -1, 0]\n'
        '[[trial]]\nname = "A"\nfile = "a.usda"\nyaw = 36\npitch = 0\ncrop = [5, 50]\nskeleton = "/Rig/Skel"\n'
    )
    sheet = load_sheet(tmp_path / "s.toml")
    assert sheet.markers == tmp_path / "ms.toml"
    assert sheet.skeleton.joints == {"pelvis": "Hips", "lowerSpine": "Spine"}
    assert sheet.skeleton.forward == (0.0, -1.0, 0.0)
    t = sheet.trials[0]
    assert (t.name, t.crop, t.skeleton) == ("A", (5, 50), "/Rig/Skel")


@pytest.mark.parametrize(
    "text, message",
    [
        ("trial,file,yaw\nA,a.c3d,0\n", "lacks column pitch"),
        ("file,yaw,pitch\na.c3d,left,0\n", "row 2: yaw 'left' is not a number"),
        ("file,yaw,pitch\na.c3d,0,0\nb.c3d,200,0\n", "row 3: target (200, 0) is outside"),
        ("file,yaw,pitch,crop_start,crop_end\na.c3d,0,0,10,\n", "give both crop_start and crop_end"),
        ("file,yaw,pitch,crop_start,crop_end\na.c3d,0,0,10.5,20\n", "not a frame index"),
        ("file,yaw,pitch,crop_start,crop_end\na.c3d,0,0,30,20\n", "not after crop_start"),
        ("trial,file,yaw,pitch\nA,a.c3d,0,0\nA,b.c3d,1,0\n", "trial name 'A' appears twice"),
        ("file,yaw,pitch\n", "no trials"),
        # More cells than the header: refused (a decimal comma shifts every value after it).
        ("file,yaw,pitch\na.c3d,1,5,0\n", "row 2: 4 cells, but the header names 3 (file, yaw, pitch)"),
        ("file,yaw,pitch\na.c3d,0,0,\n", "row 2: 4 cells, but the header names 3"),
        # A row is named by its line in the file: comment and blank lines count.
        ("file,yaw,pitch\n# degrees\n\na.c3d,0,0\nb.c3d,left,0\n", "row 5: yaw 'left' is not a number"),
        ("file,yaw,pitch\n# degrees\na.c3d,0,0,9\n", "row 3: 4 cells"),
        # A value under a column the header leaves unnamed (was "row 2: unknown key ''" on every such sheet).
        ("file,yaw,pitch,\na.c3d,0,0,\nb.c3d,1,0,x\n", "row 3: 'x' in column 4, which the header leaves unnamed"),
        # Another separator (was "unknown column 'file;yaw;pitch'").
        ("file;yaw;pitch\na.c3d;0;0\n", "the header is one cell ('file;yaw;pitch'); the cells of a CSV sheet are "
                                          "separated by commas, this one by ';'"),
        ("file\tyaw\tpitch\na.c3d\t0\t0\n", "this one by '\\t'"),
    ],
)
def test_csv_sheet_errors(tmp_path, text, message):
    path = tmp_path / "s.csv"
    path.write_text(text)
    with pytest.raises(SheetError) as err:
        load_sheet(path)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)


def test_toml_sheet_errors(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("[[trial]]\nfile = 'a.c3d'\nyaw = = 0\n")
    with pytest.raises(SheetError, match="not valid TOML"):
        load_sheet(path)
    path.write_text("[[trial]]\nfile = 'a.c3d'\nyaw = 0\n")
    with pytest.raises(SheetError, match="trial 1: no pitch"):
        load_sheet(path)
    with pytest.raises(SheetError, match="no such trial sheet"):
        load_sheet(tmp_path / "none.csv")
    # [[trials]] beside [[trial]]: the [[trials]] rows were dropped without a word
    path.write_text("[[trials]]\nfile = 'a.c3d'\nyaw = 0\npitch = 0\n[[trial]]\nfile = 'b.c3d'\nyaw = 36\npitch = 0\n")
    with pytest.raises(SheetError) as err:
        load_sheet(path)
    assert str(err.value) == f"{path}: both [[trial]] and [[trials]] tables; name every trial [[trial]]"


@pytest.mark.parametrize(
    "body, message",
    [
        ('[markers]\nhead = ["A", "B", "C"]\n', "markers.head must list the 4 square markers"),
        ('[markers]\nlower_back = ["A", "B"]\n', "lists 2 markers"),
        ('[markers]\nlower_back = ["A", "A", "B"]\n', "names a marker twice"),
        ('[markers]\nlowerback = ["A", "B", "C"]\n', "unknown key markers.lowerback"),
        ('up_axis = "W"\n[markers]\n', "up_axis 'W' is not one of X, Y, Z"),
    ],
)
def test_markerset_errors(tmp_path, body, message):
    path = tmp_path / "m.toml"
    path.write_text(body)
    with pytest.raises(MarkerSetError, match=message):
        load_markerset(path)


def test_incomplete_markerset_cannot_build(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text('[markers]\nhead = ["A", "B", "C", "D"]\n')
    ms = load_markerset(path)
    with pytest.raises(MarkerSetError, match="lacks lower_back, upper_back, neck_base"):
        ms.require_complete()


def test_example_files_parse_and_match_the_synthetic_subject():
    ms = load_markerset(EXAMPLES / "markerset.toml")
    ms.require_complete()
    np.testing.assert_array_equal(ms.up, [0.0, 0.0, 1.0])
    assert set(ms.labels()) == set(syn.LABELS) - {"LSHO", "RSHO", "LELB", "RELB", "EYE"}
    assert [len(ms.landmarks[n]) for n in LANDMARKS] == [3, 3, 3, 4]
    csv_sheet, toml_sheet = load_sheet(EXAMPLES / "sheet.csv"), load_sheet(EXAMPLES / "sheet.toml")
    assert [(t.name, t.yaw, t.pitch, t.crop) for t in csv_sheet.trials] == \
        [(t.name, t.yaw, t.pitch, t.crop) for t in toml_sheet.trials]
    assert toml_sheet.markers == EXAMPLES / "markerset.toml"
