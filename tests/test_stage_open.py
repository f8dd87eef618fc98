"""The one stage opener on several threads at once (a dask worker runs shots on threads): USD's
warnings are held back by swapping file descriptor 2 while a stage opens, and the swaps of two
threads must not interleave, or stderr ends up pointing at one thread's scratch file for good."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from usdgaze.usd.stage import open_stage

ROOT = Path(__file__).resolve().parents[1]
STAGES = [ROOT / "sample_stages" / "cmu" / "cmu_131_02.usdc", ROOT / "sample_stages" / "shared_map" / "crowd.usda",
          ROOT / "sample_stages" / "attend" / "two_balls.usda"]


def test_stage_opens_on_several_threads_leave_stderr_where_it_was():
    before = os.fstat(2)
    with ThreadPoolExecutor(8) as pool:
        stages = list(pool.map(lambda k: open_stage(str(STAGES[k % len(STAGES)])), range(96)))
    assert all(s.GetPseudoRoot() for s in stages)
    after = os.fstat(2)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)
