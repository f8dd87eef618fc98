"""Steep shifts one after the other (far up, then far down, or back), measured by UsdSkel FK on the
CMU captures: no eye swaps the limit of its range for the other in a frame.

A goal asked less than 90 deg round is behind the head only while the head is pitched away from it;
each eye then takes the yaw of the goal mirrored to the front (over the head's pole), where either
side put it on one limit or the other as the goal crossed the head's midline (88 deg in a frame). A
large shift's path is chosen its way round once, at its start: from a held point near the zenith,
whose azimuth changes fast as the eyes move, the choice flipped per frame (69 deg in a frame). What
is left (a goal crossing the pole at saccade speed: 37.5 deg in a frame; a 370 deg turn asked the
other way round from the shift before: 88.4) no eye follows faster than the seed's 800 deg/s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from usdgaze.console.main import main

from . import measure

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu"
SKEL = "/root/Body/BodySkel"


@pytest.mark.parametrize("clip, shifts", [
    ("cmu_131_01.usdc", ["1s:20:85", "2s:-20:-85"]),  # 69 deg in a frame before
    ("cmu_131_01.usdc", ["3.13s:-2:-89", "3.83s:58:82"]),  # 88
    ("cmu_131_02.usdc", ["2.23s:-2:83", "2.66s:4:-72"]),  # 88
    ("cmu_131_01.usdc", ["1.17s:-37:-86", "2.81s:-50:86"]),  # 40: across the pole at saccade speed
    ("cmu_131_01.usdc", ["1s:170:0", "3s:-200:40"]),  # 88: a 370 deg right turn, the eyes on the short way
])
def test_steep_shifts_swap_no_eye_across_its_range(tmp_path, clip, shifts):
    preview = tmp_path / "preview.usda"
    args = ["apply", str(CMU / clip), "--out", str(tmp_path / "gaze.usdc"), "--preview", str(preview)]
    assert main(args + [a for s in shifts for a in ("--shift", s)]) == 0
    new = measure.posed(str(preview), SKEL)
    fwd = measure.character_forward_skel(new, "LeftHip", "RightHip")
    up = np.linalg.solve(new.skel_to_world[:3, :3].T, new.up)
    up /= np.linalg.norm(up)
    for eye in ("LeftEye", "RightEye"):
        yaw, _ = measure.eye_in_head(new, "Head", eye, fwd, np.cross(up, fwd), up)
        # The seed bounds the eyes at 800 deg/s: 6.67 deg a frame at 120 fps.
        assert np.abs(np.diff(yaw)).max() < 800.0 / 120.0 + 0.01, (eye, np.abs(np.diff(yaw)).max())
