"""The measuring helpers themselves, on geometry whose answer is known by construction."""

import warnings

import numpy as np

from tests import measure


def _eyes(left_dirs, right_dirs, half_ipd=0.03) -> measure.Posed:
    """Two eye joints at x = +-half_ipd whose local +Z axis points along the given world directions."""
    frames = len(left_dirs)
    world = np.tile(np.eye(4), (frames, 2, 1, 1))
    for j, (x, dirs) in enumerate(((half_ipd, left_dirs), (-half_ipd, right_dirs))):
        world[:, j, 2, :3] = dirs  # row vectors: local +Z maps to row 2
        world[:, j, 3, :3] = [x, 0.0, 0.0]
    return measure.Posed(joints=["LeftEye", "RightEye"], times=np.arange(frames, dtype=float), world=world,
                         up=np.array([0.0, 1.0, 0.0]), rest_skel=np.tile(np.eye(4), (2, 1, 1)),
                         skel_to_world=np.eye(4))


def test_sight_line_converging_parallel_and_opposite_rays():
    target = np.array([0.2, 0.1, 0.5])  # both eyes aimed at it: the line of sight goes there from the midpoint
    to_l, to_r = target - [0.03, 0, 0], target - [-0.03, 0, 0]
    ahead = np.array([0.0, 0.0, 2.0])  # parallel (and not unit length): the common direction
    p = _eyes(np.array([to_l, ahead, ahead]), np.array([to_r, ahead * 0.5, -ahead]))
    axis = np.array([0.0, 0.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sight = measure.sight_line(p, "LeftEye", "RightEye", axis, axis)
    np.testing.assert_allclose(sight[0], target / np.linalg.norm(target), atol=1e-12)
    np.testing.assert_allclose(sight[1], [0.0, 0.0, 1.0], atol=1e-12)
    assert np.isnan(sight[2]).all()  # eyes looking opposite ways have no line of sight
