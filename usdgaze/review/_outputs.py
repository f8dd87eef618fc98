"""The project's one writer for review outputs (``usdgaze.files.transaction.Outputs``).

Until that module is on this branch, a minimal stand-in with the same calls (claim, read,
make_folder, stage_with, commit) keeps the review commands atomic; it goes when ``usdgaze.files``
lands.
"""

from __future__ import annotations

try:  # pragma: no cover - depends on which branch is merged
    from usdgaze.files.transaction import Outputs  # noqa: F401
except ImportError:  # pragma: no cover
    import os
    import shutil
    import tempfile
    from pathlib import Path

    from usdgaze.errors import UsdGazeError

    class Outputs:  # type: ignore[no-redef]
        def __init__(self, no_clobber: bool = False) -> None:
            self._staged: dict[Path, Path] = {}
            self._claimed: set[Path] = set()
            self._reads: set[Path] = set()
            self._made: list[Path] = []
            self._tmp: Path | None = None
            self._done = False
            umask = os.umask(0)
            os.umask(umask)
            self._mode = 0o666 & ~umask

        def __enter__(self):
            return self

        def __exit__(self, exc_type, exc, tb) -> None:
            try:
                if exc_type is None and not self._done:
                    self.commit()
            finally:
                if self._tmp is not None:
                    shutil.rmtree(self._tmp, ignore_errors=True)
                if not self._done:
                    for folder in reversed(self._made):
                        shutil.rmtree(folder, ignore_errors=True)

        def read(self, path, what: str = "input") -> None:
            self._reads.add(Path(os.path.realpath(path)))

        def claim(self, path, flag: str, edit: bool = False, follow: bool = True) -> Path:
            shown = Path(path)
            target = Path(os.path.realpath(path))
            if not target.parent.is_dir():
                raise UsdGazeError(f"{shown}: folder {shown.parent} does not exist")
            if target in self._reads:
                raise UsdGazeError(f"{shown}: {flag} would overwrite an input")
            self._claimed.add(target)
            return shown

        def make_folder(self, path) -> None:
            folder = Path(path)
            if not folder.is_dir():
                folder.mkdir(parents=True)
                self._made.append(folder)

        def stage_with(self, path, write) -> None:
            target = Path(os.path.realpath(path))
            if self._tmp is None:
                self._tmp = Path(tempfile.mkdtemp(prefix=".usdgaze-tmp-", dir=target.parent))
            temp = self._tmp / f"{len(self._staged)}-{target.name}"
            write(str(temp))
            os.chmod(temp, self._mode)
            self._staged[target] = temp

        def commit(self) -> None:
            for target, temp in self._staged.items():
                os.replace(temp, target)
            self._done = True
