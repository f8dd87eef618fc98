"""Settings for usdgaze's own processes (the CLI, batch workers), never applied by the library itself.

A long clip's pass makes many large, short-lived float64 temporaries. glibc's allocator gives memory
above its trim threshold back to the system as soon as it is free and takes fresh, zeroed pages for
the next array, so at 100k frames the pass page-faults ~7x more per joint-frame than at 10k (its
cost per joint-frame grew ~10-20%). Keeping freed memory in the process makes the cost flat; the
peak is unchanged, and the memory goes back when the process ends.
"""

from __future__ import annotations

import sys

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters (malloc.h)
_KEEP = 1 << 30
_tuned: bool | None = None


def tune_allocator() -> bool:
    """Keep freed heap memory for reuse (glibc only; elsewhere nothing changes). True when applied."""
    global _tuned
    if _tuned is None:
        _tuned = False
        if sys.platform.startswith("linux"):
            import ctypes

            try:
                libc = ctypes.CDLL(None)
                mallopt = libc.mallopt
            except (OSError, AttributeError):  # musl and other C libraries have no mallopt
                return False
            _tuned = bool(mallopt(_M_MMAP_THRESHOLD, _KEEP)) and bool(mallopt(_M_TRIM_THRESHOLD, _KEEP))
    return _tuned
