"""What a path that should be a readable file is instead, in the words of a one-line error."""

from __future__ import annotations

import os
import stat

from usdgaze.errors import UsdGazeError


def not_a_file(path: str | os.PathLike) -> str | None:
    """``None`` for a regular file (through symlinks); else why it cannot be read as one."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "a broken symlink" if os.path.islink(path) else "no such file"
    except NotADirectoryError:
        return "no such file (a part of the path is not a folder)"
    except OSError as exc:
        return f"cannot read ({exc.strerror})"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a folder, expected a file"
    return f"is {special_kind(mode) or 'not a file'}, not a regular file"


def require_file(path: str | os.PathLike, error: type[UsdGazeError] = UsdGazeError, where: str | None = None) -> None:
    """One ``error`` line, ``WHERE: why``, unless ``path`` is a regular file (``where``: the path)."""
    problem = not_a_file(path)
    if problem:
        raise error(f"{where or path}: {problem}")


def special_kind(mode: int) -> str | None:
    """A device, pipe or socket's kind in words, from its ``st_mode``; ``None`` for anything else."""
    for test, kind in ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return None
