"""Gaze directives as a user writes them (flags or a GazeScheduleAPI schedule), before any clip is read.

Syntax (``TIME`` a time code, or seconds from the stage start with an ``s`` suffix; options in any
order after the time, each ``:key=value``):

* ``--shift TIME:YAW:PITCH[:weight=W][:blend=B]``
* ``--look-at TARGET@TIME[:weight=W][:blend=B]``, ``TARGET`` a prim path or a world point ``X,Y,Z``
* ``--release TIME[:blend=B]``: a gaze shift back to the base motion's gaze; with a blend, a fade of
  the gaze weight to 0 over ``B`` instead.

``B`` is in time codes, or seconds with an ``s`` suffix. :func:`str` of a request is its canonical
flag text, so flags and a schedule that say the same thing record the same text.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from usdgaze.errors import UsdGazeError

_NUM = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
_TIME = re.compile(rf"^\s*({_NUM})(s?)\s*$")
_POINT = re.compile(rf"^\s*({_NUM})\s*,\s*({_NUM})\s*,\s*({_NUM})\s*$")
FLAGS = {"shift": "--shift", "look": "--look-at", "release": "--release"}


def _num(text: str) -> str:
    """Shortest text of a float (``120``, ``0.5``, ``1e-05``)."""
    v = float(text) if isinstance(text, str) else float(text)
    return repr(int(v)) if v == int(v) and abs(v) < 1e15 else repr(v)


@dataclass(frozen=True)
class DirectiveRequest:
    """One directive: ``kind`` shift, look or release at ``time`` (time code, or seconds)."""

    kind: str
    time: float
    seconds: bool = False
    yaw: float = 0.0
    pitch: float = 0.0
    target: str | None = None
    """Prim path looked at (look)."""
    point: tuple[float, float, float] | None = None
    """World point looked at (look, no prim)."""
    weight: float = 1.0
    blend: float = 0.0
    blend_seconds: bool = False
    origin: str | None = field(default=None, compare=False, repr=False)
    """Where an authored directive comes from (``FILE:PRIM.ATTRIBUTE entry K``), for messages; flags have none."""
    written: str | None = field(default=None, compare=False, repr=False)
    """The flag's value as the user typed it (``240.960:10:0``, which :func:`str` spells ``240.96:10:0``),
    for messages; a schedule's directives have none."""

    def time_s(self, start_time: float, time_codes_per_second: float) -> float:
        return self.time if self.seconds else (self.time - start_time) / time_codes_per_second

    def blend_s(self, time_codes_per_second: float) -> float:
        return self.blend if self.blend_seconds else self.blend / time_codes_per_second

    def __str__(self) -> str:
        at = f"{_num(self.time)}{'s' if self.seconds else ''}"
        if self.kind == "shift":
            text = f"{at}:{_num(self.yaw)}:{_num(self.pitch)}"
        elif self.kind == "look":
            what = self.target if self.target is not None else ",".join(_num(v) for v in self.point)
            text = f"{what}@{at}"
        else:
            text = at
        if self.weight != 1.0:
            text += f":weight={_num(self.weight)}"
        if self.blend != 0.0:
            text += f":blend={_num(self.blend)}{'s' if self.blend_seconds else ''}"
        return text

    @property
    def flag(self) -> str:
        return f"{FLAGS[self.kind]} {self}"

    @property
    def said(self) -> str:
        """How a message names it: the flag as typed, or where in the schedule it is and what it says."""
        if self.origin:
            return f"{self.origin} ({self.flag})"
        return f"{FLAGS[self.kind]} {self.written.strip()}" if self.written is not None else self.flag


FORMS = {"--shift": "TIME:YAW:PITCH[:weight=W][:blend=B]", "--look-at": "TARGET@TIME[:weight=W][:blend=B]",
         "--release": "TIME[:blend=B]"}


def _time(text: str, flag: str, whole: str, name: str = "TIME") -> tuple[float, bool]:
    m = _TIME.match(text)
    if not m:
        raise UsdGazeError(f"{flag} '{whole}': {name} '{text}' is not a time code (or seconds with an 's' suffix); "
                           f"expected {FORMS[flag]}")
    value = float(m.group(1))
    if not np.isfinite(value):
        raise UsdGazeError(f"{flag} '{whole}': the time must be finite")
    return value, m.group(2) == "s"


def _options(parts: list[str], flag: str, whole: str, allowed: tuple[str, ...]) -> dict:
    out: dict = {}
    for part in parts:
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or key not in allowed or key in out:
            raise UsdGazeError(f"{flag} '{whole}': unknown or repeated option '{part}' (allowed: "
                               f"{', '.join(k + '=' for k in allowed)})")
        if key == "weight":
            try:
                w = float(value)
            except ValueError:
                w = float("nan")
            if not 0.0 <= w <= 1.0:
                raise UsdGazeError(f"{flag} '{whole}': weight must be a number in [0, 1]")
            out["weight"] = w
        else:
            b, in_seconds = _time(value, flag, whole, "blend B")
            if b < 0:
                raise UsdGazeError(f"{flag} '{whole}': blend must be >= 0")
            out["blend"], out["blend_seconds"] = b, in_seconds
    return out


def parse_shift(text: str, label=None) -> DirectiveRequest:
    """``TIME:YAW:PITCH[:weight=W][:blend=B]``."""
    from usdgaze.values import ShiftRequest

    if isinstance(text, str):
        parts = text.split(":")
        head, options = ":".join(parts[:3]), parts[3:]
    else:
        head, options = text, []
    where = label("shift", repr(text)) if label else f"--shift '{text}'"
    if any("=" not in part for part in options):  # a fourth field that is no option
        head = text
    shift = ShiftRequest.parse(head, lambda key, value: where)
    return DirectiveRequest("shift", shift.time, shift.seconds, shift.yaw, shift.pitch,
                            **_options(options, "--shift", text, ("weight", "blend")),
                            written=text if isinstance(text, str) else None)


def parse_look(text: str) -> DirectiveRequest:
    """``TARGET@TIME[:weight=W][:blend=B]`` with TARGET a prim path or ``X,Y,Z``."""
    what, sep, rest = text.rpartition("@")
    if not sep or not what.strip():
        raise UsdGazeError(f"--look-at '{text}': expected TARGET@TIME, e.g. /World/Door@120 or 1,1.6,3@2.5s")
    parts = rest.split(":")
    time, seconds = _time(parts[0], "--look-at", text)
    options = _options(parts[1:], "--look-at", text, ("weight", "blend"))
    m = _POINT.match(what)
    if m:
        point = tuple(float(v) for v in m.groups())
        if not np.isfinite(point).all():
            raise UsdGazeError(f"--look-at '{text}': the point must be finite")
        return DirectiveRequest("look", time, seconds, point=point, **options, written=text)
    target = what.strip()
    if not target.startswith("/"):
        raise UsdGazeError(f"--look-at '{text}': '{target}' is neither an absolute prim path nor a point X,Y,Z")
    return DirectiveRequest("look", time, seconds, target=target, **options, written=text)


def parse_release(text: str) -> DirectiveRequest:
    """``TIME[:blend=B]``."""
    parts = text.split(":")
    time, seconds = _time(parts[0], "--release", text)
    return DirectiveRequest("release", time, seconds, **_options(parts[1:], "--release", text, ("blend",)),
                            written=text)


def check_directives(shifts, look_at, release, look, label=None) -> list[DirectiveRequest]:
    """Parse the three kinds of directive flags (texts or parsed requests), in that order; the eye
    timing must be one the look pass knows. An empty result means: use the SkelRoots' schedules."""
    from usdgaze.passes.look import EYE_TIMINGS
    from usdgaze.values import ShiftRequest

    for key, values in (("shifts", shifts), ("look_at", look_at), ("release", release)):
        if isinstance(values, (str, bytes)) or not isinstance(values, (list, tuple)):
            raise UsdGazeError(f"{key}: expected a list of directive strings, got {values!r}")
    if look.eye_timing not in EYE_TIMINGS:
        raise UsdGazeError(f"--eye-timing {look.eye_timing}: expected one of {', '.join(EYE_TIMINGS)}")
    out: list[DirectiveRequest] = []
    for s in shifts:
        if isinstance(s, ShiftRequest):
            s = DirectiveRequest("shift", s.time, s.seconds, s.yaw, s.pitch)
        out.append(s if isinstance(s, DirectiveRequest) else parse_shift(s, label))
    out += [r if isinstance(r, DirectiveRequest) else parse_look(r) for r in look_at]
    out += [r if isinstance(r, DirectiveRequest) else parse_release(r) for r in release]
    return out
