"""The planner's growing schedule (passes.schedule.Scheduler) against a fresh schedule of each list.

The look planner re-schedules its shift list after each shift it adds; the Scheduler evaluates only
the new shift's frames. Each answer must be bit for bit the schedule of the same list made from
scratch, whatever came before (including a list that changed in the middle).
"""

from __future__ import annotations

import numpy as np

from usdgaze.gaze.defaults import default_definition
from usdgaze.characters import built_map
from usdgaze.passes.body import CachedMap
from usdgaze.passes.options import Shift
from usdgaze.passes.schedule import Scheduler, schedule

SECONDS = np.arange(240) / 30.0
SHIFTS = [
    Shift(0.2, 40.0, -5.0),
    Shift(0.5, -70.0, 10.0),  # interrupts the first
    Shift(1.6, -70.0, 10.0, timing_change=(12.0, 3.0), min_duration_s=0.6),
    Shift(2.0, 0.0, 0.0, cut=True),
    Shift(3.1, 120.0, 20.0),
    Shift(3.3, 100.0, -30.0, min_duration_s=0.9),
    Shift(7.5, -20.0, 0.0),
    Shift(9.0, 30.0, 0.0),  # after the last frame
]


def _same(a, b) -> None:
    for name in ("displacement", "requested", "settled", "progress"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.timing == b.timing


def test_growing_schedule_is_the_fresh_schedule_of_each_list():
    gaze_map = CachedMap(built_map(default_definition()))
    grower = Scheduler(gaze_map, SECONDS)
    snapshots = []
    for k in range(len(SHIFTS) + 1):
        got = grower.plan(SHIFTS[:k])
        _same(got, schedule(gaze_map, SHIFTS[:k], SECONDS))
        snapshots.append(got)
    # Earlier answers are copies: later shifts did not change them.
    _same(snapshots[2], schedule(gaze_map, SHIFTS[:2], SECONDS))
    # The second shift (0.5 s, 1.5 s long) ends the list of two uninterrupted; the third interrupts it.
    assert snapshots[2].timing[1]["interrupted"] is False and snapshots[3].timing[1]["interrupted"] is True
    # A list that changed before its end, and a shorter one, are scheduled afresh.
    changed = SHIFTS[:3] + [Shift(2.0, 50.0, 0.0)] + SHIFTS[4:]
    _same(grower.plan(changed), schedule(gaze_map, changed, SECONDS))
    _same(grower.plan(SHIFTS[:5]), schedule(gaze_map, SHIFTS[:5], SECONDS))
    # The shifts really move the body: the comparison is not between two identities.
    assert np.abs(schedule(gaze_map, SHIFTS, SECONDS).requested).max() > 100.0
