"""The trial sheet: one row per example trial with its file, known target and optional manual crop.

CSV: a header row with ``file``, ``yaw``, ``pitch`` and optionally ``trial``, ``crop_start``,
``crop_end`` (frames: 0-based sample indices into the file, end inclusive, whatever numbers the capture
software shows: C3D's frame 1, or a clip's first time sample, is 0) and ``skeleton`` (the
Skeleton prim of a UsdSkel clip); ``#`` comment and blank lines, rows of empty cells and unnamed empty columns (a spreadsheet's) are skipped, a row with more cells
than the header is refused, and messages name a row by its line in the file. TOML: ``[[trial]]``
tables with the same keys (``crop = [start, end]`` also works), an optional top-level ``markers =
"markerset.toml"`` and an optional ``[skeleton]`` binding table. Relative paths are relative to the
sheet. Yaw is positive toward the subject's left and never wrapped (-180 and +180 are a right and a
left turn).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

from usdgaze.errors import UsdGazeError
from usdgaze.ingest.markers import SkeletonBinding, skeleton_binding
from usdgaze.files.kinds import not_a_file
from usdgaze.files.tomlio import load_toml

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


class SheetError(UsdGazeError):
    """The trial sheet is malformed."""


@dataclass(frozen=True)
class Trial:
    """One example: its name, file, known target (degrees) and optional manual crop (frames)."""

    name: str
    file: Path
    yaw: float
    pitch: float
    crop: tuple[int, int] | None = None
    skeleton: str | None = None
    written: str | None = field(default=None, compare=False)
    """The file as the sheet spells it (``trials/A.c3d``), for messages; ``file`` is it resolved."""

    @property
    def is_skeletal(self) -> bool:
        return self.file.suffix.lower() in USD_SUFFIXES


@dataclass(frozen=True)
class Sheet:
    """The parsed sheet: trials in order, plus what a TOML sheet may add."""

    path: Path
    trials: tuple[Trial, ...]
    markers: Path | None = None
    skeleton: SkeletonBinding = field(default_factory=SkeletonBinding)


_ALIASES = {"name": "trial", "target_yaw": "yaw", "target_pitch": "pitch", "path": "file"}


def _number(value, key: str, where: str) -> float:
    if isinstance(value, bool):  # TOML true/false: float() would read them as 1 and 0
        raise SheetError(f"{where}: {key} {str(value).lower()} is not a number")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SheetError(f"{where}: {key} '{value}' is not a number") from None
    if not math.isfinite(x):
        raise SheetError(f"{where}: {key} is {value}")
    return x


def _frame(value, key: str, where: str) -> int:
    x = _number(value, key, where)
    if x != int(x) or x < 0:
        raise SheetError(f"{where}: {key} '{value}' is not a frame index (a whole number >= 0)")
    return int(x)


_KEYS = ("file", "yaw", "pitch", "trial", "crop", "crop_start", "crop_end", "skeleton")
_TOP_KEYS = ("trial", "trials", "markers", "skeleton")


def _unknown(keys, known, what: str, where: str) -> None:
    extra = [k for k in keys if k not in known]
    if extra:
        raise SheetError(f"{where}: unknown {what} '{extra[0]}' (known: {', '.join(known)})")


def _trial(row: dict, index: int, base: Path, where: str, seen: set[str]) -> Trial:
    row = {_ALIASES.get(str(k).strip().lower(), str(k).strip().lower()): v for k, v in row.items() if k is not None}
    row = {k: (v.strip() if isinstance(v, str) else v) for k, v in row.items()}
    _unknown(row, _KEYS, "key", where)
    for key in ("file", "yaw", "pitch"):
        if row.get(key) in (None, ""):
            raise SheetError(f"{where}: no {key}")
    # TOML values keep their types: a path or a name must be text (a number names a trial too).
    for key, kinds, what in (("file", (str,), "a path"), ("skeleton", (str,), "a Skeleton prim path"),
                             ("trial", (str, int), "a name")):
        value = row.get(key)
        if value is not None and (not isinstance(value, kinds) or isinstance(value, bool)):
            raise SheetError(f"{where}: {key} {value!r} is not {what}")
    file = Path(str(row["file"]))
    file = file if file.is_absolute() else base / file
    name = str(row.get("trial") or "") or file.stem
    if name in seen:
        raise SheetError(f"{where}: trial name '{name}' appears twice")
    seen.add(name)
    yaw = _number(row["yaw"], "yaw", where)
    pitch = _number(row["pitch"], "pitch", where)
    if not -180.0 <= yaw <= 180.0 or not -90.0 <= pitch <= 90.0:
        raise SheetError(f"{where}: target ({yaw:g}, {pitch:g}) is outside yaw -180..180, pitch -90..90")
    crop = None
    if row.get("crop") is not None:
        if not isinstance(row["crop"], (list, tuple)) or len(row["crop"]) != 2:
            raise SheetError(f"{where}: crop must be [start, end] (frames), got {row['crop']!r}")
        row["crop_start"], row["crop_end"] = row["crop"]
    start, end = row.get("crop_start"), row.get("crop_end")
    if start not in (None, "") or end not in (None, ""):
        if start in (None, "") or end in (None, ""):
            raise SheetError(f"{where}: give both crop_start and crop_end, or neither")
        crop = (_frame(start, "crop_start", where), _frame(end, "crop_end", where))
        if crop[1] <= crop[0]:
            raise SheetError(f"{where}: crop_end {crop[1]} is not after crop_start {crop[0]}")
    skeleton = row.get("skeleton") or None
    return Trial(name=name, file=file, yaw=yaw, pitch=pitch, crop=crop, skeleton=skeleton, written=str(row["file"]))


def _csv_lines(path: Path) -> list[tuple[int, str]]:
    """The sheet's lines that hold data, each with its line number in the file (1-based)."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            numbered = list(enumerate(f, 1))
    except UnicodeDecodeError as exc:
        raise SheetError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise SheetError(f"{path}: cannot read ({exc.strerror})") from None
    return [(n, line) for n, line in numbered if line.strip() and not line.lstrip().startswith("#")]


def _check_separator(fieldnames: list[str], path: Path) -> None:
    """A header of one cell holding ';' or a tab is a sheet saved with another separator (a spreadsheet
    in a locale whose decimal mark is the comma): say so, not 'unknown column'."""
    if len(fieldnames) == 1:
        used = [sep for sep in (";", "\t") if sep in fieldnames[0]]
        if used:
            raise SheetError(f"{path}: the header is one cell ({fieldnames[0].strip()!r}); the cells of a CSV "
                             f"sheet are separated by commas, this one by {used[0]!r}")


def _row(fieldnames: list[str], fields: list[str], where: str) -> dict | None:
    """The row's cells by column, None for a row of empty cells. A spreadsheet writes columns it
    once formatted as empty header cells (``trial,file,yaw,pitch,,``) and rows of empty cells:
    those are skipped, and a value under an unnamed column is refused (it was ``unknown key ''``,
    blamed on the first trial's row)."""
    if not any(cell.strip() for cell in fields):
        return None
    for k, (head, cell) in enumerate(zip(fieldnames, fields)):
        if not head.strip() and cell.strip():
            raise SheetError(f"{where}: '{cell.strip()}' in column {k + 1}, which the header leaves unnamed")
    return {head: cell for head, cell in zip(fieldnames, fields) if head.strip()}


def _csv_trials(path: Path, base: Path, seen: set[str]) -> list[Trial]:
    """The trials of a CSV sheet; a row is named by its line in the file, as an editor shows it."""
    kept = _csv_lines(path)
    reader = csv.reader(line for _, line in kept)
    fieldnames = next(reader, None)
    if not fieldnames:
        raise SheetError(f"{path}: empty sheet (expected a header with file, yaw, pitch)")
    _check_separator(fieldnames, path)
    named = [_ALIASES.get(h.strip().lower(), h.strip().lower()) for h in fieldnames if h.strip()]
    twice = [h for k, h in enumerate(named) if h in named[:k]]
    if twice:
        raise SheetError(f"{path}: column '{twice[0]}' appears twice in the header")
    _unknown(named, tuple(k for k in _KEYS if k != "crop"), "column", str(path))
    missing = [k for k in ("file", "yaw", "pitch") if k not in set(named)]
    if missing:
        raise SheetError(f"{path}: the header lacks column {missing[0]} (has {', '.join(fieldnames)})")
    trials = []
    while True:
        first = reader.line_num  # lines consumed so far: the next row starts at kept[first]
        fields = next(reader, None)
        if fields is None:
            return trials
        where = f"{path} row {kept[first][0]}"
        if len(fields) > len(fieldnames):
            # Extra cells would be dropped without a word; a decimal comma ("1,5") shifts every
            # value after it, so even an empty extra cell is refused.
            raise SheetError(f"{where}: {len(fields)} cells, but the header names {len(fieldnames)} "
                             f"({', '.join(fieldnames)}); quote a value that holds a comma")
        row = _row(fieldnames, fields, where)
        if row:
            trials.append(_trial(row, len(trials), base, where, seen))


def load_sheet(path: str | Path) -> Sheet:
    """Read a CSV or TOML trial sheet."""
    path = Path(path)
    problem = not_a_file(path)
    if problem:  # a pipe or a device is no trial sheet, but it exists: say what it is
        raise SheetError(f"{path}: {'no such trial sheet' if problem == 'no such file' else problem}")
    base = path.parent
    seen: set[str] = set()
    markers = None
    binding = SkeletonBinding()
    if path.suffix.lower() == ".toml":
        data = load_toml(path, SheetError)
        _unknown(data, _TOP_KEYS, "key", str(path))
        if "trial" in data and "trials" in data:  # one of the two was dropped without a word
            raise SheetError(f"{path}: both [[trial]] and [[trials]] tables; name every trial [[trial]]")
        rows = data.get("trial", data.get("trials", []))
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise SheetError(f"{path}: trials must be [[trial]] tables")
        trials = [_trial(r, i, base, f"{path} trial {i + 1}", seen) for i, r in enumerate(rows)]
        if data.get("markers"):
            markers = Path(str(data["markers"]))
            markers = markers if markers.is_absolute() else base / markers
        if "skeleton" in data:
            binding = skeleton_binding(data["skeleton"], str(path))
    else:
        trials = _csv_trials(path, base, seen)
    if not trials:
        raise SheetError(f"{path}: no trials")
    return Sheet(path=path, trials=tuple(trials), markers=markers, skeleton=binding)
