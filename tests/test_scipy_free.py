"""The apply path's numpy replacements for scipy.spatial, checked against scipy itself.

``usdgaze.core.rotations`` converts matrices and quaternions with numpy, the gaze map finds nearest
samples with numpy (``usdgaze.gaze.neighbors``) and takes the built-in examples' triangles and
neighbours from a stored table (``usdgaze.gaze.triangulation``), so that ``usdgaze apply`` never
imports scipy.spatial. Each is compared here with scipy's own answer, bit for bit.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from usdgaze.core import rotations as rot
from usdgaze.gaze import defaults, neighbors, triangulation
from usdgaze.gaze.gazemap import ParametricGazeMap

ROOT = Path(__file__).resolve().parents[1]


def _quats(rng, n):
    q = rng.normal(size=(n, 4))
    q[: n // 10, :3] *= 1e-9  # near identity
    q[n // 10: n // 5, 3] = 0.0  # half turns
    q[n // 5: n // 5 + 24] = np.eye(4)[np.arange(24) % 4] * np.where(np.arange(24) % 8 < 4, 1.0, -1.0)[:, None]
    return q


def test_to_matrix_equals_scipy_bit_for_bit():
    q = _quats(np.random.default_rng(0), 20000)
    assert np.array_equal(rot.to_matrix(q), Rotation.from_quat(q).as_matrix())
    assert rot.to_matrix(q.reshape(100, 200, 4)).shape == (100, 200, 3, 3)


@pytest.mark.parametrize("kind", ["orthogonal", "float32", "skewed", "scaled"])
def test_from_matrix_equals_scipy_bit_for_bit(kind):
    rng = np.random.default_rng(1)
    m = Rotation.from_quat(_quats(rng, 20000)).as_matrix()
    if kind == "float32":  # as read from float32 storage: not orthogonal to 1e-12, so scipy takes the SVD path
        m = m.astype(np.float32).astype(float)
    elif kind == "skewed":
        m = m + rng.normal(scale=1e-3, size=m.shape)
    elif kind == "scaled":  # per-axis scale, as joint matrices carry it: removed before the conversion
        m = m * rng.uniform(0.2, 5.0, size=(len(m), 1, 3))
    cols = m / np.linalg.norm(m, axis=-2, keepdims=True)
    want = Rotation.from_matrix(cols).as_quat()
    want = np.where(want[:, 3:] < 0, -want, want)  # usdgaze's representative has w >= 0
    assert np.array_equal(rot.from_matrix(m), want)


def test_from_matrix_refuses_a_mirror():
    with pytest.raises(ValueError, match="determinant"):
        rot.from_matrix(np.diag([1.0, 1.0, -1.0]))


def test_nearest_equals_cKDTree_on_map_samples():
    gaze_map = ParametricGazeMap(defaults.default_definition())
    rng = np.random.default_rng(2)
    queries = np.column_stack([rng.uniform(-200, 200, 3000), rng.uniform(-70, 70, 3000)])
    queries[:50] = gaze_map.sample_params[:50]  # exactly on samples: distance 0
    want_d, want_i = cKDTree(gaze_map.sample_params).query(queries, k=9)
    got_d, got_i = neighbors.nearest(gaze_map.sample_params, queries, 9)
    assert np.array_equal(got_d, want_d) and np.array_equal(got_i, want_i)


def test_nearest_breaks_ties_by_index_like_a_full_sort():
    grid = np.array([(x, y) for x in range(-6, 7) for y in range(-4, 5)], dtype=float) * 10.0
    rng = np.random.default_rng(3)
    queries = np.concatenate([np.round(rng.uniform(-60, 60, (400, 2)) / 5.0) * 5.0,  # many equidistant
                              rng.uniform(-60, 60, (100, 2))])
    for k in (1, 4, 9, 30, len(grid)):
        d, i = neighbors.nearest(grid, queries, k)
        d2 = ((queries[:, None, :] - grid[None]) ** 2).sum(-1)
        brute = np.argsort(d2, axis=1, kind="stable")[:, :k]  # ascending distance, ties by index
        assert np.array_equal(i, brute), k
        assert np.allclose(d, np.sqrt(np.take_along_axis(d2, brute, axis=1)), rtol=0, atol=1e-12)


def test_stored_geometry_is_scipys():
    for label, (params, k) in triangulation.builtin().items():
        stored = triangulation.example_geometry(params, k)
        computed = triangulation.computed(params, k)
        assert triangulation.params_key(params, k) in triangulation._KNOWN, label
        assert all(np.array_equal(a, b) for a, b in zip(stored, computed)), (
            f"{label}: stored triangles or neighbours differ from scipy's; "
            "regenerate with python -m usdgaze.gaze.triangulation")


def test_apply_process_does_not_import_scipy(tmp_path):
    code = ("import sys\nfrom usdgaze.console.main import main\n"
            "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
            "print(sorted(m for m in sys.modules if m == 'scipy' or m.startswith('scipy.')))")
    cmu = ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc"
    proc = subprocess.run([sys.executable, "-c", code, "apply", str(cmu), "--shift", "2s:60:0",
                           "--look-at", "1,1.5,3@4s", "--out", str(tmp_path / "o.usdc")],
                          capture_output=True, text=True, check=True)
    assert proc.stdout.strip().splitlines()[-1] == "[]"


def test_sorted_points_answer_as_the_brute_force_pass():
    """The gaze map's strip search (a few queries at a time) gives nearest()'s answer bit for bit:
    on the map's samples, off the sampled box, on exact samples and among equidistant grid points."""
    gaze_map = ParametricGazeMap(defaults.default_definition())
    rng = np.random.default_rng(4)
    queries = np.column_stack([rng.uniform(-250, 250, 2000), rng.uniform(-100, 100, 2000)])
    queries[:50] = gaze_map.sample_params[:50]
    grid = np.array([(x, y) for x in range(-6, 7) for y in range(-4, 5)], dtype=float) * 10.0
    on_grid = np.round(rng.uniform(-60, 60, (600, 2)) / 5.0) * 5.0
    for points, qs in ((gaze_map.sample_params, queries), (grid, on_grid)):
        index = neighbors.SortedPoints(points)
        for k in (1, 9, 30):
            for lo in range(0, len(qs), 3):
                want, got = neighbors.nearest(points, qs[lo:lo + 3], k), index.nearest(qs[lo:lo + 3], k)
                assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1]), (k, lo)
