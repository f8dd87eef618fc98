"""Stopping signals that land inside an import: raised there, USD's module loader can swallow the
exception (the command then carried on, wrote its output and exited 0) or leave a module half made
(an internal error). The handlers of the writer and of the CLI send such a signal again a moment
later, when the import is done."""

from __future__ import annotations

import os
import threading

AGAIN_S = 0.05


def in_import(frame) -> bool:
    """Whether ``frame`` (a signal handler's) runs inside Python's import machinery."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def later_if_importing(signum: int, frame) -> bool:
    """Inside an import (``frame``, a signal handler's): deliver ``signum`` to this process again after
    :data:`AGAIN_S` seconds and say so (True); the handler then returns instead of raising."""
    if not in_import(frame):
        return False
    timer = threading.Timer(AGAIN_S, os.kill, (os.getpid(), signum))
    timer.daemon = True
    timer.start()
    return True
