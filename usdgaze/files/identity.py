"""File identity: is this output one of the files a command reads, or another of its outputs?

Paths are compared by what they name on disk, not by how they are spelled: an existing file by
``(st_dev, st_ino)`` after following symlinks (so a hard link, a symlink, a symlinked folder or
``./a/../a`` all name the same file), a file still to be created by its real folder's identity and
its name.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from usdgaze.errors import UsdGazeError


@dataclass(frozen=True)
class FileId:
    """What a path names on disk: ``(device, inode)`` of a file, or ``(device, inode, name)`` of a new one."""

    key: tuple

    @classmethod
    def of(cls, path: str | os.PathLike, follow: bool = True) -> "FileId":
        path = os.fspath(path)
        try:
            st = os.stat(path, follow_symlinks=follow)
        except FileNotFoundError:
            # A dangling symlink is written through: the file it names is the one to be created.
            parent, name = os.path.split(os.path.realpath(path) if follow else os.path.abspath(path))
            try:
                pst = os.stat(parent)
            except OSError:
                return cls(("path", os.path.realpath(path)))
            return cls(("new", pst.st_dev, pst.st_ino, name))
        except OSError:
            return cls(("path", os.path.realpath(path)))
        return cls(("file", st.st_dev, st.st_ino))


def real_path(path: str | os.PathLike) -> Path:
    """The path with every symlink resolved (a link to be written is written through, at its target)."""
    return Path(os.path.realpath(os.fspath(path)))


class Identities:
    """The files a command reads and the files it will write, checked against each other as they are added."""

    def __init__(self) -> None:
        self._reads: dict[FileId, tuple[str, str]] = {}
        self._writes: dict[FileId, tuple[str, str]] = {}

    def read(self, path: str | os.PathLike, what: str) -> None:
        """Record a file the command reads; a clash with an output already claimed is an error."""
        fid = FileId.of(path)
        if fid in self._writes:
            out, flag = self._writes[fid]
            raise UsdGazeError(f"{out}: {flag} is {_same(out, path)}{what} ({path}); refusing to overwrite an input")
        self._reads.setdefault(fid, (str(path), what))

    def write(self, path: str | os.PathLike, flag: str, follow: bool = True) -> None:
        """Record a file the command will write; one it reads, or another output, is an error."""
        fid = FileId.of(path, follow)
        if fid in self._reads:
            src, what = self._reads[fid]
            raise UsdGazeError(f"{path}: {flag} is {_same(path, src)}{what} ({src}); refusing to overwrite an input")
        if fid in self._writes:
            other, other_flag = self._writes[fid]
            raise UsdGazeError(f"{path}: {flag} and {other_flag} name the same file; give each output its own path")
        self._writes[fid] = (str(path), flag)


def _same(a: str | os.PathLike, b: str | os.PathLike) -> str:
    """'' when two paths are spelled alike, else how they come to name one file."""
    a, b = os.path.abspath(os.fspath(a)), os.path.abspath(os.fspath(b))
    if a == b:
        return "the "
    if os.path.islink(a) or os.path.islink(b):
        return "a symlink to the same file as the "
    if os.path.realpath(a) == os.path.realpath(b):
        return "(through a symlinked folder) the "
    if os.path.exists(a) and os.path.exists(b):
        return "a hard link to the "
    return "the "
