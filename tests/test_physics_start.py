"""A walk simulated from its first frame: ``sample_stages/attend/stepping_stones.usda``'s start, the
right foot standing on Stone00 and the left swinging to Stone01 (0.24 s in).

Its first simulation fell at 0.58 s in every run tried (docs/physics-log.md, "The whole stones
sample's start"): the planner's guess for the cold first window was the target's inverse dynamics
through MuJoCo's soft contacts, which made forces of how far the swinging toe sat inside the contact
margin and saturated the left hip, ankle and toe. Measured on the WRITTEN layer by UsdSkel FK.
"""

from __future__ import annotations

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc

from . import measure, stone_stages

START_SPAN = (0.0, 1.0)


def test_the_stones_walk_simulated_from_its_first_frame_stands_and_steps_on_its_stones(tmp_path):
    """One simulation, no retry (``retry_iterations=0``), the command's other defaults: by UsdSkel FK of
    the written layer over the input, the pelvis stays at >= 80% of the reference's height on every
    frame (it was 30% by 0.76 s), and each stone a foot stands on within the shot (the right foot's from
    the first frame, the left's from 0.27 s) is stood on within 5 cm: the written toe's mean
    ground-plane distance over the reference's contact, the toe no higher than the reference's by 2 cm.
    Measured whatever the written foot did before (``stone_stages.stood_on``): with the support in the
    warm start the written left toe is never low and slow before it lands on Stone01, so
    ``gaze_before_lift``, which needs the foot's lift before a landing, finds none to count."""
    src = stone_stages.walk_stage(tmp_path / "walk.usda", *START_SPAN, until_lift=True, task=True)
    out = tmp_path / "walked.usda"
    physics_pass.run(src, out, mpc.Options(h=0.02, retry_iterations=0))
    composed = stone_stages.compose(tmp_path, src, out)
    times = stone_stages._shot_times(src)
    sim = measure.posed(str(composed), stone_stages.SKEL, times=times)
    ref = measure.posed(str(src), stone_stages.SKEL, times=times)
    hips = lambda p: p.position("Hips") @ p.up  # noqa: E731
    assert (hips(sim) / hips(ref)).min() >= 0.8, (hips(sim) / hips(ref)).min()
    rows = stone_stages.stood_on(tmp_path, src, out)
    assert {(stone, toe) for stone, toe, _, _ in rows} == {("Stone00", "RightToe"), ("Stone01", "LeftToe")}, rows
    # on its stone (the written toe's mean ground-plane distance over the reference's contact), and down:
    # not held over it (the toe on average no more than 2 cm above the reference's there)
    assert all(miss <= 0.05 and rise <= 0.02 for _, _, miss, rise in rows), rows
