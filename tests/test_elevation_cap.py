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
