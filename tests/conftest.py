"""Hypothesis profiles: ``ci`` (default; fixed, derandomized, small) and ``long`` (USDGAZE_FUZZ=long)."""

import os

from hypothesis import settings

settings.register_profile("ci", max_examples=50, deadline=None, derandomize=True, print_blob=True)
settings.register_profile("long", max_examples=2000, deadline=None)
settings.load_profile(os.environ.get("USDGAZE_FUZZ", "ci"))
