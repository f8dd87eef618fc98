"""The quaternion products' shortcuts give the bits of the plain forms they stand for."""

from __future__ import annotations

import numpy as np
import pytest

from usdgaze.core import rotations as rot
from usdgaze.passes.chain import _runs

SPECIAL = np.array([0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, -1e300])


def _component_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product written out component by component (multiply's form for many rows)."""
    ax, ay, az, aw = (a[..., i] for i in range(4))
    bx, by, bz, bw = (b[..., i] for i in range(4))
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 1] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 2] = aw * bz + ax * by - ay * bx + az * bw
    out[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(np.ascontiguousarray(a).view(np.int64),
                                                 np.ascontiguousarray(b).view(np.int64))


@pytest.mark.parametrize("shapes", [((4,), (4,)), ((7, 4), (4,)), ((4,), (9, 4)), ((3, 5, 4), (3, 5, 4)),
                                    ((2, 1, 4), (2, 6, 4)), ((64, 4), (64, 4))])
def test_a_few_rows_multiply_to_the_component_products_bits(shapes):
    rng = np.random.default_rng(5)
    for trial in range(200):
        a, b = (rng.normal(size=s) * np.exp(3 * rng.normal(size=s)) for s in shapes)
        if trial % 3 == 0:  # signed zeros and extremes: a sign flip must stay exact
            a, b = (rng.choice(SPECIAL, size=s) for s in shapes)
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            assert _same_bits(rot.multiply(a, b), _component_product(a, b))


@pytest.mark.parametrize("shapes", [((1247, 4), (1247, 4)), ((1247, 4), (4,)), ((6, 1247, 4), (6, 1247, 4)),
                                    ((2, 1247, 4), (2, 1, 4)), ((20_000, 4), (20_000, 4)), ((9, 4), (9, 4))])
def test_normalized_product_is_normalize_of_multiply_bit_for_bit(shapes):
    rng = np.random.default_rng(2)
    for trial in range(12):
        a, b = (rng.normal(size=s) for s in shapes)
        if trial % 3 == 0:
            a[..., 1], b[..., 2] = 0.0, -0.0
        if trial % 4 == 0:
            a[..., ::3, :] = 0.0  # zero-length products stay zero
        got, want = rot.normalized_product(a, b), rot.normalize(rot.multiply(a, b))
        # The same bits on the builds measured (numpy's einsum sums the four squares pairwise, as
        # normalized_product does); within an ulp on a build whose einsum sums in another order.
        np.testing.assert_array_max_ulp(got, want, maxulp=1)
        assert np.array_equal(got == 0, want == 0)


def test_runs_of_held_displacements_are_told_by_their_bits():
    disp = np.array([[0.0], [-0.0], [-0.0], [1.0], [1.0], [0.0]])[:, None, :]
    first, run = _runs(disp)
    assert first.tolist() == [0, 1, 3, 5] and run.tolist() == [0, 1, 1, 2, 2, 3]
    first, run = _runs(np.empty((0, 5, 4)))
    assert len(first) == 0 and len(run) == 0


@pytest.mark.parametrize("shapes", [((4,), (3,)), ((1247, 4), (3,)), ((1247, 4), (1247, 3)), ((2, 1247, 4), (2, 1247, 3)),
                                    ((2, 1, 4), (2, 50, 3)), ((1, 4), (5, 3))])
def test_rotate_is_its_vector_form_bit_for_bit(shapes):
    rng = np.random.default_rng(9)
    for trial in range(30):
        q, v = (rng.normal(size=s) for s in shapes)
        if trial % 3 == 0:
            q, v = (rng.choice(SPECIAL, size=s) for s in shapes)
        u, w = q[..., :3], q[..., 3:4]
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            t = 2.0 * rot.cross(u, v)
            assert _same_bits(rot.rotate(q, v), v + w * t + rot.cross(u, t))
