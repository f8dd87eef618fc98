"""Hypothesis profiles: ``ci`` (default; fixed, derandomized, small) and ``long`` (USDGAZE_FUZZ=long);
matplotlib figures a test drew and did not close are closed after it; the suite's worker processes
(pytest-xdist, ``-n auto`` in pyproject.toml): one per core this process may run on, at most 8."""

import os
import sys

import pytest
from hypothesis import settings

settings.register_profile("ci", max_examples=50, deadline=None, derandomize=True, print_blob=True)
settings.register_profile("long", max_examples=2000, deadline=None)
settings.load_profile(os.environ.get("USDGAZE_FUZZ", "ci"))


@pytest.fixture(autouse=True)
def _close_figures():
    """Tests that look at one figure of several leave the others open: closed here, not accumulated."""
    yield
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")


@pytest.fixture(scope="session")
def stone_walk():
    """The CMU walk's MuJoCo body at h 0.03 and its reference over 1.0-2.5 s
    (``stone_stages.walk_body``), built once per worker for the stone and obstacle cost tests."""
    from . import stone_stages

    return stone_stages.walk_body(0.03)


def pytest_xdist_auto_num_workers(config) -> int:
    """One worker per core this process may run on (a CI container's share, not the host's), at most 8:
    each worker imports USD, MuJoCo and the package (~0.5 GB), and the longest test file alone
    (the coupled physics shots) sets the suite's floor well before 8."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cores, 8))
