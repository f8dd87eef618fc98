"""What ``attend --physics`` recorded per simulated character, read back for the review: the layer's
``customLayerData["usdgaze:physics"][<skeleton path>]``, its per-step measures (``frames``) as
arrays on the composed stage's clock, and the times its problems name.

A malformed record (a measure of another length than ``seconds``, no ``seconds``, a value that is no
number) is a one-line error naming the layer and the key, as a malformed ``usdgaze`` record is.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from usdgaze.errors import UsdGazeError

PHYSICS_KEY = "usdgaze:physics"
"""``customLayerData["usdgaze:physics"]``: skeleton path -> ``report``, ``problems``, ``frames``."""

_TIMES = re.compile(r"(?<![\d.])(?<!within )(\d+\.\d\d)(?:-(\d+\.\d\d))? s\b")
"""A problem's time (``at 0.42 s``, ``by 1.20 s``) or span (``over 1.37-1.50 s``), as the pass says
them (two decimals); a duration (``within 0.3 s of``) is none."""


@dataclass
class PhysicsMeasures:
    """One simulated character's per-step measures, on the review's clock (seconds from the stage start)."""

    skeleton: str
    seconds: np.ndarray
    """The control steps' times ``(K,)``."""
    frames: dict[str, np.ndarray]
    """Every per-step measure of the record but ``seconds``, by its key, ``(K,)`` (NaN: no value)."""
    problems: list[str] = field(default_factory=list)
    """The shot's problems, as the pass said them (none: empty)."""
    problem_times: list[tuple[float, float]] = field(default_factory=list)
    """(start, end) seconds of each time a problem names (start == end for an instant)."""


def _key(skeleton: str, *keys: str) -> str:
    return f'customLayerData["{PHYSICS_KEY}"]["{skeleton}"]' + "".join(f'["{k}"]' for k in keys)


def _numbers(value, where: str, layer_file: str) -> np.ndarray:
    """A list of numbers (None: NaN) as floats, or a one-line error."""
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__"):
        raise UsdGazeError(f"{layer_file}: {where} is not a list of numbers")
    try:
        return np.array([np.nan if v is None else float(v) for v in value], dtype=float)
    except (TypeError, ValueError):
        raise UsdGazeError(f"{layer_file}: {where} holds a value that is no number") from None


def _frames(skeleton: str, entry, layer_file: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``entry["frames"]`` checked: increasing finite ``seconds``, every other measure as long."""
    if not isinstance(entry, Mapping):
        raise UsdGazeError(f"{layer_file}: {_key(skeleton)} is not a dictionary")
    frames = entry.get("frames")
    if not isinstance(frames, Mapping):
        raise UsdGazeError(f"{layer_file}: {_key(skeleton, 'frames')} is missing or not a dictionary")
    if "seconds" not in frames:
        raise UsdGazeError(f"{layer_file}: {_key(skeleton, 'frames', 'seconds')} is missing")
    seconds = _numbers(frames["seconds"], _key(skeleton, "frames", "seconds"), layer_file)
    if not len(seconds) or not np.all(np.isfinite(seconds)) or np.any(np.diff(seconds) <= 0):
        raise UsdGazeError(f"{layer_file}: {_key(skeleton, 'frames', 'seconds')} is not increasing times")
    out = {}
    for name in sorted(frames):
        if name == "seconds":
            continue
        where = _key(skeleton, "frames", name)
        values = _numbers(frames[name], where, layer_file)
        if len(values) != len(seconds):
            raise UsdGazeError(f"{layer_file}: {where} holds {len(values)} values for {len(seconds)} seconds")
        out[str(name)] = values
    return seconds, out


def problem_times(problems: list[str]) -> list[tuple[float, float]]:
    """The times and spans (seconds, the pass's clock) the problems name, in order."""
    out = []
    for text in problems:
        for a, b in _TIMES.findall(text):
            out.append((float(a), float(b or a)))
    return out


def read_physics(custom: Mapping, skeletons: list[str], layer_file: str,
                 clock: Callable[[np.ndarray], np.ndarray]) -> dict[str, PhysicsMeasures]:
    """The physics record of each of ``skeletons`` the layer's ``customLayerData`` holds (none: empty).

    ``clock`` maps the record's seconds (from the input's start) to the composed stage's (a layer
    sublayered at an offset); only the characters reviewed are read.
    """
    record = custom.get(PHYSICS_KEY)
    if record is None:
        return {}
    if not isinstance(record, Mapping):
        raise UsdGazeError(f'{layer_file}: customLayerData["{PHYSICS_KEY}"] is not a dictionary')
    out = {}
    for skeleton in skeletons:
        if skeleton not in record:
            continue
        entry = record[skeleton]
        seconds, frames = _frames(skeleton, entry, layer_file)
        said = entry.get("problems") or []
        if isinstance(said, str):
            said = [said]
        problems = [str(p) for p in said if str(p) != "none"]
        spans = [tuple(float(t) for t in clock(np.array(s))) for s in problem_times(problems)]
        out[skeleton] = PhysicsMeasures(skeleton, clock(seconds), frames, problems, spans)
    return out
