"""What a gaze layer records it was asked, read back on the composed stage's clock: the directive
flags ``apply`` recorded per SkelRoot (``customLayerData["usdgaze"]["directives"]``, else its
``shifts``), each character's look-at targets sampled, and each character's requests as steps.

Per character: a layer that animates several SkelRoots records each one's own directives (their
GazeScheduleAPI schedules may differ), and each character is drawn against its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.errors import UsdGazeError


@dataclass
class Look:
    """One look-at directive: what, from when to when (seconds), where it is on every frame."""

    label: str
    start_s: float
    end_s: float
    positions: np.ndarray
    """Target world positions ``(F, 3)`` at the clip's samples."""


def _key(key: str) -> str:
    return f"customLayerData usdgaze.{key}"


def recorded_strings(record: dict, key: str, layer_file: str) -> list[str]:
    """``record[key]`` as a list of strings (none if absent), or a one-line error naming the layer and
    the key: a hand-edited record's ``shifts = 7`` was exit 1, and ``shifts = "10:20:0"`` was read
    letter by letter (``--shift '1'``)."""
    return _strings(record.get(key), key, layer_file)


def _strings(value, key: str, layer_file: str) -> list[str]:
    if value is None:
        return []
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or not all(isinstance(v, str) for v in value):
        raise UsdGazeError(f"{layer_file}: {_key(key)} is not a list of strings")
    return list(value)


def recorded_number(record: dict, key: str, layer_file: str) -> float:
    """``record[key]`` (``key`` a dotted path into it: ``eyeRange.yaw``) as a finite number > 0, or a
    one-line error naming the layer and the key: a hand-edited ``fixation = "far"`` was exit 1, and
    a negative one drew the lines of sight backwards."""
    value = record
    for part in key.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value) and value > 0:
        return float(value)
    raise UsdGazeError(f"{layer_file}: {_key(key)} is {value!r}, expected a finite number > 0")


def recorded_directives(record: dict, layer_file: str) -> dict[str, list[str]]:
    """``record["directives"]``, SkelRoot path -> its directive flags, each checked as
    :func:`recorded_strings` checks (none recorded: empty)."""
    value = record.get("directives")
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise UsdGazeError(f"{layer_file}: {_key('directives')} is not a dictionary of SkelRoot paths")
    return {str(root): _strings(texts, f"directives.{root}", layer_file) for root, texts in value.items()}


def check_record(record: dict, layer_file: str) -> None:
    """Every value of an override's record that the review reads, checked as it reads them (a one-line
    error naming the layer and the key): what ``validate`` says where ``plot`` and ``preview`` refuse."""
    from usdgaze.core.hints import from_record

    for key in ("shifts", "characters"):
        recorded_strings(record, key, layer_file)
    recorded_directives(record, layer_file)
    if "fixation" in record:
        recorded_number(record, "fixation", layer_file)
    limits = record.get("eyeRange")
    if isinstance(limits, dict) and {"yaw", "up", "down"} <= set(limits):  # else the review shows the defaults
        for k in ("yaw", "up", "down"):
            recorded_number(record, f"eyeRange.{k}", layer_file)
    from_record(record, layer_file)


def layer_offset(stage, layer):
    """The time offset at which the stage's root layer stack brings ``layer`` in (identity if not)."""
    from pxr import Sdf

    from usdgaze.usd.stage import layer_stack

    return next((o for name, _, o in layer_stack(stage.GetRootLayer()) if name == layer.identifier), Sdf.LayerOffset())


def _stage_code(layer, offset):
    """The stage time code of a time the layer records: an input time code, or (``seconds``) seconds
    from the input's start (the layer carries the input's timing), a float or an array, brought to
    the stage through the layer's ``offset`` (a shot that sublayers it later than the input's own
    time). ``scale * t + offset`` is ``Sdf.LayerOffset * t``, for arrays too."""
    start = layer.startTimeCode if layer.HasStartTimeCode() else 0.0
    tcps = layer.timeCodesPerSecond
    return lambda t, seconds: offset.scale * (start + t * tcps if seconds else t) + offset.offset


def recorded_code(layer, offset):
    """The stage time code of a directive the layer records (:func:`_stage_code`)."""
    code = _stage_code(layer, offset)
    return lambda d: code(d.time, d.seconds)


def recorded_clock(layer, offset, clip):
    """Seconds on ``clip`` of a directive the layer records (:func:`recorded_code`)."""
    code = recorded_code(layer, offset)
    return lambda d: (code(d) - clip.start_time) / clip.time_codes_per_second


def recorded_seconds(layer, offset, clip):
    """Seconds on ``clip`` of an array of seconds the layer records from the input's start (the
    physics pass's per-step times)."""
    code = _stage_code(layer, offset)
    return lambda seconds: (code(np.asarray(seconds, dtype=float), True) - clip.start_time) / clip.time_codes_per_second


def looks(stage, root, clip, source: str, record: dict, layer_file: str, clock) -> list[Look]:
    """Look directives the pass was given (the layer's record, timed by ``clock``), else the SkelRoot's
    schedule; each holds until the next directive (or the clip's end)."""
    from usdgaze.usd import schedule
    from usdgaze.usd.targets import sample_target

    directives = _recorded_directives(record, str(root.GetPath()), layer_file)
    tc = clock
    if directives is None:
        if not schedule.has_schedule(root):
            return []
        directives = schedule.read_schedule(root, source)
        tc = lambda d: d.time_s(clip.start_time, clip.time_codes_per_second)  # noqa: E731
    directives = sorted(directives, key=tc)
    out = []
    for k, d in enumerate(directives):
        if d.kind != "look":
            continue
        end = tc(directives[k + 1]) if k + 1 < len(directives) else float(clip.seconds[-1])
        if d.target is not None:
            positions, label = sample_target(stage, d.target, clip.times, source), d.target
        else:
            positions = np.broadcast_to(np.asarray(d.point, dtype=float), (len(clip.times), 3)).copy()
            label = "point (" + ", ".join(f"{v:g}" for v in d.point) + ")"
        out.append(Look(f"{label} from {tc(d):.2f} s", tc(d), end, positions))
    return out


def _recorded_directives(record: dict, root: str, layer_file: str):
    """The directive flags ``apply`` recorded for ``root`` (customLayerData usdgaze.directives), parsed;
    None where the layer records none for it."""
    from usdgaze.passes.requests import parse_look, parse_release, parse_shift

    texts = recorded_directives(record, layer_file).get(root)
    if not texts:
        return None
    parsers = {"--shift": parse_shift, "--look-at": parse_look, "--release": parse_release}
    out = []
    for text in texts:
        flag, _, value = str(text).partition(" ")
        if flag not in parsers:
            raise UsdGazeError(f"{layer_file}: customLayerData usdgaze.directives: '{text}' is no directive")
        try:
            out.append(parsers[flag](value))
        except UsdGazeError as exc:
            raise UsdGazeError(f"{layer_file}: customLayerData usdgaze.directives: {exc}") from None
    return out


def requests(record: dict, root: str, layer_file: str, clock) -> list[tuple[float, float, float]]:
    """(seconds, yaw, pitch) of what the pass was asked, in time order: a shift's change (times its
    weight, the share of the way it turns), a release's return to 0, and a look as NaN (a target,
    not a change; the target panel measures it). From the directives recorded for ``root``, else the
    layer's shifts (a layer without directives)."""
    from usdgaze.passes.requests import parse_shift

    directives = _recorded_directives(record, root, layer_file)
    if directives is None:
        directives = []
        for text in recorded_strings(record, "shifts", layer_file):
            try:
                directives.append(parse_shift(str(text)))
            except UsdGazeError as exc:
                raise UsdGazeError(f"{layer_file}: customLayerData usdgaze.shifts: {exc}") from None
    out = []
    for d in directives:
        t = clock(d)
        change = {"shift": (d.weight * d.yaw, d.weight * d.pitch), "release": (0.0, 0.0)}.get(d.kind, (np.nan, np.nan))
        out.append((t, *change))
    return sorted(out)


def check_not_preview(layer, layer_file: str) -> None:
    """One line for a ``--preview`` root given as ``--layer``: it holds no overrides of its own, so plot
    and preview found nothing to review, while validate composed it (the input twice) and said clean."""
    from usdgaze.usd.layers import preview_overrides

    found = preview_overrides(layer)
    if found is not None:
        raise UsdGazeError(f"{layer_file}: --layer names a root --preview wrote (it sublayers the override and "
                           f"the input), not an override; pass --layer {found[0] if found else 'OVERRIDE'}, the "
                           "layer apply or attend wrote with --out")
