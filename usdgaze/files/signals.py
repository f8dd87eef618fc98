"""Stopping signals that land inside an import: raised there, USD's module loader can swallow the
exception (the command then carried on, wrote its output and exited 0) or leave a module half made
(an internal error). The handlers of the writer and of the CLI send such a signal again a moment
later, when the import is done."""

from __future__ import annotations

import os
import signal
import threading

AGAIN_S = 0.05

STOPS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGINT", "SIGHUP", "SIGQUIT") if hasattr(signal, name))
"""The signals that stop a command: a kill, Ctrl-C, a closed terminal or dropped ssh, Ctrl-\\ (the last two
left temporary folders and partial files behind). Each ends it with 128 + its number."""


def stops_to_handle() -> list[int]:
    """:data:`STOPS` but for SIGHUP and SIGQUIT where ignored: ``nohup`` ignores SIGHUP so that the
    command outlives its terminal, and a handler would undo that. SIGTERM and SIGINT are always
    handled, as they were before."""
    keep = (signal.SIGTERM, signal.SIGINT)
    return [sig for sig in STOPS if sig in keep or signal.getsignal(sig) is not signal.SIG_IGN]


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


CLI_MODULES = ("usdgaze", "usdgaze.__main__", "usdgaze.console.main")
"""What ``python -m`` runs as the usdgaze command."""


def is_cli_process() -> bool:
    """Whether this process is the usdgaze command: the console script, or ``python -m usdgaze``
    while runpy imports the package (``sys.argv[0]`` is ``-m`` until the module is found)."""
    import sys

    argv = sys.argv or [""]
    if os.path.basename(argv[0]) in ("usdgaze", "usdgaze.exe", "usdgaze-script.py"):
        return True
    orig = getattr(sys, "orig_argv", [])
    if argv[0] != "-m" or len(orig) < len(argv):
        return False
    module = orig[-len(argv)]  # orig_argv ends with -m MODULE ARGS..., argv with -m ARGS...
    return module.removeprefix("-m") in CLI_MODULES


def quiet_stops_while_starting() -> None:
    """In the usdgaze command, a Ctrl-C before the CLI's own handlers are set (while Python imports
    OpenUSD, ~0.2 s) ends it as one after does: one line and 130, not a KeyboardInterrupt traceback.
    Nothing is written yet. A library import (no command) keeps Python's handler."""
    if not is_cli_process() or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return  # a host that ignores SIGINT (a background job) keeps ignoring it

    def stop(signum, frame) -> None:
        os.write(2, f"usdgaze: error: interrupted by {signal.Signals(signum).name}; nothing was written\n".encode())
        os._exit(128 + signum)

    signal.signal(signal.SIGINT, stop)
