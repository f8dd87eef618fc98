"""The usdview Gaze menu's commands. Each takes usdview's ``usdviewApi`` (or anything with the same
few members: ``stage``, ``frame``, ``PrintStatus``, ``ClearPrimSelection``, ``AddPrimToSelection``,
``UpdateViewport``) and acts on its open stage. Helpers (lines of sight, joint markers) are authored
in the stage's session layer under :data:`HELPERS`, so they are never saved with the user's layers.

The Qt side (menu, registration) is :mod:`usdgaze.review.usdview_plugin`.
"""

from __future__ import annotations

import numpy as np

from usdgaze.errors import UsdGazeError

HELPERS = "/UsdGazeReview"
LINES = f"{HELPERS}/LinesOfSight"
JOINTS = f"{HELPERS}/ChainJoints"


def gaze_layers(stage) -> list:
    """The root layer's sublayers that are usdgaze overrides (``layers.is_override_record``), muted ones
    included."""
    from pxr import Sdf

    from usdgaze.usd.layers import is_override_record

    out = []
    for identifier in stage.GetRootLayer().subLayerPaths:
        layer = Sdf.Layer.FindOrOpenRelativeToLayer(stage.GetRootLayer(), identifier)
        if layer and is_override_record((layer.customLayerData or {}).get("usdgaze")):
            out.append(layer)
    return out


def toggle_gaze_layer(api) -> str:
    """Mute the gaze layer(s) if any is active, else unmute them: compare the base and the gaze in place."""
    stage = api.stage
    layers = gaze_layers(stage)
    if not layers:
        return _say(api, "usdgaze: no usdgaze layer among the root layer's sublayers (open the --preview root)")
    mute = any(not stage.IsLayerMuted(layer.identifier) for layer in layers)
    for layer in layers:
        (stage.MuteLayer if mute else stage.UnmuteLayer)(layer.identifier)
    names = ", ".join(layer.GetDisplayName() for layer in layers)
    api.UpdateViewport()
    return _say(api, f"usdgaze: {'muted' if mute else 'unmuted'} {names} ({'base' if mute else 'gaze'} animation shown)")


def _characters(stage):
    """(clip, chain, character review with the current composition posed) per animated skeleton."""
    from pxr import UsdGeom

    from usdgaze import api as gaze_api
    from usdgaze.characters import own_map
    from usdgaze.core.hints import from_record
    from usdgaze.review.composed import CharacterReview, _pose
    from usdgaze.usd.skelio import read_clip, skel_roots, skeletons_under

    source = stage.GetRootLayer().identifier
    up = np.array([0.0, 0.0, 1.0]) if UsdGeom.GetStageUpAxis(stage) == "Z" else np.array([0.0, 1.0, 0.0])
    layers = gaze_layers(stage)
    try:  # bind as the pass did: with the --bind/--forward its layer recorded
        hints = from_record(layers[0].customLayerData["usdgaze"], layers[0].identifier) if layers else None
    except UsdGazeError:
        hints = None
    out = []
    for root in skel_roots(stage):
        try:  # a map that cannot be used (Print Map and Schedule says why) skips its character, as a skeleton that cannot bind does
            own = own_map(root, source)
        except UsdGazeError:
            continue
        for skel in skeletons_under(root):
            try:
                clip = read_clip(stage, skel, root, source)
                chain, frame = gaze_api.bind(clip, own, hints)
            except UsdGazeError:
                continue
            posed = _pose(clip, clip.joints, clip.rest_local, clip.parents, chain)
            out.append((clip, CharacterReview(
                skel_root=clip.skel_root, skeleton=clip.skeleton, joints=clip.joints, parents=clip.parents,
                seconds=clip.seconds, base=posed, gaze=posed, chain=chain, frame=frame,
                neutral_world=clip.neutral(), skel_to_world=clip.skel_to_world, up=up,
                meters_per_unit=clip.meters_per_unit)))
    return out


def _remove(layer, path: str) -> bool:
    spec = layer.GetPrimAtPath(path)
    if spec is None:
        return False
    parent = spec.nameParent
    if parent == layer.pseudoRoot or parent is None:
        del layer.rootPrims[spec.name]
    else:
        del parent.nameChildren[spec.name]
    return True


def _helper_layer(stage):
    """The session layer, timed like the stage (a layer's samples are rescaled by its own
    timeCodesPerSecond, and a session layer has none of its own)."""
    session = stage.GetSessionLayer()
    if not session.HasTimeCodesPerSecond():
        session.timeCodesPerSecond = stage.GetTimeCodesPerSecond()
    return session


def _def(layer, path: str, type_name: str):
    from pxr import Sdf

    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierDef
    spec.typeName = type_name
    return spec


def _attr(spec, name: str, type_name, default=None):
    from pxr import Sdf

    attr = Sdf.AttributeSpec(spec, name, type_name)
    if default is not None:
        attr.default = default
    return attr


def show_lines_of_sight(api, length_m: float = 2.0) -> str:
    """Toggle a line of sight per character (eyes, else head; ``length_m`` long) in the session layer."""
    from pxr import Sdf, Vt

    from usdgaze.review import analysis

    stage, session = api.stage, _helper_layer(api.stage)
    if _remove(session, LINES):
        api.UpdateViewport()
        return _say(api, "usdgaze: lines of sight hidden")
    chars = _characters(stage)
    if not chars:
        return _say(api, "usdgaze: no skeleton with a bound animation and a gaze chain on this stage")
    with Sdf.ChangeBlock():
        _def(session, HELPERS, "Scope")
        for k, (clip, c) in enumerate(chars):
            if c.eyes:
                origin, direction = analysis.sight(c, c.gaze)
            else:
                origin, direction = c.gaze.positions[:, c.chain.head], analysis.head_direction(c, c.gaze)
            reach = length_m / clip.meters_per_unit
            spec = _def(session, f"{LINES}/Character{k}", "BasisCurves")
            _attr(spec, "type", Sdf.ValueTypeNames.Token, "linear")
            _attr(spec, "curveVertexCounts", Sdf.ValueTypeNames.IntArray, Vt.IntArray([2]))
            _attr(spec, "widths", Sdf.ValueTypeNames.FloatArray, Vt.FloatArray([0.01 / clip.meters_per_unit]))
            _attr(spec, "primvars:displayColor", Sdf.ValueTypeNames.Color3fArray, Vt.Vec3fArray([(0.9, 0.1, 0.1)]))
            points = _attr(spec, "points", Sdf.ValueTypeNames.Point3fArray)
            ends = np.stack([origin, origin + reach * direction], axis=1).astype(np.float32)
            for t, row in zip(clip.times, ends):
                session.SetTimeSample(points.path, float(t), Vt.Vec3fArray.FromNumpy(row))
    api.UpdateViewport()
    return _say(api, f"usdgaze: lines of sight shown for {len(chars)} character(s) (session layer {LINES})")


def select_chain_joints(api) -> str:
    """Mark the gaze chain's joints (UsdSkel joints are not prims) with small spheres in the session
    layer, following the animation, and select those markers."""
    from pxr import Sdf, Tf, Vt

    stage, session = api.stage, _helper_layer(api.stage)
    chars = _characters(stage)
    if not chars:
        return _say(api, "usdgaze: no skeleton with a bound animation and a gaze chain on this stage")
    _remove(session, JOINTS)
    made = []
    with Sdf.ChangeBlock():
        _def(session, HELPERS, "Scope")
        for k, (clip, c) in enumerate(chars):
            picked = [j for role in ("pelvis", "lowerSpine", "upperSpine", "neck", "head", "leftEye", "rightEye")
                      for j in c.chain.roles.get(role, ())]
            for j in picked:
                name = Tf.MakeValidIdentifier(f"c{k}_{c.joints[j].rsplit('/', 1)[-1]}")
                path = f"{JOINTS}/{name}"
                spec = _def(session, path, "Sphere")
                _attr(spec, "radius", Sdf.ValueTypeNames.Double, 0.03 / clip.meters_per_unit)
                _attr(spec, "primvars:displayColor", Sdf.ValueTypeNames.Color3fArray, Vt.Vec3fArray([(0.1, 0.7, 0.3)]))
                _attr(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Vt.TokenArray(["xformOp:translate"]))
                op = _attr(spec, "xformOp:translate", Sdf.ValueTypeNames.Double3)
                for t, p in zip(clip.times, c.gaze.positions[:, j]):
                    session.SetTimeSample(op.path, float(t), tuple(float(v) for v in p))
                made.append((path, c.joints[j]))
    api.ClearPrimSelection()
    for path, _ in made:
        api.AddPrimToSelection(stage.GetPrimAtPath(path))
    api.UpdateViewport()
    return _say(api, f"usdgaze: selected {len(made)} gaze chain joint markers: "
                     + ", ".join(j.rsplit('/', 1)[-1] for _, j in made))


def summary(api) -> str:
    """The map and the schedule: per SkelRoot the map used and the chain; per gaze layer its shifts and limits."""
    from usdgaze.usd import schema
    from usdgaze.usd.skelio import skel_roots

    stage = api.stage
    lines = []
    from usdgaze.review.recorded import check_record

    for layer in gaze_layers(stage):
        record = dict(layer.customLayerData["usdgaze"])
        muted = " (muted)" if stage.IsLayerMuted(layer.identifier) else ""
        lines.append(f"gaze layer {layer.GetDisplayName()}{muted}: usdgaze {record.get('version', '?')}, "
                     f"input {record.get('input', '?')}")
        try:  # a hand-edited record (`directives = 5`, `eyeRange.yaw = "wide"`) had stopped the command
            check_record(record, layer.GetDisplayName())
        except UsdGazeError as exc:
            lines.append(f"  record unreadable ({exc})")
            continue
        lines += _asked(record)
        for key in ("maps", "eyeRange", "fixation"):
            if key in record:
                lines.append(f"  {key}: {_shown(record[key])}")
    from usdgaze.usd import schedule

    for root in skel_roots(stage):
        try:  # read as apply reads it: a broken or misplaced map (on the Skeleton) is no map to count
            definition = schema.root_map(root, stage.GetRootLayer().GetDisplayName())
        except UsdGazeError as exc:  # or applied while the schema registry predates usdgaze's plugin
            lines.append(f"{root.GetPath()}: GazeMapAPI unreadable ({exc})")
            continue
        if definition is not None:
            lines.append(f"{root.GetPath()}: GazeMapAPI, {len(definition)} examples")
        else:
            lines.append(f"{root.GetPath()}: no GazeMapAPI (the built-in map is used)")
        if schedule.has_schedule(root):
            try:
                directives = schedule.read_schedule(root, stage.GetRootLayer().GetDisplayName())
                lines.append("  GazeScheduleAPI: " + ", ".join(str(d) for d in directives))
            except UsdGazeError as exc:
                lines.append(f"  GazeScheduleAPI: unreadable ({exc})")
    for clip, c in _characters(stage):
        roles = ", ".join(f"{r}={'+'.join(clip.joints[j].rsplit('/', 1)[-1] for j in idx) or '-'}"
                          for r, idx in c.chain.roles.items())
        lines.append(f"  {clip.skeleton}: {roles}")
    text = "\n".join(lines) if lines else "usdgaze: no SkelRoot and no usdgaze layer on this stage"
    print(text)
    api.PrintStatus(lines[0] if lines else text)
    return text


def _asked(record: dict) -> list[str]:
    """What a gaze layer records it was asked: each character's directives as ``apply`` recorded them
    (looks and releases too; a layer older than that record, its shifts), or an attend run's settings."""
    if str(record.get("command", "")).startswith("attend"):
        settings = ", ".join(f"{k} {record[k]}" for k in ("cost", "alpha", "window_s", "seed") if k in record)
        return [f"  {record['command']}: {settings}", "  objects: " + (", ".join(map(str, record.get("objects", []))) or "-")]
    directives = record.get("directives") or {}
    if directives:
        return [f"  schedule {root}: " + (" ".join(map(str, texts)) or "-") for root, texts in sorted(directives.items())]
    return ["  schedule: " + (", ".join(str(s) for s in record.get("shifts", [])) or "-")]


def _shown(value) -> str:
    if hasattr(value, "items"):
        value = dict(value)
        keys = [k for k in ("yaw", "up", "down") if k in value] + sorted(k for k in value if k not in ("yaw", "up", "down"))
        return ", ".join(f"{k} {value[k]:g}" for k in keys)
    if isinstance(value, (str, float, int)):
        return f"{value:g}" if isinstance(value, float) else str(value)
    return ", ".join(str(v) for v in value)


def _say(api, message: str) -> str:
    api.PrintStatus(message)
    return message
