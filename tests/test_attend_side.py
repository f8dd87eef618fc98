"""``usdgaze attend`` holds an object far to the side by turning the head, as people do (Freedman &
Sparks 1997: beyond ~25 deg the head takes a growing share of a gaze shift, the eyes level off near
35 deg). With the gaze-chain offsets priced 20 times the paper's w_trk, a still sphere 50 deg to the
left was held on only 61 % of the frames of a standing clip with idle sway: the head turned ~8 deg, the
eyes sat at their 44 deg limit and the sway carried the sphere 13 deg off. Measured by UsdSkel FK on
the composed output; the base motion's head is measured the same way on the input."""

from __future__ import annotations

import numpy as np

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import attend_support as A
from . import measure, stages

SKEL = "/root/Body/BodySkel"


def _scene(tmp, angle_deg: float, distance: float, frames: int):
    """The captured idle (real sway) and a still sphere ``distance`` m from the head, ``angle_deg`` to the
    character's left of its hips' forward at the first frame; returns the shot, the sphere and left/forward."""
    idle = stages.standing(tmp / "idle.usdc", frames)
    shot = tmp / "shot.usda"
    layer = A.over(shot, idle)
    layer.Save()
    p = measure.posed(str(shot), SKEL)
    forward = measure.character_forward_skel(p, "LeftHip", "RightHip") @ p.skel_to_world[:3, :3]
    forward[1] = 0.0
    forward /= np.linalg.norm(forward)
    left = np.cross([0.0, 1.0, 0.0], forward)
    a = np.radians(angle_deg)
    where = p.position("Head")[0] + distance * (np.cos(a) * forward + np.sin(a) * left)
    A.still_ball(layer, "/Objects/Ball", where, 0.1)
    layer.Save()
    return shot, where


def _horizontal_angle(direction: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """Degrees between the horizontal (Y up) parts of each row of ``direction`` and ``towards``."""
    a, b = direction.copy(), towards.copy()
    a[:, 1] = b[:, 1] = 0.0
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(1), -1.0, 1.0)))


def test_a_still_object_50_deg_to_the_side_is_held_with_the_head_turned(tmp_path):
    """Measured (3 s, sphere 2.5 m away): held within 5 deg on 100 % of the frames after 0.5 s, the head
    turned a median 12.9 deg toward it beyond the base motion, the eyes a median 37 deg in the head.
    Before (offsets at 20 x w_trk): 61 %, head 7.7 deg, the sphere up to 13 deg off from 2.0 s."""
    shot, where = _scene(tmp_path, 50.0, 2.5, frames=360)
    out = tmp_path / "out.usda"
    assert main(["attend", str(shot), "--out", str(out)]) == 0
    g = A.gaze(A.compose(tmp_path, shot, out))
    to_ball = np.broadcast_to(where, g.eyes.shape) - g.eyes
    late = g.seconds >= 0.5
    held = np.mean(A.angle_to(g, np.broadcast_to(where, g.eyes.shape))[late] < 5.0)
    # The base motion's head, by the same FK on the input (rest-pose axes, as attend_support.gaze does).
    p = measure.posed(str(shot), SKEL, times=g.times)
    base_fwd = p.axis("Head", measure.local_forward(p, "Head", measure.character_forward_skel(p, "LeftHip", "RightHip")))
    turned = _horizontal_angle(base_fwd, to_ball) - _horizontal_angle(g.head_fwd, to_ball)
    assert held >= 0.9, held
    assert np.median(turned[late]) >= 10.0, np.median(turned[late])
