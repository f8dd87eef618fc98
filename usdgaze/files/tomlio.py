"""TOML loading (tomllib on Python >= 3.11, tomli before) with one-line errors."""

from __future__ import annotations

from pathlib import Path

from usdgaze.errors import UsdGazeError
from usdgaze.files.kinds import special_kind

try:
    import tomllib as _toml
except ModuleNotFoundError:  # Python 3.10
    try:
        import tomli as _toml
    except ModuleNotFoundError:
        _toml = None


def load_toml(path: str | Path, error: type[UsdGazeError] = UsdGazeError) -> dict:
    """Parse a TOML file, raising ``error`` with the file and the parser's reason."""
    path = Path(path)
    if _toml is None:
        raise error(f"{path}: reading TOML on Python 3.10 needs tomli: pip install tomli")
    try:
        # A pipe would block the open until a writer comes (the command hung); a device reads as an
        # empty table (/dev/null: "lacks" every key). Both are refused as the other inputs are.
        kind = special_kind(path.stat().st_mode)
        if kind:
            raise error(f"{path}: is {kind}, not a regular file")
        with path.open("rb") as f:
            data = f.read()
        # A UTF-8 byte-order mark (Notepad, Excel's "UTF-8" export) is not text: the parser said
        # "Invalid statement (at line 1, column 1)" of a file that looks right. Read past it, as the
        # CSV sheets are (utf-8-sig).
        return _toml.loads(data.removeprefix(b"\xef\xbb\xbf").decode("utf-8"))
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, expected a TOML file") from None
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror or exc})") from None
    except _toml.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML ({exc})") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not valid TOML (not UTF-8 text at byte {exc.start})") from None
