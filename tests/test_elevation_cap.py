"""A pitch request the line of sight cannot reach (it would pass straight down: elevation is capped
at -89 deg) is said: a warning, and a hold error that is what UsdSkel FK measures, not 0."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from usdgaze.console.main import main

from . import measure

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
SKEL = "/root/Body/BodySkel"


@pytest.mark.parametrize("timing", [[], ["--eye-timing", "model"]])
def test_a_request_cut_short_by_the_elevation_cap_is_said_with_its_measured_miss(tmp_path, capsys, timing):
    out, preview = tmp_path / "gaze.usdc", tmp_path / "preview.usda"
    assert main(["apply", str(CMU), "--shift", "2.3s:0:-35", "--shift", "4s:0:0", "--out", str(out),
                 "--preview", str(preview), "--json", *timing]) == 0
    report = json.loads(capsys.readouterr().out)
    assert any("cannot pass straight down" in w for w in report["warnings"]), report["warnings"]
    said = float(report["characters"][0]["shifts"][0]["hold_error_deg"].split()[0])

    base, new = measure.posed(str(CMU), SKEL), measure.posed(str(preview), SKEL)
    change, _, line = measure.gaze_change(base, new, measure.character_forward_skel(base, "LeftHip", "RightHip"))
    tcps = 120.00479955795427
    hold = (base.times > 1 + 2.8 * tcps) & (base.times < 1 + 4 * tcps)
    miss = np.abs(change[hold, 1] + 35.0).max()
    assert miss > 10.0  # the request is out of reach here: the base already looks 60-75 deg down
    assert measure.az_el(line, new.up)[hold, 1].min() > -89.5  # capped, never through the vertical
    assert said == pytest.approx(miss, abs=0.5)


@pytest.mark.parametrize("shift", ["30:0:90", "30:60:90"])
def test_a_shift_toward_the_zenith_swings_no_eye_from_side_to_side(tmp_path, shift):
    """Past the eyes' upward range, near the head's pole, a point's yaw is all but undefined: each
    eye, clamped at +-44.2 deg yaw, swung from side to side as the point moved about the pole (up to
    70 deg in a frame, 3,675 deg/s by UsdSkel FK on the synthetic walk). Now no eye turns faster than
    the seed's 800 deg/s saccade cap."""
    from . import synthetic as syn

    rig = syn.make_rig(tmp_path / "in.usda", mesh=False, frames=240, time_codes_per_second=60)
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--shift", shift, "--out", str(tmp_path / "gaze.usdc"),
                 "--preview", str(preview)]) == 0
    new = measure.posed(str(preview), rig.skeleton)
    for eye in rig.eye_leaves:
        yaw, pitch = measure.eye_in_head(new, rig.leaf["head"], eye, rig.forward, rig.left, rig.up)
        d = np.column_stack([np.cos(np.radians(pitch)) * np.sin(np.radians(yaw)), np.sin(np.radians(pitch)),
                             np.cos(np.radians(pitch)) * np.cos(np.radians(yaw))])
        speed = measure.angle_between(d[1:], d[:-1]) * rig.time_codes_per_second
        assert speed.max() < 800.0, (eye, speed.max())
