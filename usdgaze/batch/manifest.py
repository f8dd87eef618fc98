"""Batch manifests: TOML jobs (shots) with defaults, validated up front, mapped onto ``api.apply``.

A manifest lists shots; paths are relative to the manifest's folder::

    [defaults]                  # optional; any shot key
    fixation = 2.0

    [[job]]
    name = "walk_01"            # default: the input's file stem
    input = "shots/walk_01.usdc"
    out = "out/walk_01_gaze.usdc"
    preview = "out/walk_01_preview.usda"        # or sublayer_into = "shots/walk_01_shot.usda"
    shifts = ["2s:60:0", "5s:-120:10"]          # and/or look_at = ["/World/Door@4s"], release = ["8s"];
                                                # none of them: each SkelRoot's GazeScheduleAPI schedule
    # eye_timing = "saccade" | "model"; guides = true
    # map = "maps/studio.usda:/GazeMap"; skel_root = "/Char/Body"
    # bind = ["pelvis=j1", "head=j5"] (or a table: bind = { neck = ["j3", "j4"] }); forward = [0, 0, 1]

Every key a shot may carry is one row of :data:`KEYS`: how its value is checked and normalized, and
which ``api.apply`` argument (or ``PassOptions`` / ``LookOptions`` field) it becomes. Adding an
apply option to the manifest is one row there.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from usdgaze.batch.checks import (
    Label, _as_given, _binding, _choice, _directives, _fixation, _flag, _integer, _map, _number, _path, _prim_path,
    _prims, _shifts, _text)
from usdgaze.errors import UsdGazeError
from usdgaze.values import MAX_ALPHA

# The value checks, (value, label, folder) -> normalized value, are in :mod:`usdgaze.batch.checks`.


@dataclass(frozen=True)
class Key:
    """One manifest key: its check and the ``api.apply`` keyword it feeds (``options.F``: a
    ``PassOptions`` field; None: used by the batch itself)."""

    check: Callable[[Any, Label, Path], Any]
    to: str | None
    required: bool = False
    output: bool = False
    """A path the shot writes (not part of its resume key)."""
    keyed: bool = True
    """Part of the resume key as a value (False: file contents stand in for it, or it cannot change
    the result)."""
    commands: tuple[str, ...] = ("apply", "attend")
    """The job commands that take the key."""


COMMANDS = ("apply", "attend")
_APPLY, _ATTEND = ("apply",), ("attend",)


KEYS: dict[str, Key] = {
    "name": Key(_text("name"), None),
    "command": Key(_choice("command", COMMANDS), None),
    "input": Key(_path("input"), "input_path", required=True, keyed=False),
    "out": Key(_path("out", layer=True), "out", required=True, output=True),
    "preview": Key(_path("preview", layer=True), "preview", output=True, commands=_APPLY),
    "sublayer_into": Key(_path("sublayer_into", layer=True), "sublayer_into", output=True, commands=_APPLY),
    "plot": Key(_path("plot", suffixes=(".png", ".pdf", ".svg")), "plot", output=True, commands=_APPLY),
    "shifts": Key(_shifts, "shifts", commands=_APPLY),
    "look_at": Key(_directives("look_at", "parse_look", "TARGET@TIME"), "look_at", commands=_APPLY),
    "release": Key(_directives("release", "parse_release", "TIME"), "release", commands=_APPLY),
    "eye_timing": Key(_choice("eye_timing", ("saccade", "model")), "look.eye_timing", commands=_APPLY),
    "guides": Key(_flag("guides"), "guides", commands=_APPLY),
    "map": Key(_map, "map_spec", keyed=False, commands=_APPLY),
    "skel_root": Key(_prim_path("skel_root"), "skel_root"),
    "fixation": Key(_fixation, "options.fixation_m", commands=_APPLY),
    "bind": Key(_as_given, "options.binding"),
    "forward": Key(_as_given, "options.binding"),
    "no_clobber": Key(_flag("no_clobber"), "no_clobber", keyed=False),
    # usdgaze attend (docs/attend.md, docs/physics.md): the command's options under the same names
    "objects": Key(_prims, "objects", commands=_ATTEND),
    "alpha": Key(_number("alpha", 0.0, MAX_ALPHA), "settings.alpha", commands=_ATTEND),
    "cost": Key(_choice("cost", ("uncertainty", "distance", "sequential")), "settings.cost", commands=_ATTEND),
    "window": Key(_number("window", 0.05, 5.0), "settings.window_s", commands=_ATTEND),
    "seed": Key(_integer("seed", 0, 2**32 - 1), "settings.seed", commands=_ATTEND),
    "realize": Key(_choice("realize", ("direct", "map")), "settings.realize", commands=_ATTEND),
    "physics": Key(_flag("physics"), "physics", commands=_ATTEND),
    "discard_failed": Key(_flag("discard_failed"), "discard_failed", commands=_ATTEND),
    "threads": Key(_integer("threads", 1, 64), "threads", keyed=False, commands=_ATTEND),  # same bytes for any
    "fd_stride": Key(_integer("fd_stride", 1, 8), "fd_stride", commands=_ATTEND),
    "fd_reuse": Key(_integer("fd_reuse", 1, 8), "fd_reuse", commands=_ATTEND),
    "iterations": Key(_integer("iterations", 1, 10), "iterations", commands=_ATTEND),
    "retry_iterations": Key(_integer("retry_iterations", 0, 10), "retry_iterations", commands=_ATTEND),
    "timestep": Key(_number("timestep", 0.01, 0.05), "timestep", commands=_ATTEND),
    "raw_contacts": Key(_flag("raw_contacts"), "raw_contacts", commands=_ATTEND),
    "mass": Key(_number("mass", 1.0, 500.0), "mass", commands=_ATTEND),
}

# Targets fed by several keys: built from all of them at once (and checked up front).
_COMBINED: dict[str, Callable[[dict, Callable[[str], str]], Any]] = {"options.binding": _binding}

# The shared checks name some values as the CLI's flags do (parse_shift: "shift"); a manifest's
# messages name the key as written there.
_AS_WRITTEN = {"shift": "shifts", "fixation_m": "fixation"}
_FLAG = re.compile(r"(?<![\w-])--([a-z][a-z-]*[a-z])( ')?")
"""A CLI flag in a message (``--skel-root``), and the quote of a value given after it."""


def _key_name(manifest: str, where: str, inherited: frozenset, key: str, job: bool = True) -> str:
    """How a message names ``key`` of a job: ``M: job I 'N': KEY``. A value the job took from
    [defaults] says so (the fix is there, not in the job): ``M: [defaults] KEY`` for a check of the
    value alone (``job`` False), ``M: job I 'N': [defaults] KEY`` for one that involves the job's
    other keys."""
    key = _AS_WRITTEN.get(key, key)
    if key not in inherited:
        return f"{where}: {key}"
    return f"{where}: [defaults] {key}" if job else f"{manifest}: [defaults] {key}"


@dataclass(frozen=True)
class Shot:
    """One validated manifest job: normalized values by manifest key, paths absolute."""

    index: int
    name: str
    values: dict = field(default_factory=dict)
    where: str = ""
    """How messages name it: ``MANIFEST: job I 'NAME'``."""
    manifest: str = ""
    inherited: frozenset = frozenset()
    """The keys whose values came from the manifest's [defaults] (messages name them as its)."""

    @property
    def label(self) -> str:
        """``job I 'NAME'``, as the file checks name it."""
        return f"job {self.index} '{self.name}'"

    def name_of(self, key: str) -> str:
        """How a message names one of its keys (``_key_name``)."""
        return _key_name(self.manifest, self.where, self.inherited, key)

    def value_label(self, key: str, value: object) -> str:
        """``label(key, value)`` of the shared checks for this job's values."""
        return f"{self.name_of(key)} = {value}"

    def said(self, message: str) -> str:
        """A message of the shot's command as the manifest names things: the command's checks at run
        time name the CLI's flags (``--shift 9999:30:0 lies outside the animation``, ``--skel-root``),
        which a manifest's author did not write. Those become this job's keys, after the job."""
        def key(found: re.Match) -> str:
            name = _AS_WRITTEN.get(found[1].replace("-", "_"), found[1].replace("-", "_"))
            if name not in KEYS:  # a flag with no manifest key (--workers): as it was
                return found[0]
            return ("[defaults] " if name in self.inherited else "") + name + (" = '" if found[2] else "")

        rewritten = _FLAG.sub(key, message)
        return message if rewritten == message else f"{self.where}: {rewritten}"

    @property
    def out(self) -> str:
        return self.values["out"]

    @property
    def command(self) -> str:
        """``apply`` (the default) or ``attend``."""
        return self.values.get("command", "apply")

    def outputs(self) -> list[str]:
        return [self.values[k] for k, spec in KEYS.items() if spec.output and k in self.values]

    def parameters(self) -> dict:
        """What the result depends on besides file contents: every non-path, non-output value."""
        keyed = {k: v for k, v in sorted(self.values.items())
                 if KEYS[k].to is not None and not KEYS[k].output and KEYS[k].keyed}
        if "bind" in keyed or "forward" in keyed:
            # As parsed, not as spelled: forward [0, 0, 1] or "0,0,1", bind as a list or a table, in
            # any order, is one binding (a respelled manifest redid its shots).
            hints = _binding(self.values, self.name_of)
            keyed.pop("bind", None)
            keyed.pop("forward", None)
            keyed["binding"] = {"bind": sorted([role, list(joints)] for role, joints in hints.bindings),
                                "forward": None if hints.forward is None else list(hints.forward)}
        return keyed if self.command == "apply" else {"command": self.command, **keyed}


def apply_kwargs(shot: Shot) -> dict:
    """The ``usdgaze.api.apply`` keyword arguments of a shot: ``GROUP.FIELD`` targets are fields of
    the option dataclasses (``options``: PassOptions, ``look``: LookOptions)."""
    from usdgaze.passes.look import LookOptions
    from usdgaze.passes.shift import PassOptions

    groups = {"options": PassOptions, "look": LookOptions}
    kwargs, fields = {"shifts": []}, {name: {} for name in groups}
    for key, value in shot.values.items():
        to = KEYS[key].to
        if to is None:
            continue
        value = _COMBINED[to](shot.values, shot.name_of) if to in _COMBINED else value
        group, dot, name = to.partition(".")
        if dot:
            fields[group][name] = value
        else:
            kwargs[to] = value
    for group, values in fields.items():
        if values:
            kwargs[group] = groups[group](**values)
    return kwargs


def attend_kwargs(shot: Shot) -> dict:
    """The call of an ``attend`` job: ``usdgaze.attend.attend`` keywords, or with ``physics`` those of
    ``usdgaze.passes.physics.run`` (``physics`` True); checked as the CLI checks them."""
    from usdgaze.attend import KINEMATIC_ONLY, PHYSICS_ONLY, AttendSettings

    v = shot.values
    settings = {KEYS[k].to.partition(".")[2]: value for k, value in v.items()
                if (KEYS[k].to or "").startswith("settings.")}
    common = {"input_path": v["input"], "out": v["out"], "skel_root": v.get("skel_root"),
              "no_clobber": v.get("no_clobber", False)}
    binding = _binding(v, shot.name_of) if ("bind" in v or "forward" in v) else None
    if not v.get("physics"):
        extra = sorted(set(v) & set(PHYSICS_ONLY))
        if extra:
            raise UsdGazeError(f"{shot.name_of(extra[0])}: a key of physics jobs (physics = true)")
        found = AttendSettings(**settings, binding=binding)
        found.check()
        return {**common, "physics": False, "objects": v.get("objects"), "settings": found}
    extra = sorted(set(v) & set(KINEMATIC_ONLY))
    if extra:  # the coupled loop reads every GazeObjectAPI prim and its own belief settings
        raise UsdGazeError(f"{shot.name_of(extra[0])}: not taken by physics jobs (docs/physics.md)")
    from usdgaze.passes.physics_options import check_window, with_timestep, with_window
    from usdgaze.physics.mpc import Options

    options = Options(workers=v.get("threads", 1), fd_stride=v.get("fd_stride", 1), fd_reuse=v.get("fd_reuse", 1),
                      iterations=v.get("iterations", Options.iterations),
                      retry_iterations=v.get("retry_iterations", Options.retry_iterations),
                      ground_feet=not v.get("raw_contacts", False))
    options = with_window(with_timestep(options, v.get("timestep")), settings.get("window_s"))
    check_window(options, f"{shot.name_of('window')} =")
    return {**common, "physics": True, "options": options, "seed": settings.get("seed", 0), "binding": binding,
            "keep_failed": not v.get("discard_failed", False), "total_mass": v.get("mass", 75.0)}


def _where(path: Path, index: int, name: str | None) -> str:
    return f"{path}: job {index}" + (f" '{name}'" if name is not None else "")


def _check_shot(path: Path, index: int, raw: object, defaults: dict) -> Shot:
    from usdgaze.api import ApplyRequest, check_request

    if not isinstance(raw, dict):
        raise UsdGazeError(f"{path}: job {index}: {raw!r} is not a table; expected [[job]] tables")
    merged = {**defaults, **raw}
    where = _where(path, index, raw.get("name") if isinstance(raw.get("name"), str) else None)
    inherited = frozenset(set(defaults) - set(raw))
    # A value's own check names a [defaults] value as the table's, not the first job's that takes it.
    label = lambda key, value: f"{_key_name(str(path), where, inherited, key, job=False)} = {value}"  # noqa: E731
    unknown = sorted(set(merged) - set(KEYS))
    if unknown:
        raise UsdGazeError(f"{where}: unknown key '{unknown[0]}' (keys: {', '.join(sorted(KEYS))})")
    command = _choice("command", COMMANDS)(merged.get("command", "apply"), label, path.parent)
    wrong = sorted(k for k in raw if command not in KEYS[k].commands)
    if wrong:
        raise UsdGazeError(f"{where}: {wrong[0]}: not a key of {command} jobs (pipeline/README.md)")
    # [defaults] may hold keys of either command: each job takes those of its own.
    merged = {k: v for k, v in merged.items() if command in KEYS[k].commands}
    for key, spec in KEYS.items():
        if spec.required and key not in merged:
            raise UsdGazeError(f"{where}: missing '{key}'")
    base = path.parent.resolve()
    values = {k: KEYS[k].check(v, label, base) for k, v in merged.items()}
    name = values.pop("name", None) or Path(values["input"]).stem
    shot = Shot(index=index, name=name, values=values, where=where, manifest=str(path), inherited=inherited)
    directives = [k for k in ("shifts", "look_at", "release") if k in values]
    if command == "apply" and directives and not any(values[k] for k in directives):
        # Left out, the SkelRoots' own GazeScheduleAPI schedules apply; only empty lists are a slip.
        what = {"shifts": "shift", "look_at": "look-at", "release": "release"}[directives[0]]
        raise UsdGazeError(f"{shot.value_label(directives[0], '[]')}: no {what} given; nothing to do")
    if command == "attend":
        attend_kwargs(shot)  # the attend command's own checks, up front
    else:
        # the CLI's and the API's own checks; these involve the job's other keys, so they name the job
        check_request(ApplyRequest(**apply_kwargs(shot)), shot.value_label)
    return shot


def _check_files(path: Path, shots: list[Shot]) -> None:
    """No shot writes the manifest, a file any shot reads, or a file another shot writes. Shots run in
    parallel, so two inserting into one sublayer target would race: each shot gets its own."""
    from usdgaze.files.identity import Identities

    ids = Identities()
    register(ids, path, shots)


def register(ids, path: Path, shots: list[Shot]) -> None:
    """Record the manifest and every shot's inputs as read, every shot's outputs as written, in an
    :class:`usdgaze.files.identity.Identities`: a clash is a one-line error naming the manifest, the
    file and both uses of it."""
    try:
        _register(ids, path, shots)
    except UsdGazeError as exc:
        message = str(exc)
        raise UsdGazeError(message if message.startswith(f"{path}:") else f"{path}: {message}") from None


def _read_files(s: Shot) -> list[tuple[str, str]]:
    """(role, file) of what a shot reads as a whole: its input, and its map file where it names one."""
    files = [("input", s.values["input"])]
    if "map" in s.values:
        files.append(("map", s.values["map"].partition(":/")[0]))
    return files


def _register(ids, path: Path, shots: list[Shot]) -> None:
    from usdgaze.usd.stage import layer_dependencies, without_usd_warnings

    ids.read(path, "manifest")
    composed: dict[str, list[str]] = {}  # per file: shots often share their inputs and maps
    for s in shots:
        for role, file in _read_files(s):
            ids.read(file, f"{role} of {s.label}")
    for s in shots:
        # Another shot must not write a layer this one composes (its input's or its map's: a map's
        # sublayer was not checked, and the shot read another's override or failed on it missing by
        # the order they ran in); on a farm it would read it half-made. A layer not there yet counts
        # too: on the first run it is another shot's output to come. The path as given, links
        # unresolved: USD anchors a symlinked file's sublayers at the link's folder (as
        # batch.keys.shot_key reads them); realpath only to know the file among them.
        for role, file in _read_files(s):
            source = os.path.abspath(file)
            if source not in composed:
                with without_usd_warnings():  # USD's multi-line warning for each layer not there yet
                    found = layer_dependencies(source, missing=True)
                real = os.path.realpath(source)
                composed[source] = [f for f in found if os.path.realpath(f) != real]
            for f in composed[source]:
                ids.read(f, f"layer composed by the {role} of {s.label}")
    for s in shots:
        for key in ("out", "preview", "sublayer_into", "plot"):
            if key in s.values:
                ids.write(s.values[key], f"{s.label} {key}")


def load_manifest(path: str | os.PathLike) -> list[Shot]:
    """The shots of a manifest, every key checked before any shot runs (one-line errors)."""
    from usdgaze.files.tomlio import load_toml

    path = Path(path)
    data = load_toml(path)
    extra = sorted(set(data) - {"defaults", "job"})
    if extra:
        raise UsdGazeError(f"{path}: unknown table '{extra[0]}' (tables: [defaults], [[job]])")
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise UsdGazeError(f"{path}: [defaults] must be a table of job keys")
    if "name" in defaults:
        raise UsdGazeError(f"{path}: [defaults]: name: a name belongs to one job")
    unknown = sorted(set(defaults) - set(KEYS))
    if unknown:  # said of [defaults], not of the first job that inherits it
        raise UsdGazeError(f"{path}: [defaults]: unknown key '{unknown[0]}' (keys: {', '.join(sorted(KEYS))})")
    jobs = data.get("job", [])
    if not isinstance(jobs, list):
        raise UsdGazeError(f"{path}: job = {jobs!r}: expected [[job]] tables")
    if not jobs:
        raise UsdGazeError(f"{path}: no [[job]] entries")
    shots = [_check_shot(path, i, raw, defaults) for i, raw in enumerate(jobs)]
    names: dict[str, Shot] = {}
    for s in shots:
        if s.name in names:
            raise UsdGazeError(f"{s.where}: name '{s.name}' is also the name of job {names[s.name].index}")
        names[s.name] = s
    _check_files(path, shots)
    return shots
