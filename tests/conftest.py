"""Hypothesis profiles: ``ci`` (default; fixed, derandomized, small) and ``long`` (USDGAZE_FUZZ=long);
matplotlib figures a test drew and did not close are closed after it."""

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
