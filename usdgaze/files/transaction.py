"""The one writer: every output of a command is staged, then all are renamed into place together.

A command opens one :class:`Outputs`, claims each path it will write (checked at once: folder,
name, ``--no-clobber``, and identity against every file read, see :mod:`.identity`), records the
files it reads, stages each output (a USD layer, a plot, text) into a temporary folder
``.usdgaze-tmp-<host>-<pid>-<token>`` beside the output, and commits at the end. The commit renames
every staged file over its target, and if one rename fails, puts back what the earlier ones
replaced; a stopping signal (SIGTERM, SIGINT, SIGHUP, SIGQUIT: :data:`.signals.STOPS`) that arrives
during the renames, or during the cleanup after them or after a failure, waits for them. Otherwise,
on any error or stopping signal nothing of the command remains, USD's own temporaries included (they go
into the same folder). After SIGKILL the targets are untouched and the leftover
folder is removed by the next run that writes into that folder.

New files get mode ``0666 & ~umask``; a replaced file keeps its mode and group (and owner, as root).
Symlinks are written through (the target changes, the link stays). OS failures are one-line
:class:`UsdGazeError` naming the path and the OS's reason, exit 2: they are the user's to fix.

The temporaries' names, the sweep and the checks of a claimed path are in :mod:`.paths`.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import signal
import threading
from pathlib import Path
from typing import Callable

from usdgaze.errors import Interrupted, UsdGazeError, usd_failure
from usdgaze.files.signals import later_if_importing, stops_to_handle
from usdgaze.files.identity import Identities, real_path
from usdgaze.files.paths import (TMP_PREFIX, _foreign_layer, _host, _name_max, _special_kind, _text_usd, _unfollowed,
                                 sweep)

_REASONS = (errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EPERM, errno.EDQUOT, errno.EFBIG, errno.EIO,
            errno.ENAMETOOLONG, errno.ENOENT, errno.ENOTDIR, errno.EISDIR)


def os_reason(exc: BaseException) -> str:
    """The OS's words for an OSError, or for the OS failure inside a USD error message."""
    if isinstance(exc, OSError):
        return exc.strerror or str(exc)
    if isinstance(exc, UnicodeError):  # a name of bytes that are not UTF-8 (os.fsdecode's surrogates)
        return "the name is not UTF-8, and OpenUSD takes only UTF-8 file names"
    text = str(exc)
    for code in _REASONS:
        if os.strerror(code) in text:
            return os.strerror(code)
    return usd_failure(exc)


def current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


class _Staged:
    def __init__(self, target: Path, flag: str, keep_mode: int | None, owner: tuple[int, int] | None = None) -> None:
        self.target = target
        self.flag = flag
        self.keep_mode = keep_mode
        self.owner = owner
        """(uid, gid) of the file replaced; None for a new file."""
        self.temp: Path | None = None
        self.foreign: str | None = None
        """The first prim of the USD layer at ``target`` when usdgaze did not write it."""
        self.shown: Path = target


class Outputs:
    """One command's outputs, all or none. Use as a context manager; ``commit`` on success."""

    commits = 0
    """Commits completed in this process: a command whose outputs are in place is past interrupting."""

    def __init__(self, no_clobber: bool = False, ids: Identities | None = None) -> None:
        self.no_clobber = no_clobber
        self.ids = ids if ids is not None else Identities()
        self._claims: dict[Path, _Staged] = {}
        self._tmpdirs: dict[Path, Path] = {}
        self._mode = 0o666 & ~current_umask()
        self._old_handlers: dict[int, object] = {}
        self._made: list[Path] = []
        self._locks: dict[str, int] = {}
        """Folder locks (real path: descriptor) held until the outputs are in place or removed (``lock``)."""
        self._wanted: set[str] = set()
        """Real paths of the folders ``make_folder`` was asked for (see ``_rewanted``)."""
        self._done = False
        self._committing = False
        self._closing = False
        self._pending: int | None = None
        self._raised = False
        """The handler has raised Interrupted: a further signal waits for the cleanup (``_on_signal``)."""

    # -- context: signals and cleanup --------------------------------------------------------------
    def __enter__(self) -> "Outputs":
        if threading.current_thread() is threading.main_thread():
            for sig in stops_to_handle():
                self._old_handlers[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None and not self._done:
                self.commit()
        finally:
            # From here a signal waits for the cleanup: raised inside it, it would leave temporaries
            # and this command's handlers in place (a pool stopping its workers signals them twice).
            self._closing = True
            try:
                self.abort()
            finally:
                for sig, handler in self._old_handlers.items():
                    signal.signal(sig, handler)
                self._old_handlers.clear()
                self._unlock()
        if self._pending is not None and not isinstance(exc, Interrupted):  # a signal is never lost
            if exc is None:
                raise Interrupted(self._pending, "every output had been written when it stopped")
            raise Interrupted(self._pending) from exc

    def _on_signal(self, signum, frame) -> None:
        # Renames (or their rollback) and cleanup run to their end. So does the unwinding of an
        # Interrupted already raised: a second signal (a pool's SIGTERM right after the terminal's
        # SIGINT) raised again, at the first instruction of __exit__, skipped the cleanup and left
        # the temporary folder behind.
        if self._committing or self._closing or self._raised:
            self._pending = signum
            return
        if later_if_importing(signum, frame):  # raised there, the import could swallow it
            return
        self._raised = True
        raise Interrupted(signum)  # not KeyboardInterrupt: click would turn that into "Aborted!"

    def lock(self, folder: str | os.PathLike) -> None:
        """Hold an exclusive lock on ``folder`` until this command's outputs are renamed into place (or
        removed): taken before reading a file the command edits there (``--sublayer-into``), so that
        another command's edit of it waits and then reads this one's (:mod:`.locks`)."""
        from usdgaze.files.locks import lock_folder

        real = os.path.realpath(folder)
        if real in self._locks:  # held: a second flock on another descriptor would wait for ever
            return
        fd = lock_folder(real)
        if fd is not None:
            self._locks[real] = fd

    def _unlock(self) -> None:
        while self._locks:
            with contextlib.suppress(OSError):
                os.close(self._locks.popitem()[1])

    # -- reads and claims --------------------------------------------------------------------------
    def read(self, path: str | os.PathLike, what: str = "input") -> None:
        """Record a file the command reads (an output may never be it)."""
        self.ids.read(path, what)

    def claimed(self, path: str | os.PathLike) -> bool:
        return self.claimed_by(path) is not None

    def claimed_by(self, path: str | os.PathLike) -> str | None:
        """The flag of the output claimed at ``path`` (through a symlink or not), ``None`` where none is."""
        item = self._claims.get(real_path(path)) or self._claims.get(_unfollowed(path))
        return item.flag if item else None

    def claim(self, path: str | os.PathLike, flag: str, edit: bool = False, follow: bool = True) -> Path:
        """Check that ``path`` can be written and reserve it; returns the path to report.

        ``edit``: the file must exist and is replaced by an edited copy (``--sublayer-into``); it
        keeps its mode and a read-only file is refused. ``follow=False``: a symlink at ``path`` is
        replaced, not written through (for files a command names itself inside a given folder).
        """
        shown = Path(path)
        target = real_path(path) if follow else _unfollowed(path)
        folder = target.parent
        self._rewanted(folder)
        if not os.path.exists(folder):  # os.path: Path.exists() raises for a name over NAME_MAX
            if follow and os.path.islink(shown):  # a dangling link: its target's folder, not the link's
                raise UsdGazeError(f"{shown}: links to {target}, whose folder {folder} does not exist")
            raise UsdGazeError(f"{shown}: folder {shown.parent} does not exist")
        if not folder.is_dir():
            raise UsdGazeError(f"{shown}: {shown.parent} is not a folder")
        if len(os.fsencode(target.name)) > _name_max(folder):
            raise UsdGazeError(f"{shown}: cannot write ({os.strerror(errno.ENAMETOOLONG)})")
        if target.is_dir():
            raise UsdGazeError(f"{shown}: {flag} names a folder, expected a file")
        kind = _special_kind(target)
        if kind:  # the rename would put a plain file where a device, pipe or socket was
            raise UsdGazeError(f"{shown}: {flag} names {kind}, not a regular file")
        keep_mode = owner = None
        if target.exists() and not target.is_symlink():
            st = target.stat()
            keep_mode, owner = st.st_mode & 0o7777, (st.st_uid, st.st_gid)
            if edit and not (st.st_mode & 0o222 and os.access(target, os.W_OK)):
                raise UsdGazeError(f"{shown}: {flag} names a read-only file; refusing to replace it (make it writable first)")
            if self.no_clobber and not edit:
                raise UsdGazeError(f"{shown}: {flag} exists and --no-clobber is set")
        elif edit:
            raise UsdGazeError(f"{shown}: no such file for {flag} to edit")
        self.ids.write(path if follow else target, flag, follow=follow)
        self._tmpdir(folder, shown)  # a folder we cannot write into is found now, before any work
        item = self._claims[target] = _Staged(target, flag, keep_mode, owner)
        if keep_mode is not None and not edit:
            item.foreign = _foreign_layer(target)
            item.shown = shown
        return shown

    def check_replaceable(self) -> None:
        """Refuse to replace a USD layer usdgaze did not write (a typo for an output name must not cost
        a shot's source layer). Said once the command has recorded what it reads, so an output that is
        one of its inputs is said as that; every output is checked again before it is staged."""
        for item in self._claims.values():
            if item.foreign:
                raise UsdGazeError(f"{item.shown}: {item.flag} names a USD layer usdgaze did not write (it holds "
                                   f"{item.foreign}); refusing to replace it: remove it first or name another file")

    # -- staging -----------------------------------------------------------------------------------
    def stage_with(self, path: str | os.PathLike, write: Callable[[str], None]) -> None:
        """Stage an output by calling ``write(temp_path)``; the temp has the target's name and suffix."""
        item = self._claims.get(real_path(path)) or self._claims.get(_unfollowed(path))
        if item is None:
            raise RuntimeError(f"{path}: staged without being claimed")  # a bug in a command
        self.check_replaceable()
        tmpdir = self._tmpdir(item.target.parent, path)
        temp = tmpdir / item.target.name
        try:
            write(str(temp))
            with open(temp, "rb+") as f:
                os.fsync(f.fileno())
            _keep_owner(temp, item.owner)  # before the mode: a chown clears setuid and setgid
            os.chmod(temp, self._mode if item.keep_mode is None else item.keep_mode)
        except UsdGazeError:
            raise
        except Exception as exc:  # OSError, or USD's Tf.ErrorException around one
            raise UsdGazeError(f"{path}: cannot write ({os_reason(exc)})") from None
        item.temp = temp

    def stage_layer(self, path: str | os.PathLike, layer) -> None:
        """Stage a USD layer (Sdf ``Export``; the format follows the suffix, and a ``.usd`` file that
        is replaced keeps its encoding: a text root edited by ``--sublayer-into`` had become a crate)."""
        args = {"format": "usda"} if _text_usd(path) else {}

        def export(temp: str) -> None:
            if not layer.Export(temp, args=args):
                raise OSError(errno.EIO, "USD could not write the layer")
        self.stage_with(path, export)

    def make_folder(self, path: str | os.PathLike) -> None:
        """Create a missing output folder; it is removed again if the command fails."""
        folder = Path(path)
        self._wanted.add(os.path.realpath(folder))
        # os.path, not pathlib: Path.is_dir()/exists() raise for a name over NAME_MAX (ENAMETOOLONG);
        # here it is a folder to make, whose mkdir says why it cannot be.
        if os.path.isdir(folder):
            return
        missing = []
        probe = folder
        while not os.path.exists(probe) and probe != probe.parent:
            missing.append(probe)
            probe = probe.parent
        made = []
        try:
            for level in reversed(missing):  # shallowest first
                try:
                    level.mkdir()
                except FileExistsError:
                    if not level.is_dir():
                        raise
                    continue  # a parallel shot made it just now: not ours to remove on failure
                made.append(level)
        except OSError as exc:
            raise UsdGazeError(f"{folder}: cannot create the folder ({os_reason(exc)})") from None
        finally:
            self._made.extend(reversed(made))  # deepest first

    def _rewanted(self, folder: Path) -> None:
        """Make again a folder ``make_folder`` was asked for and that is gone. Two parallel shots writing
        into one new folder: A made it, B found it there (not B's to remove), A failed and removed it
        (empty then), and B's claim said it does not exist. Once B's temporary is in it, it stays."""
        if str(folder) in self._wanted and not os.path.isdir(folder):
            self.make_folder(folder)

    def stage_text(self, path: str | os.PathLike, text: str) -> None:
        def write(temp: str) -> None:
            with open(temp, "w", newline="", encoding="utf-8") as f:
                f.write(text)
        self.stage_with(path, write)

    def _tmpdir(self, folder: Path, shown) -> Path:
        tmpdir = self._tmpdirs.get(folder)
        if tmpdir is None:
            sweep(folder)
            tmpdir = folder / f"{TMP_PREFIX}{_host()}-{os.getpid()}-{secrets.token_hex(4)}"
            self._tmpdirs[folder] = tmpdir  # first: a signal right after the mkdir still finds it to remove
            try:
                for _ in range(3):  # the folder removed again between the two lines: made again
                    self._rewanted(folder)
                    with contextlib.suppress(FileNotFoundError):
                        tmpdir.mkdir(mode=0o700)
                        break
                else:
                    tmpdir.mkdir(mode=0o700)
            except OSError as exc:
                del self._tmpdirs[folder]
                raise UsdGazeError(f"{shown}: cannot write into {Path(shown).parent} ({os_reason(exc)})") from None
        return tmpdir

    # -- commit / abort ----------------------------------------------------------------------------
    def commit(self) -> None:
        """Rename every staged output into place; on a failure, restore what was replaced."""
        self._committing = True
        try:
            self._rename_all()
            Outputs.commits += 1
        finally:
            self._committing = False
        if self._pending is not None:
            raise Interrupted(self._pending, "every output had been written when it stopped")

    def _rename_all(self) -> None:
        items = [i for i in self._claims.values() if i.temp is not None]
        done: list[tuple[_Staged, Path | None]] = []
        try:
            for item in items:
                backup = None
                if item.target.exists():
                    backup = item.temp.with_name(f".previous-{item.target.name}")
                    try:
                        os.link(item.target, backup)
                    except OSError:
                        backup = None  # no hard links here: the rename alone is still atomic
                os.replace(item.temp, item.target)
                done.append((item, backup))
        except BaseException as exc:  # an OS failure, or a signal where no handler defers it
            for put, backup in reversed(done):
                with contextlib.suppress(OSError):
                    if backup is not None:
                        os.replace(backup, put.target)
                    elif put.keep_mode is None:
                        os.unlink(put.target)
            if isinstance(exc, OSError):
                raise UsdGazeError(f"{item.target}: cannot write ({os_reason(exc)})") from None
            raise
        for folder in self._tmpdirs:
            with contextlib.suppress(OSError):
                fd = os.open(folder, os.O_RDONLY)
                try:
                    os.fsync(fd)
                finally:
                    os.close(fd)
        self._done = True

    def abort(self) -> None:
        """Remove every temporary (also after a commit: the backups of replaced files)."""
        for tmpdir in self._tmpdirs.values():
            shutil.rmtree(tmpdir, ignore_errors=True)
        self._tmpdirs.clear()
        if not self._done:
            for folder in self._made:  # deepest first
                with contextlib.suppress(OSError):
                    folder.rmdir()
        self._made.clear()


def _keep_owner(temp: Path, owner: tuple[int, int] | None) -> None:
    """Give the staged replacement the group of the file it replaces, and its owner where we may (root):
    a rename puts a new inode in place, made ours, and a show's shared group lost write access to the
    override it shared. Where the group is not ours to give, the file is ours as any new one is."""
    if owner is None or not hasattr(os, "chown"):
        return
    uid, gid = owner
    with contextlib.suppress(PermissionError):
        os.chown(temp, uid if os.geteuid() == 0 else -1, gid)


@contextlib.contextmanager
def outputs_of(outputs: "Outputs | None"):
    """``outputs`` when a command passes its own, else a new one committed when the block ends."""
    if outputs is not None:
        yield outputs
    else:
        with Outputs() as own:
            yield own
