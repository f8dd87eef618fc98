"""An exclusive lock on a folder while a command edits a file in it.

Two commands inserting their overrides into one shot layer at once (two manifests' shots of one shot
on a farm) each read the layer, add their sublayer and rename the edit into place: the later rename
dropped the other's sublayer. The folder is locked, not the file: the edit replaces the file's inode,
so a third command would lock the new inode while the second still held the old one.
"""

from __future__ import annotations

import os


def lock_folder(folder: str | os.PathLike) -> int | None:
    """Wait for an exclusive ``flock`` on ``folder``; its descriptor (close it to release), or None where
    the system or file system has no such lock (Windows, NFS without lock support): the edit then goes
    on unlocked, as before."""
    try:
        import fcntl
    except ImportError:  # Windows
        return None
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:  # the claim that follows says why the folder cannot be written
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
    except OSError:  # ENOLCK, EOPNOTSUPP, EBADF (NFS's flock of a read-only descriptor)
        os.close(fd)
        return None
    except BaseException:  # a stop signal while waiting: the command unwinds
        os.close(fd)
        raise
    return fd
