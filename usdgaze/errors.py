"""Errors that reach the user as one line (the CLI prints them and exits with code 2)."""

from __future__ import annotations

import re


class UsdGazeError(Exception):
    """Bad input: the message is one line naming the file, prim or attribute and what is wrong."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


class Interrupted(BaseException):
    """SIGTERM or SIGINT arrived while a command held outputs (``files.transaction``); raised so that
    cleanup runs."""

    def __init__(self, signum: int, detail: str = "nothing was written") -> None:
        import signal

        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.detail = detail
        """What the stop left behind, for the command's one line."""


class GazeMapError(UsdGazeError):
    """A gaze map (on a prim or in memory) is malformed."""


class RigError(UsdGazeError):
    """A skeleton's gaze chain cannot be bound."""


class NoHeadError(RigError):
    """A skeleton with no head at all (by name, by eyes or by binding): no character, e.g. a face's,
    a prop's or a cloth rig's skeleton beside the body's under one SkelRoot."""


def usd_failure(exc: BaseException) -> str:
    """The first (root-cause) message of a Tf.ErrorException, without USD's source location."""
    for line in str(exc).splitlines():
        line = line.strip()
        if line:
            m = re.match(r"^Error in '.*?' at line \d+ in file .*? : '(.*?)'?$", line)
            return m.group(1) if m else line
    return type(exc).__name__
