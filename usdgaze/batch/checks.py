"""The value checks of batch manifest keys (each row of :data:`usdgaze.batch.manifest.KEYS` names
one): ``check(value, label, folder)`` returns the normalized value or raises a one-line
:class:`UsdGazeError`; ``label(key, value)`` names the manifest, the shot and the key, as
:mod:`usdgaze.values` does for the CLI.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Callable

from usdgaze.errors import UsdGazeError

Label = Callable[[str, object], str]


def _text(key: str):
    def check(value: Any, label: Label, base: Path) -> str:
        if not isinstance(value, str) or not value.strip():
            raise UsdGazeError(f"{label(key, repr(value))}: expected a non-empty string")
        if not value.isprintable():  # a newline or tab would split the farm log's one line per shot
            raise UsdGazeError(f"{label(key, repr(value))}: holds a control character (newline, tab, ...)")
        return value
    return check


_SHELL_WORD = re.compile(r"^~|\$(?:\{\w+\}|[A-Za-z_]\w*)")
"""What a shell would expand in a path: a leading ``~`` (``~`` or ``~user``), ``$NAME`` or ``${NAME}``."""


def _unexpanded(key: str, text: str, label: Label) -> None:
    """Refuse a path a shell would have expanded: TOML does not, nor does usdgaze, and ``out =
    "~/gaze/a.usdc"`` made a folder named ``~`` beside the manifest (``$SHOW/...`` one named ``$SHOW``)."""
    found = _SHELL_WORD.search(text)
    if found:
        raise UsdGazeError(f"{label(key, repr(text))}: usdgaze does not expand '{found[0]}' (TOML has no ~ or "
                           "environment variables); write the path out, or relative to the manifest's folder")


def _path(key: str, layer: bool = False, suffixes: tuple[str, ...] = ()):
    if layer:
        suffixes = (".usda", ".usdc", ".usd")

    def check(value: Any, label: Label, base: Path) -> str:
        text = _text(key)(value, label, base)
        _unexpanded(key, text, label)
        path = os.path.normpath(os.path.join(base, text))
        if suffixes and Path(path).suffix.lower() not in suffixes:
            *most, last = suffixes
            raise UsdGazeError(f"{label(key, repr(value))}: must end in {', '.join(most)} or {last}")
        return path
    return check


def _is_prim_path(text: str) -> bool:
    """An absolute prim path as USD parses one: a leading slash is not enough ('/a b' failed only once
    the shot ran, said with the CLI's flag)."""
    from pxr import Sdf

    return Sdf.Path.IsValidPathString(text) and Sdf.Path(text).IsAbsolutePath() and Sdf.Path(text).IsPrimPath()


def _prim_path(key: str):
    def check(value: Any, label: Label, base: Path) -> str:
        if not _is_prim_path(_text(key)(value, label, base)):
            raise UsdGazeError(f"{label(key, repr(value))}: expected an absolute prim path such as /Character")
        return value
    return check


def _flag(key: str):
    def check(value: Any, label: Label, base: Path) -> bool:
        if not isinstance(value, bool):
            raise UsdGazeError(f"{label(key, repr(value))}: expected true or false")
        return value
    return check


def _map(value: Any, label: Label, base: Path) -> str:
    file, sep, prim = _text("map")(value, label, base).partition(":/")
    if sep and not _is_prim_path(f"/{prim}"):
        raise UsdGazeError(f"{label('map', repr(value))}: '/{prim}' is not an absolute prim path such as /GazeMap")
    return _path("map")(file, label, base) + (f":/{prim}" if sep else "")


def _shifts(value: Any, label: Label, base: Path) -> list[str]:
    from usdgaze.passes.requests import parse_shift

    if isinstance(value, (str, bytes)) or not isinstance(value, list):
        raise UsdGazeError(f"{label('shifts', repr(value))}: expected a list of \"TIME:YAW:PITCH\" strings")
    out = []
    for text in value:
        try:
            out.append(str(parse_shift(text, label)))
        except UsdGazeError as exc:  # a weight= or blend= option's message names the CLI's flag
            message = str(exc)
            if not message.startswith("--shift "):
                raise
            raise UsdGazeError(f"{label('shifts', repr(text))}: {message.split(chr(39) + ': ', 1)[-1]}") from None
    return out


def _directives(key: str, parse: str, form: str):
    """A list of ``look_at`` or ``release`` directive strings, each parsed as the CLI's flag is."""
    def check(value: Any, label: Label, base: Path) -> list[str]:
        from usdgaze.passes import requests

        if isinstance(value, (str, bytes)) or not isinstance(value, list):
            raise UsdGazeError(f"{label(key, repr(value))}: expected a list of \"{form}\" strings")
        out = []
        for text in value:
            if not isinstance(text, str):
                raise UsdGazeError(f"{label(key, repr(text))}: expected a \"{form}\" string")
            try:
                out.append(str(getattr(requests, parse)(text)))
            except UsdGazeError as exc:  # the CLI's message names its flag: name the manifest key
                reason = str(exc).split("': ", 1)[-1]
                raise UsdGazeError(f"{label(key, repr(text))}: {reason}") from None
        return out
    return check


def _choice(key: str, choices: tuple[str, ...]):
    def check(value: Any, label: Label, base: Path) -> str:
        if value not in choices:
            raise UsdGazeError(f"{label(key, repr(value))}: expected one of {', '.join(choices)}")
        return value
    return check


def _number(key: str, low: float, high: float):
    def check(value: Any, label: Label, base: Path) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
            raise UsdGazeError(f"{label(key, repr(value))}: expected a number from {low:g} to {high:g}")
        return float(value)
    return check


def _integer(key: str, low: int, high: int):
    def check(value: Any, label: Label, base: Path) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise UsdGazeError(f"{label(key, repr(value))}: expected a whole number from {low} to {high}")
        return value
    return check


def _prims(value: Any, label: Label, base: Path) -> list[str]:
    if isinstance(value, (str, bytes)) or not isinstance(value, list) or not value:
        raise UsdGazeError(f"{label('objects', repr(value))}: expected a list of prim paths such as \"/World/Ball\"")
    for text in value:
        if not isinstance(text, str) or not _is_prim_path(text):
            raise UsdGazeError(f"{label('objects', repr(text))}: expected an absolute prim path such as /World/Ball")
    return list(value)


def _fixation(value: Any, label: Label, base: Path) -> float:
    from usdgaze.values import check_fixation

    if isinstance(value, int) and not isinstance(value, bool):
        value = float(value)  # messages show the distance as the pass takes it
    return check_fixation(value, label)


def _as_given(value: Any, label: Label, base: Path) -> Any:
    return value  # checked with the keys it combines with (see manifest._COMBINED)


def _binding(values: dict, name: Callable[[str], str]):
    """``bind`` and ``forward`` together are one ``PassOptions.binding``; ``name(key)`` says how a
    message names each (``Shot.name_of``)."""
    from usdgaze.core.hints import parse_hints

    return parse_hints(values.get("bind"), values.get("forward"), bind_label=name("bind"),
                       forward_label=name("forward"))
