"""``preview`` draws each line of sight to the point of sight: the gaze's end is where the layer's own
guide (``gazeGuides.gaze:pointOfSight``, what ``apply`` aimed the eyes at) puts it. The reach had been
the fixation distance measured by the figure's height (a head joint at 1.5 m), not in the stage's
units: the dot lay 7% beyond the point of sight on a synthetic Z-up centimetre rig and 15% short of
it on the CMU actor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Usd

from usdgaze import api
from usdgaze.review import preview as pv
from usdgaze.review.composed import composed_stage, read_review

from . import synthetic as syn

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


@pytest.mark.parametrize("which", ["z-up-cm", "cmu"])
def test_the_gaze_line_ends_at_the_layers_point_of_sight(tmp_path, which):
    if which == "cmu":
        src, guides, shift = CMU, "/root/Body/BodySkel/gazeGuides", "2s:60:0"
    else:
        src = syn.make_rig(tmp_path / "in.usda", frames=48, time_codes_per_second=24, mesh=False,
                           up_axis="Z", meters_per_unit=0.01).path
        guides, shift = "/Character/Skel/gazeGuides", "0.5s:40:0"
    layer = tmp_path / "gaze.usdc"
    api.apply(str(src), [shift], layer)
    review = read_review(str(src), str(layer), playback=True)
    c = review.characters[0]
    stage, _ = composed_stage(str(src), str(layer))
    scene = pv.build_scene(review, pv.PreviewOptions(camera="top"), stage, c.seconds)
    drawn = scene.panels[1][0].sight_end  # side by side: base, gaze
    guide = Usd.Stage.Open(str(src)).GetRootLayer()  # the input's timing
    code = guide.startTimeCode + c.seconds * guide.timeCodesPerSecond
    attr = stage.GetPrimAtPath(guides).GetAttribute("gaze:pointOfSight")
    wanted = np.array([attr.Get(float(t)) for t in code], dtype=float)
    miss_m = np.linalg.norm(drawn - wanted, axis=1) * c.meters_per_unit
    # Mid-saccade the eyes' rays are not converged on it; on nine frames in ten they are.
    assert np.percentile(miss_m, 90) < 1e-4, np.percentile(miss_m, [50, 90])
