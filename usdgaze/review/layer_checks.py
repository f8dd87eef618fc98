"""The stage-level validator over the usdgaze layers of a stage's layer stack (``GazeLayerSchedule``):
what a layer records it was asked fits the stage, and the layer animates the frames of the input below
it. Registered with the prim validators in :mod:`usdgaze.review.validators`."""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdSkel, UsdValidation


def gaze_layer_schedule(stage: Usd.Stage, time_range=None) -> list:
    """A usdgaze layer's recorded schedule: every shift, look-at and release parses and starts inside
    the stage's time range, every character it names is a SkelRoot on the stage whose animation the
    layer samples over the span the layers below it do."""
    from usdgaze.errors import UsdGazeError
    from usdgaze.passes.requests import parse_shift
    from usdgaze.review.recorded import check_record, layer_offset, recorded_code

    errors = []
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        record = (layer.customLayerData or {}).get("usdgaze")
        if not isinstance(record, dict) or not ("shifts" in record or "characters" in record):
            continue  # not a gaze layer (apply's records its shifts; attend's, plain or physics, its characters)
        name = layer.GetDisplayName()
        try:  # what plot and preview refuse; read below, a hand-edited `shifts = 7` stopped validate (exit 1)
            check_record(record, name)
        except UsdGazeError as exc:
            errors.append(_stage_error(stage, "BadRecord", str(exc)))
            continue
        lo, hi = sampled_range(stage, record.get("characters", []), start, end)
        clock = recorded_code(layer, layer_offset(stage, layer))
        checked = stage.HasAuthoredTimeCodeRange() or lo < hi
        for text in record.get("shifts", []):
            try:
                shift = parse_shift(str(text))
            except UsdGazeError as exc:
                errors.append(_stage_error(stage, "BadShift", f"{name}: customLayerData usdgaze.shifts: {exc}"))
                continue
            code = clock(shift)
            if checked and not lo <= code <= hi:
                errors.append(_stage_error(stage, "ShiftOutOfRange",
                                           f"{name}: shift {text} starts at time code {code:g}, outside the stage's "
                                           f"range and its characters' animation [{lo:g}, {hi:g}]"))
        errors += _looks_and_releases(stage, record, name, clock, (lo, hi) if checked else None)
        for path in record.get("characters", []):
            prim = stage.GetPrimAtPath(str(path)) if Sdf.Path.IsValidPathString(str(path)) else None
            if prim and not prim.IsDefined():  # the override layer on its own: overs, no defs
                errors.append(_stage_error(stage, "MissingCharacter",
                                           f"{name}: customLayerData usdgaze.characters names {path}, which this stage "
                                           f"only overrides (no def); validate the layer over its input: "
                                           f"usdgaze validate INPUT --layer {name}"))
            elif not prim or not prim.IsA(UsdSkel.Root):
                errors.append(_stage_error(stage, "MissingCharacter",
                                           f"{name}: customLayerData usdgaze.characters names {path}, which is not a "
                                           f"SkelRoot on this stage"))
        other = _other_take(stage, layer, record.get("characters", [])) + _other_input(stage, layer)
        errors += other or _other_version(stage, layer, record)  # another take differs everywhere: said once
    return errors


def _other_input(stage, layer) -> list:
    """A layer none of whose overrides lands on a SkelAnimation of the stage: made for another input
    (another take's animation has another name), so plot and preview refuse it, and :func:`_other_take`,
    which compares only the animations the layer samples, finds nothing. A stage with no SkelRoot (the
    layer alone) is left to ``MissingCharacter``."""
    from usdgaze.review.composed import not_for_input, overridden_animations, touched_paths
    from usdgaze.usd.skelio import skel_roots

    if not skel_roots(stage) or overridden_animations(stage, touched_paths(layer)):
        return []
    return [_stage_error(stage, "OtherTake", f"{layer.GetDisplayName()}: {not_for_input(stage.GetRootLayer().identifier)} "
                                             "(plot and preview refuse it); validate it over the input it was made for")]


def _other_version(stage, layer, record: dict) -> list:
    """Each named character's animation whose joints the layer writes but its gaze does not drive are
    not the input's (:mod:`usdgaze.review.layer_versions`): the layer was made from another version
    of the input, and composed over this one plays that version's motion."""
    from usdgaze.review.layer_versions import driven_joints, moves_every_joint, other_version, stale_joint

    if moves_every_joint(record):
        return []
    errors, name = [], layer.GetDisplayName()
    for root, skel, anim in _bound(stage, record.get("characters", [])):
        driven = driven_joints(skel, root, record, stage.GetRootLayer().identifier, name)
        found = None if driven is None else stale_joint(layer, anim, driven)
        if found is not None:
            errors.append(_stage_error(stage, "OtherVersion", other_version(name, anim.GetPath(), found)))
    return errors


def _other_take(stage, layer, characters) -> list:
    """Each named character's animation as ``layer`` samples it against the input without it: ``apply``
    writes every frame from the first key of its rotations, translations and scales to the last, so
    another span is a layer made for another take (plot and preview refuse it; validate had called it
    clean). An input that holds one pose (one sample or none) has no span of its own (``apply`` took
    the range of the stage it was given), so there is nothing to compare. Rotations alone were
    compared: one held while the translations moved, or one pose on a single sample, was called
    another take on ``apply``'s own preview."""
    errors = []
    for anim in _animations(stage, characters):
        ours = _times_in(anim.GetRotationsAttr(), layer)
        below = _times_without(anim, layer)
        if ours is None or len(below) < 2:  # not sampled here, or no span below
            continue
        (a, b), (c, d) = (ours[0], ours[-1]), (below[0], below[-1])
        if not np.allclose([a, b], [c, d], rtol=1e-9, atol=1e-6):
            errors.append(_stage_error(stage, "OtherTake",
                                       f"{layer.GetDisplayName()}: {anim.GetPath()} samples time codes {a:g}..{b:g}, "
                                       f"the input below it {c:g}..{d:g}: the layer was made for another take; "
                                       f"validate it over the input it was made for"))
    return errors


def _times_in(attr, layer) -> np.ndarray | None:
    """Stage times of the samples ``layer`` holds for ``attr`` (through its offset), or None."""
    for spec, offset in (attr.GetPropertyStackWithLayerOffsets(Usd.TimeCode.Default()) if attr else []):
        if spec.layer.identifier == layer.identifier and spec.layer.GetNumTimeSamplesForPath(spec.path):
            return np.array([offset * t for t in spec.layer.ListTimeSamplesForPath(spec.path)], dtype=float)
    return None


def _times_without(anim, layer) -> np.ndarray:
    """The animation's sample times as value resolution gives them with ``layer`` left out: per array,
    the strongest other spec's samples (none where its default wins), joined (value clips are not
    looked into: none)."""
    from usdgaze.usd.samples import samples_spec

    times = set()
    for attr in (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr()):
        found = samples_spec(attr, skip=layer) if attr else None
        if found is not None:
            held, path, offset = found
            times.update(offset * t for t in held.ListTimeSamplesForPath(path))
    return np.array(sorted(times), dtype=float)


def _looks_and_releases(stage, record: dict, name: str, clock, span) -> list:
    """The look-ats and releases ``apply`` recorded per character (``directives``; its shifts are the
    layer's ``shifts``, checked above): each parses and, where ``span`` is given, starts inside it."""
    from usdgaze.errors import UsdGazeError
    from usdgaze.passes.requests import parse_look, parse_release

    errors = []
    parsers = {"--look-at": parse_look, "--release": parse_release}
    directives = record.get("directives") or {}
    for root in directives:
        for text in directives[root]:
            flag, _, value = str(text).partition(" ")
            if flag not in parsers:
                continue
            try:
                d = parsers[flag](value)
            except UsdGazeError as exc:
                errors.append(_stage_error(stage, "BadDirective", f"{name}: customLayerData usdgaze.directives: {exc}"))
                continue
            code = clock(d)
            if span is not None and not span[0] <= code <= span[1]:
                errors.append(_stage_error(stage, "DirectiveOutOfRange",
                                           f"{name}: {root}'s {text} starts at time code {code:g}, outside the stage's "
                                           f"range and its characters' animation [{span[0]:g}, {span[1]:g}]"))
    return errors


def _animations(stage, characters):
    """The SkelAnimation bound to each Skeleton under each named character that is a SkelRoot."""
    for _, _, anim in _bound(stage, characters):
        yield anim


def _bound(stage, characters):
    """(SkelRoot prim, Skeleton, its bound SkelAnimation) under each named character that is a SkelRoot."""
    for path in characters:
        prim = stage.GetPrimAtPath(str(path)) if Sdf.Path.IsValidPathString(str(path)) else None
        if not prim or not prim.IsA(UsdSkel.Root):
            continue
        for skel in (p for p in Usd.PrimRange(prim) if p.IsA(UsdSkel.Skeleton)):
            anim = UsdSkel.BindingAPI(skel).GetInheritedAnimationSource()
            if anim:
                yield prim, UsdSkel.Skeleton(skel), UsdSkel.Animation(anim)


def sampled_range(stage, characters, start: float, end: float) -> tuple[float, float]:
    """The stage's time range widened to its characters' animation samples: ``apply`` takes a shift
    anywhere the animation has samples, the stage's playback range or not."""
    lo, hi = (start, end) if stage.HasAuthoredTimeCodeRange() else (np.inf, -np.inf)
    for anim in _animations(stage, characters):
        attr = anim.GetRotationsAttr()
        times = attr.GetTimeSamples() if attr else []
        if times:
            lo, hi = min(lo, times[0]), max(hi, times[-1])
    return float(lo), float(hi)


def _stage_error(stage, name: str, message: str):
    site = UsdValidation.ValidationErrorSite(stage, Sdf.Path.absoluteRootPath)
    return UsdValidation.ValidationError(name, UsdValidation.ValidationErrorType.Error, [site], message)
