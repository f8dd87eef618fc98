"""C3D reading and writing, and cleaning, on the real vendor files in tests/data/c3d and on made-up data."""

from __future__ import annotations

import builtins
from pathlib import Path

import numpy as np
import pytest

from usdgaze.errors import UsdGazeError
from usdgaze.ingest import c3dio
from usdgaze.ingest.cleaning import fill_gaps, missing_markers
from usdgaze.ingest.markers import MarkerSetError, resolve_labels

DATA = Path(__file__).parent / "data" / "c3d"


@pytest.fixture(scope="module")
def vicon():
    return c3dio.read_c3d(DATA / "Vicon.c3d")


@pytest.mark.parametrize(
    "name, rate, frames, markers",
    [("Optotrak", 30.0, 29, 54), ("Qualisys", 200.0, 340, 55), ("Vicon", 100.0, 580, 51)],
)
def test_vendor_headers(name, rate, frames, markers):
    capture = c3dio.read_c3d(DATA / f"{name}.c3d")
    assert capture.rate == rate
    assert capture.units == "mm" and capture.mm_per_unit == 1.0  # Optotrak has one unit per marker, all mm
    assert capture.points.shape == (frames, markers, 3)
    assert len(capture.labels) == markers


def test_qualisys_first_frame_and_labels():
    capture = c3dio.read_c3d(DATA / "Qualisys.c3d")
    assert capture.first_frame == 704
    assert capture.labels[9:13] == ("L_HDF", "L_HDB", "R_HDB", "R_HDF")
    assert not np.isnan(capture.points).any()


def test_prefixed_labels_match_with_or_without_subject(vicon):
    with_prefix = resolve_labels(["Daphnee:T1"], vicon.labels, None, "Vicon")
    without = resolve_labels(["T1", "ASISl", "XIPH"], vicon.labels, None, "Vicon")
    assert vicon.labels[with_prefix[0]] == "Daphnee:T1"
    assert [vicon.labels[i] for i in without] == ["Daphnee:T1", "Daphnee:ASISl", "Daphnee:XIPH"]
    assert vicon.labels[resolve_labels(["gauche_ext"], vicon.labels, None, "Vicon")[0]] == "boite:gauche_ext"


def test_absent_and_ambiguous_labels_are_one_line_errors(vicon):
    with pytest.raises(MarkerSetError, match=r"Vicon: marker 'HEADTOP' is not in the file"):
        resolve_labels(["T1", "HEADTOP"], vicon.labels, None, "Vicon")
    labels = ("A:X", "B:X", "A:Y")
    with pytest.raises(MarkerSetError, match="ambiguous"):
        resolve_labels(["X"], labels, None, "f")
    assert resolve_labels(["X"], labels, "B", "f") == [1]


def test_vicon_occlusions_are_filled_on_the_line_between_neighbours(vicon):
    points = vicon.points
    missing = np.isnan(points).any(axis=-1)
    assert missing.sum() == 305  # the file's real occlusions
    filled, mask = fill_gaps(points)
    assert not np.isnan(filled).any()
    np.testing.assert_array_equal(mask, missing)
    np.testing.assert_array_equal(filled[~missing], points[~missing])  # seen samples untouched
    interior = 0
    for m in np.flatnonzero(missing.any(axis=0)):
        seen = np.flatnonzero(~missing[:, m])
        for f in np.flatnonzero(missing[:, m]):
            before, after = seen[seen < f], seen[seen > f]
            if len(before) and len(after):
                a, b = before[-1], after[0]
                expected = points[a, m] + (points[b, m] - points[a, m]) * (f - a) / (b - a)
                np.testing.assert_allclose(filled[f, m], expected, rtol=0, atol=1e-9)
                interior += 1
            else:  # a gap at an end keeps the nearest seen sample
                np.testing.assert_array_equal(filled[f, m], points[(before[-1] if len(before) else after[0]), m])
    assert interior > 200


def test_optotrak_markers_never_seen_stay_missing():
    capture = c3dio.read_c3d(DATA / "Optotrak.c3d")
    never = missing_markers(capture.points)
    assert [capture.labels[i] for i in np.flatnonzero(never)] == ["Marker_52", "Marker_53"]
    filled, _ = fill_gaps(capture.points)
    assert np.isnan(filled[:, never]).all() and not np.isnan(filled[:, ~never]).any()


def test_fill_gaps_small_example():
    p = np.zeros((6, 1, 3))
    p[:, 0, 0] = [0.0, np.nan, np.nan, 3.0, np.nan, np.nan]
    p[:, 0, 1] = [np.nan, 1.0, 1.0, 1.0, 1.0, 1.0]
    filled, mask = fill_gaps(p)
    # a sample is a 3D point: frame 0 is missing too, so frame 3 is the only one seen
    np.testing.assert_allclose(filled[:, 0, 0], [3.0, 3.0, 3.0, 3.0, 3.0, 3.0])
    assert mask[:, 0].tolist() == [True, True, True, False, True, True]
    p[:, 0, 1] = 1.0
    filled, _ = fill_gaps(p)
    np.testing.assert_allclose(filled[:, 0, 0], [0.0, 1.0, 2.0, 3.0, 3.0, 3.0])


def test_write_read_round_trip_keeps_gaps_units_and_rate(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.normal(0.0, 1.0, (50, 3, 3))
    points[10:14, 1] = np.nan
    path = tmp_path / "t.c3d"
    c3dio.write_c3d(path, ["A", "Subj:B", "C"], points, 60.0, units="m")
    back = c3dio.read_c3d(path)
    assert back.rate == 60.0 and back.units == "m" and back.mm_per_unit == 1000.0
    assert back.labels == ("A", "Subj:B", "C")
    np.testing.assert_allclose(back.points, points, atol=1e-5)  # float32 storage
    assert np.isnan(back.points[10:14, 1]).all()


def test_missing_ezc3d_says_how_to_install(monkeypatch, tmp_path):
    real_import = builtins.__import__

    def no_ezc3d(name, *args, **kwargs):
        if name == "ezc3d":
            raise ImportError("No module named 'ezc3d'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ezc3d)
    with pytest.raises(UsdGazeError) as err:
        c3dio.read_c3d(DATA / "Vicon.c3d")
    assert str(err.value) == "reading C3D needs ezc3d: pip install usdgaze[c3d]"


def test_unreadable_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"not a c3d file at all" * 10)
    with pytest.raises(c3dio.C3DError) as err:
        c3dio.read_c3d(bad)
    assert str(bad) in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(c3dio.C3DError, match="no such file"):
        c3dio.read_c3d(tmp_path / "none.c3d")


def test_labels_past_255_come_from_labels2(tmp_path):
    """C3D keeps at most 255 labels in POINT:LABELS; the rest go to LABELS2, LABELS3 (a multi-subject or
    face capture). A landmark marker stored past 255 is found, with its own trajectory."""
    from . import ingest_synth as syn

    labels = [f"Prop:M{i}" for i in range(300)] + ["Subject:HLF"]
    points = np.random.default_rng(2).normal(0.0, 500.0, (20, len(labels), 3))
    syn.write_points(tmp_path / "many.c3d", labels, points, 120.0)
    capture = c3dio.read_c3d(tmp_path / "many.c3d")
    assert capture.labels == tuple(labels)
    [i] = resolve_labels(["HLF"], capture.labels, None, "many")
    np.testing.assert_allclose(capture.points[:, i], points[:, -1], atol=1e-3)


@pytest.mark.parametrize("written, same_as", [("  ", "mm"), ("meters", "m"), ("Millimeters", "mm"), ("centimeters", "cm")])
def test_blank_and_plural_units_read_as_their_unit(tmp_path, written, same_as):
    """C3D strings are space-padded: an all-blank POINT:UNITS is no unit given (mm, as a file without
    one); a plural spelling is its unit."""
    from . import ingest_synth as syn

    points = np.random.default_rng(3).normal(0.0, 1.0, (5, 2, 3))
    syn.write_points(tmp_path / "a.c3d", ["A", "B"], points, 100.0, written)
    syn.write_points(tmp_path / "b.c3d", ["A", "B"], points, 100.0, same_as)
    a, b = c3dio.read_c3d(tmp_path / "a.c3d"), c3dio.read_c3d(tmp_path / "b.c3d")
    assert a.mm_per_unit == b.mm_per_unit == {"mm": 1.0, "m": 1000.0, "cm": 10.0}[same_as]
    np.testing.assert_array_equal(a.points, b.points)


def test_a_label_the_file_holds_twice_is_ambiguous(tmp_path):
    """Two trajectories labelled alike (the second took the last one silently): refused as two subjects'
    alike-named markers are, naming the label."""
    labels = ("HLF", "HLB", "HLF")
    with pytest.raises(MarkerSetError, match=r"f: marker 'HLF' is ambiguous \(HLF, HLF\)"):
        resolve_labels(["HLB", "HLF"], labels, None, "f")
