"""``usdgaze attend`` looks at objects far away, out to the eye model's focal range (33 m): its look-at
proposals stopped 0.5 mm of focal length under the top of that range, at 16 m, and since the belief's
observation noise grows with the distance from the point of sight to the object, an object 20 m away
was never looked at. Measured by UsdSkel FK on the written layer."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import attend_support as A
from . import measure

CMU = A.ATTEND.parent / "cmu" / "cmu_131_01.usdc"


def _scene(path, distance: float) -> tuple[Sdf.Layer, np.ndarray]:
    """The standing clip and a still sphere ``distance`` metres from the head, 30 deg to its left."""
    layer = A.over(path, CMU)
    layer.subLayerPaths[:] = [str(A.ATTEND / "standing.usdc"), str(CMU)]
    layer.Save()
    p = measure.posed(str(path), "/root/Body/BodySkel")
    forward = measure.character_forward_skel(p, "LeftHip", "RightHip") @ p.skel_to_world[:3, :3]
    forward[1] = 0.0
    forward /= np.linalg.norm(forward)
    left = np.cross([0.0, 1.0, 0.0], forward)
    where = p.position("Head")[0] + distance * (np.cos(np.radians(30)) * forward + np.sin(np.radians(30)) * left)
    A.still_ball(layer, "/Objects/Far", where, 0.3)
    layer.Save()
    return layer, where


@pytest.mark.parametrize("distance", [25.0])
def test_an_object_far_away_is_looked_at(tmp_path, distance):
    scene, where = _scene(tmp_path / "shot.usda", distance)
    out = tmp_path / "out.usda"
    assert main(["attend", str(tmp_path / "shot.usda"), "--out", str(out)]) == 0
    g = A.gaze(A.compose(tmp_path, tmp_path / "shot.usda", out))
    off = A.angle_to(g, np.broadcast_to(where, g.eyes.shape))
    assert np.median(off) < 2.0 and np.mean(off < 5.0) > 0.9, (np.median(off), np.mean(off < 5.0))
