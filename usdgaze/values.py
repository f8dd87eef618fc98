"""Value checks shared by the CLI, the Python API and the batch manifest (one function each).

A ``label(key, value)`` says how the caller names a value in its one-line error: the CLI writes
``--fixation 0.0``, a manifest ``shots.toml: job 2 'walk': fixation = -2``.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Callable

from usdgaze.errors import UsdGazeError

Label = Callable[[str, object], str]

MAX_SHIFT_TIME = 1e7
"""Largest |time| of a shift, time codes or seconds (about 115 days at 1 code a second)."""
MAX_FIXATION_M = 1e6
"""Beyond a thousand kilometres the lines of sight are parallel; larger is a typo."""
MAX_TARGET_DISTANCE_M = 1e9
"""Beyond this a look target, object, stone or obstacle is only a direction; its distance in stage units
would overflow squared."""
MAX_ALPHA = 100.0
"""Largest ``attend --alpha``, the belief's process noise per second in (0.1 m)^2: at 100 an unwatched object's
position spreads by 1 m (one standard deviation) in a second, a belief that knows nothing it is not
looking at (the paper uses 0.2). 1e300 overflowed the covariances: exit 0 under 30 lines of numpy warnings."""
MAX_OBSTACLE_RADIUS_M = 10.0
"""Largest ``gaze:object:radius`` of a physics obstacle (``usdgaze:physics:task = "obstacle"``). Its cost
reaches radius + 0.1 m from the body and the planner sees 1.6 s (about 2 m of walking) ahead: past
10 m the sphere is a hill or a building, flat over any stride, not something a person walks round.
A 1e6 m radius swallowed the character: "touched" from the first step, 1000 km of overlap, exit 0."""

_SHIFT = re.compile(r"^\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)(s?)\s*:\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)"
                    r"\s*:\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*$")


SHIFT_FORM = "expected TIME:YAW:PITCH, e.g. 48:60:-10 or 2.5s:60:-10"
_NUMBER = re.compile(r"^\s*[-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?\s*$")
_TIME_FIELD = re.compile(r"^\s*[-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?s?\s*$")


def _bad_field(text: object) -> str:
    """Which field of a ``TIME:YAW:PITCH`` text that :data:`_SHIFT` refuses is wrong, as the start of the
    message (``YAW 'abc' is not a number; ``, ``PITCH missing; ``), or nothing where there is no one to name."""
    fields = text.split(":") if isinstance(text, str) and text.strip() else []
    names = ("TIME", "YAW", "PITCH")
    if not 0 < len(fields) <= 3:
        return ""
    for name, value, form in zip(names, fields, (_TIME_FIELD, _NUMBER, _NUMBER)):
        if not form.match(value):  # a field written wrong first: '2s:abc' is a bad YAW before a missing PITCH
            what = "a time code (or seconds with an 's' suffix)" if name == "TIME" else "a number"
            return f"{name} '{value}' is not {what}; "
    return f"{' and '.join(names[len(fields):])} missing; " if len(fields) < 3 else ""


def cli_label(key: str, value: object) -> str:
    return f"--{key.replace('_', '-')} {value}"


@dataclass(frozen=True)
class ShiftRequest:
    """A shift as the user wrote it: at a time code, or at seconds from the stage start."""

    time: float
    seconds: bool
    yaw: float
    pitch: float

    @classmethod
    def parse(cls, text: object, label: Label | None = None) -> "ShiftRequest":
        """Parse ``TIME:YAW:PITCH`` (``TIME`` a time code, or seconds with an ``s`` suffix)."""
        where = label("shift", repr(text)) if label else f"--shift '{text}'"
        m = _SHIFT.match(text) if isinstance(text, str) else None
        if not m:
            raise UsdGazeError(f"{where}: {_bad_field(text)}{SHIFT_FORM}")
        shift = cls(float(m.group(1)), m.group(2) == "s", float(m.group(3)), float(m.group(4)))
        if not all(math.isfinite(v) for v in (shift.time, shift.yaw, shift.pitch)):
            raise UsdGazeError(f"{where}: values must be finite")
        if abs(shift.time) > MAX_SHIFT_TIME:
            raise UsdGazeError(f"{where}: time must lie in [-{MAX_SHIFT_TIME:g}, {MAX_SHIFT_TIME:g}]")
        if abs(shift.pitch) > 90.0:
            raise UsdGazeError(f"{where}: pitch must lie in [-90, 90] deg")
        if abs(shift.yaw) > 360.0:
            raise UsdGazeError(f"{where}: yaw must lie in [-360, 360] deg (more than a full turn is no gaze shift)")
        return shift

    def to_shift(self, clip):
        from usdgaze.passes.options import Shift

        seconds = self.time if self.seconds else (self.time - clip.start_time) / clip.time_codes_per_second
        return Shift(seconds, self.yaw, self.pitch)

    def __str__(self) -> str:
        return f"{self.time:g}{'s' if self.seconds else ''}:{self.yaw:g}:{self.pitch:g}"


def check_shifts(shifts: object, label: Label) -> list[ShiftRequest]:
    """A list of ``TIME:YAW:PITCH`` strings (or parsed shifts) -> parsed shifts; at least one."""
    if isinstance(shifts, (str, bytes)) or not isinstance(shifts, (list, tuple)):
        raise UsdGazeError(f"{label('shifts', repr(shifts))}: expected a list of \"TIME:YAW:PITCH\" strings")
    if not shifts:
        raise UsdGazeError("no --shift given; nothing to do" if label is cli_label
                           else f"{label('shifts', '[]')}: no shift given; nothing to do")
    return [s if isinstance(s, ShiftRequest) else ShiftRequest.parse(s, None if label is cli_label else label)
            for s in shifts]


def check_fixation(value: object, label: Label) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UsdGazeError(f"{label('fixation', repr(value))}: expected a distance in metres")
    if not (math.isfinite(value) and 0.0 < value <= MAX_FIXATION_M):
        raise UsdGazeError(f"{label('fixation', value)}: must be a positive distance in metres "
                           f"(at most {MAX_FIXATION_M:g})")
    return float(value)


def check_pass_options(options, label: Label) -> None:
    """Every number of a :class:`usdgaze.passes.options.PassOptions` finite; distances positive."""
    check_fixation(options.fixation_m, lambda key, value: label("fixation", value))
    for f in dataclasses.fields(options):
        value = getattr(options, f.name)
        if f.name == "fixation_m" or not isinstance(value, (int, float)) or isinstance(value, bool):
            continue
        if not math.isfinite(value) or value < 0.0:
            raise UsdGazeError(f"{label(f.name, value)}: must be a finite, non-negative number")
