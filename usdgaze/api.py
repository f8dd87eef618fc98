"""The Python API of the gaze pass: read stage -> arrays -> model -> arrays -> write layer."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from usdgaze import __version__
from usdgaze.core import rotations as rot
from usdgaze.usd import schema
from usdgaze.core.clip import SkelClip
from usdgaze.gaze.defaults import default_definition
from usdgaze.gaze.definition import GazeMapDefinition
from usdgaze.errors import UsdGazeError
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.look import Directive, LookOptions, apply_look, to_skel
from usdgaze.passes.requests import DirectiveRequest, check_directives
from usdgaze.passes.options import PassOptions, PassResult
from usdgaze.values import ShiftRequest, check_pass_options, cli_label
from usdgaze.files.transaction import Outputs
from usdgaze.usd.layers import (
    AnimOverride,
    LayerInfo,
    atomic_export,
    build_override,
    check_output_path,
    check_sublayer_target,
    insert_sublayer,
    reload_if_open,
    write_preview,
)
from usdgaze.core.hints import BindHints
from usdgaze.core.hints import to_record as hints_record
from usdgaze.core.rig import Chain, CharacterFrame, bind_chain, character_frame

@dataclass
class ApplyRequest:
    """Everything one ``apply`` is asked to do. New options are new fields (``apply`` passes keywords on)."""

    input_path: str | os.PathLike
    shifts: list[ShiftRequest | str]
    out: str | os.PathLike
    skel_root: str | None = None
    map_spec: str | None = None
    sublayer_into: str | os.PathLike | None = None
    preview: str | os.PathLike | None = None
    plot: str | os.PathLike | None = None
    no_clobber: bool = False
    make_folders: bool = False
    """Create missing output folders (removed again if the command fails); the batch's default."""
    options: PassOptions = field(default_factory=PassOptions)
    progress: object = None
    record: dict = field(default_factory=dict)
    """Extra entries for the override's ``customLayerData["usdgaze"]`` (the batch's resume key)."""
    look_at: list[DirectiveRequest | str] = field(default_factory=list)
    """``TARGET@TIME[:weight=W][:blend=B]`` directives (see :mod:`usdgaze.passes.requests`)."""
    release: list[DirectiveRequest | str] = field(default_factory=list)
    """``TIME[:blend=B]`` directives."""
    look: LookOptions = field(default_factory=LookOptions)
    """Eye timing, pursuit and reach of the look pass."""
    guides: bool = True
    """Author guide-purpose lines of sight and the point of sight for review."""

    @property
    def source(self) -> str:
        return os.fspath(self.input_path)


@dataclass
class CharacterReport:
    """What the pass did to one skeleton."""

    skel_root: str
    skeleton: str
    animation: str
    map_source: str
    chain: dict[str, list[str]]
    forward: list[float]
    frames: int
    added_joints: list[str]
    result: PassResult
    guide: tuple | None = None
    """(times, eye positions (2, F, 3) and point of sight (F, 3) in skeleton space, point of sight in
    world space, line width), when guides are written."""


@dataclass
class ApplyReport:
    output: str
    input: str | None = None
    characters: list[CharacterReport] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    preview: str | None = None
    plot: str | None = None
    sublayered_into: str | None = None
    directives: dict[str, list[str]] = field(default_factory=dict)
    """Per SkelRoot, the directives applied, as flags (from the command or the SkelRoot's schedule)."""


def select_roots(stage, source: str, skel_root: str | None):
    """The SkelRoots to work on: the named one, else every one with a GazeMapAPI, else the only one."""
    from pxr import Sdf, UsdSkel

    from usdgaze.usd.skelio import skel_roots

    if skel_root:
        if not Sdf.Path.IsValidPathString(skel_root) or not (Sdf.Path(skel_root).IsAbsolutePath()
                                                               and Sdf.Path(skel_root).IsPrimPath()):
            raise UsdGazeError(f"{source}: --skel-root '{skel_root}' is not an absolute prim path such as /Character")
        prim = stage.GetPrimAtPath(skel_root)
        if not prim or not prim.IsValid():
            raise UsdGazeError(f"{source}:{skel_root}: no such prim")
        if not prim.IsA(UsdSkel.Root):
            raise UsdGazeError(f"{source}:{skel_root}: is a {prim.GetTypeName() or 'typeless prim'}, not a SkelRoot")
        return [prim]
    roots = skel_roots(stage)
    if not roots:
        raise UsdGazeError(f"{source}: no SkelRoot on the stage")
    with_map = [r for r in roots if schema.has_map(r)]
    if with_map:
        return with_map
    if len(roots) > 1:
        listed = ", ".join(str(r.GetPath()) for r in roots[:6])
        raise UsdGazeError(f"{source}: {len(roots)} SkelRoots and none has a GazeMapAPI; pick one with --skel-root ({listed})")
    return roots


def _map_key(definition: GazeMapDefinition) -> bytes:
    """Content key: characters sharing one map (by composition) build it once."""
    m = definition.motions
    return b"|".join([definition.params.tobytes(), m.offsets.tobytes(), m.timing.tobytes(),
                      repr(definition.settings).encode()])


_MAPS: dict[bytes, ParametricGazeMap] = {}
_MAPS_KEPT = 8


def built_map(definition: GazeMapDefinition) -> ParametricGazeMap:
    """The built map of a definition, built once per process: shots (and characters) sharing a map
    by content reuse it."""
    key = _map_key(definition)
    gaze_map = _MAPS.pop(key, None)
    if gaze_map is None:
        gaze_map = ParametricGazeMap(definition)
    _MAPS[key] = gaze_map  # most recently used last
    while len(_MAPS) > _MAPS_KEPT:
        _MAPS.pop(next(iter(_MAPS)))
    return gaze_map


def _character_frame(clip: SkelClip, forward, label: str) -> CharacterFrame:
    sw = clip.skel_to_world[0, :3, :3]
    up_s = rot.normalize(np.linalg.solve(sw, clip.world_up))
    return character_frame(clip.joints, clip.neutral(), up_s, forward, where=f"{clip.source}:{clip.skeleton}",
                           forward_label=label)


def bind(clip: SkelClip, definition: GazeMapDefinition | None, hints: BindHints | None = None
         ) -> tuple[Chain, CharacterFrame]:
    """Chain and character frame of a clip: the user's hints first, then the map's bindings, then names."""
    hints = hints or BindHints()
    bindings = dict(definition.bindings) if definition else {}
    labels = {role: f"gaze:binding:{role}" for role in bindings}
    for role, joints in hints.bindings:
        bindings[role], labels[role] = joints, f"{hints.bind_label} {role}={'+'.join(joints)}"
    forward, label = (hints.forward, hints.forward_label) if hints.forward is not None else (
        definition.forward if definition else None, "gaze:binding:forward")
    chain = bind_chain(clip.joints, clip.parents, bindings, where=f"{clip.source}:{clip.skeleton}", labels=labels)
    return chain, _character_frame(clip, forward, label)


def apply(input_path: str | os.PathLike, shifts: list[ShiftRequest | str], out: str | os.PathLike,
          **options) -> ApplyReport:
    """Add gaze directives to the skeletal animation(s) of ``input_path``; write ``out`` as an override layer.

    Keywords are the fields of :class:`ApplyRequest` (``skel_root``, ``map_spec``, ``sublayer_into``,
    ``preview``, ``plot``, ``no_clobber``, ``options``, ``progress``, ``look_at``, ``release``,
    ``look``, ``guides``). Without shifts, look-ats or releases, each SkelRoot's GazeScheduleAPI
    schedule is applied. Nothing is written unless
    everything succeeds; no output may be a file the command reads (``sublayer_into`` changes only
    that layer's subLayers).
    """
    return run(ApplyRequest(input_path, shifts, out, **options))


def run(req: ApplyRequest) -> ApplyReport:
    """The steps of :func:`apply`: check the request, claim outputs, read, pass, stage, commit."""
    requests = check_request(req)
    with Outputs(no_clobber=req.no_clobber) as tx:
        _claim_outputs(tx, req)
        stage = _open_input(tx, req.source)
        forced = schema.load_map(req.map_spec, tx) if req.map_spec else None
        roots = select_roots(stage, req.source, req.skel_root)
        report, overrides, info = _run_pass(stage, roots, forced, requests, req)
        info.custom = _provenance(req.source, requests, report, req.options, req.look)
        info.custom["usdgaze"].update(req.record)
        _stage_outputs(tx, req, stage, report, overrides, info)
    if req.sublayer_into is not None:
        reload_if_open(req.sublayer_into)
    return report


def check_request(req: ApplyRequest, label=cli_label) -> list[DirectiveRequest]:
    """Values and combinations that are wrong whatever the stage; the parsed directives.

    The one check of the CLI, the API and the batch manifest (``label`` names a value in each).
    """
    check_pass_options(req.options, label)
    if req.sublayer_into is not None and req.preview is not None:
        raise UsdGazeError("--sublayer-into and --preview are alternatives; pass one" if label is cli_label
                           else f"{label('sublayer_into', req.sublayer_into)}: sublayer_into and preview are alternatives; pass one")
    return check_directives(req.shifts, req.look_at, req.release, req.look, label)


def _claim_outputs(tx: Outputs, req: ApplyRequest) -> None:
    if not Path(req.source).is_file():
        raise UsdGazeError(f"{req.source}: no such file")
    tx.read(req.source)  # first, so a clash names the input as such
    if req.make_folders:
        for path in (req.out, req.preview, req.plot):
            if path is not None:
                tx.make_folder(Path(path).parent)
    tx.claim(check_output_path(req.out), "--out")
    if req.preview is not None:
        tx.claim(check_output_path(req.preview), "--preview")
    if req.plot is not None:
        from usdgaze.review.plotting import check_plot_path

        check_plot_path(req.plot)  # before any work: a missing matplotlib must not cost a pass
        tx.claim(req.plot, "--plot")
    if req.sublayer_into is not None:
        if Path(req.sublayer_into).suffix.lower() not in {".usda", ".usdc", ".usd"}:
            raise UsdGazeError(f"{req.sublayer_into}: --sublayer-into must name a .usda, .usdc or .usd layer")
        if not os.path.isfile(req.sublayer_into):
            raise UsdGazeError(f"{req.sublayer_into}: no such file to insert the sublayer into")
        tx.claim(req.sublayer_into, "--sublayer-into", edit=True)


def _open_input(tx: Outputs, source: str):
    from usdgaze.usd.stage import composed_files, open_stage

    stage = open_stage(source)
    for path in composed_files(stage):
        tx.read(path, "layer composed by the input")  # the input itself was read first
    return stage


def _run_pass(stage, roots, forced, requests, req):
    """Read every skeleton under ``roots``, run the gaze pass, collect overrides and the report."""
    from usdgaze.usd.skelio import read_clip, skeletons_under

    source = req.source
    report = ApplyReport(output=str(req.out), input=req.source)
    overrides: list[AnimOverride] = []
    seen_anims: dict[str, str] = {}
    for root in roots:
        root_requests = _root_directives(root, source, requests)
        report.directives[str(root.GetPath())] = [r.flag for r in root_requests]
        own = schema.read_map(root, source) if schema.has_map(root) else None
        definition = forced or own or default_definition()
        map_source = req.map_spec if forced else (f"{source}:{root.GetPath()} (GazeMapAPI)" if own else f"built-in default (usdgaze {__version__})")
        gaze_map = built_map(definition)
        skels = skeletons_under(root)
        if not skels:
            raise UsdGazeError(f"{source}:{root.GetPath()}: no Skeleton under this SkelRoot")
        for skel in skels:
            clip = read_clip(stage, skel, root, source)
            clip.owns_arrays = True  # read for this call alone: the pass may build its result in place
            if clip.animation in seen_anims:
                raise UsdGazeError(
                    f"{source}:{clip.animation}: drives both {seen_anims[clip.animation]} and {clip.skeleton}; "
                    "give each skeleton its own SkelAnimation or pick one with --skel-root"
                )
            seen_anims[clip.animation] = clip.skeleton
            chain, frame = bind(clip, own, req.options.binding)
            if clip.neutral_source.startswith("restTransforms (") and "not authored" not in clip.neutral_source:
                report.warnings.append(f"{clip.source}:{clip.skeleton}: neutral pose from {clip.neutral_source}")
            directives, targets, names = _directives(stage, clip, root_requests)
            result = apply_look(clip, chain, frame, gaze_map, directives, targets, req.options, req.look, names)
            report.warnings.extend(result.warnings)
            overrides.append(_override(clip, chain, result))
            report.characters.append(_character_report(clip, chain, frame, map_source, result))
            if req.guides:
                report.characters[-1].guide = (
                    clip.times, np.stack([to_skel(clip, p) for p in result.eye_positions]),
                    to_skel(clip, result.point_of_sight), result.point_of_sight, 0.003 / clip.meters_per_unit)
            if req.progress:
                req.progress(clip)
    return report, overrides, _layer_info(stage)


def _layer_info(stage) -> LayerInfo:
    """Timing and units metadata of the input, copied to every layer written."""
    from pxr import UsdGeom

    return LayerInfo(float(stage.GetTimeCodesPerSecond()), float(stage.GetFramesPerSecond()),
                     float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode()),
                     str(UsdGeom.GetStageUpAxis(stage)), float(UsdGeom.GetStageMetersPerUnit(stage)))


def _root_directives(root, source: str, requests: list[DirectiveRequest]) -> list[DirectiveRequest]:
    """The command's directives, or without any the SkelRoot's own schedule."""
    from usdgaze.usd import schedule

    if requests:  # in time order, as a schedule holds them: the same directives record the same text
        return sorted(requests, key=lambda r: (r.seconds, r.time))
    if not schedule.has_schedule(root):
        raise UsdGazeError(f"{source}:{root.GetPath()}: no --shift, --look-at or --release given and no "
                           f"{schedule.API_NAME} on this SkelRoot; nothing to do")
    return schedule.read_schedule(root, source)


def _directives(stage, clip: SkelClip, requests: list[DirectiveRequest]
                ) -> tuple[list[Directive], list[np.ndarray], list[str]]:
    """Pass directives for one clip, and the world positions per frame of what its looks look at."""
    from usdgaze.usd.targets import sample_target

    tcps = clip.time_codes_per_second
    first, last = clip.seconds[0], clip.seconds[-1]
    index_of: dict = {}
    targets: list[np.ndarray] = []
    names: list[str] = []
    directives = []
    for r in requests:
        t = r.time_s(clip.start_time, tcps)
        if not first - 1e-9 <= t <= last + 1e-9:
            raise UsdGazeError(
                f"{clip.where()}: {r.flag} lies outside the animation (time codes {clip.times[0]:g} to "
                f"{clip.times[-1]:g}, {first:g} to {last:g} s)")
        index = -1
        if r.kind == "look":
            key = r.target if r.target is not None else r.point
            if key not in index_of:
                index_of[key] = len(targets)
                if r.target is not None:
                    targets.append(sample_target(stage, r.target, clip.times, clip.source))
                    names.append(r.target)
                else:
                    targets.append(np.tile(np.asarray(r.point, dtype=float), (len(clip.times), 1)))
                    names.append(",".join(f"{v:g}" for v in r.point))
            index = index_of[key]
        directives.append(Directive(t, r.kind, r.yaw, r.pitch, index, r.weight, r.blend_s(tcps)))
    return directives, targets, names


def _override(clip: SkelClip, chain: Chain, result: PassResult) -> AnimOverride:
    """The arrays the override layer holds for one animation (and its skeleton, if eyes were added)."""
    grew = len(result.anim_joints) > len(clip.anim_joints)
    override = AnimOverride(
        animation=clip.animation,
        times=clip.times,
        joints=result.anim_joints,
        rotations=result.rotations,
        translations=result.translations if (chain.leg_roots or result.added_joints or grew) else None,
        scales=result.scales if grew else None,
        write_joints=grew,
    )
    if result.added_joints:
        override.skeleton = clip.skeleton
        override.skeleton_joints = clip.joints + result.added_joints
        override.rest_transforms = np.concatenate([clip.rest_local, result.added_rest_local])
        override.bind_transforms = np.concatenate([clip.bind_world, result.added_bind_world])
        if clip.joint_names is not None:
            override.joint_names = clip.joint_names + [j.rsplit("/", 1)[-1] for j in result.added_joints]
    return override


def _character_report(clip: SkelClip, chain: Chain, frame: CharacterFrame, map_source: str,
                      result: PassResult) -> CharacterReport:
    return CharacterReport(
        skel_root=clip.skel_root, skeleton=clip.skeleton, animation=clip.animation, map_source=map_source,
        chain={r: [clip.joints[j] for j in idx] for r, idx in chain.roles.items()},
        forward=[float(v) for v in frame.forward], frames=len(clip.times),
        added_joints=result.added_joints, result=result,
    )


def _provenance(source: str, requests: list[DirectiveRequest], report: ApplyReport, options: PassOptions,
                look: LookOptions) -> dict:
    # Only what the directives say, never where they came from: a schedule and the same flags
    # record the same text.
    flags = [f for fl in report.directives.values() for f in fl]
    return {
        "usdgaze": {
            "version": __version__,
            "input": os.path.basename(source),
            "shifts": list(dict.fromkeys(f.split(" ", 1)[1] for f in flags if f.startswith("--shift "))),
            "directives": report.directives,
            "eyeTiming": look.eye_timing,
            "maps": sorted({c.map_source for c in report.characters}),
            "characters": [c.skel_root for c in report.characters],
            # What the review tools draw the eye angles against, and the point of sight's distance.
            "eyeRange": {"yaw": float(options.eye_range.yaw), "up": float(options.eye_range.up),
                         "down": float(options.eye_range.down)},
            "fixation": float(options.fixation_m),
            **hints_record(options.binding),
        }
    }


def _stage_outputs(tx: Outputs, req: ApplyRequest, stage, report: ApplyReport,
                   overrides: list[AnimOverride], info: LayerInfo) -> None:
    """Stage the override, then the preview, plot or sublayer edit; the caller's ``with`` commits them."""
    animations = [c.animation for c in report.characters]
    if req.sublayer_into is not None:  # refuse before anything is staged
        check_sublayer_target(req.sublayer_into, animations)
    out = Path(req.out)
    layer = build_override(overrides, info, fmt=out.suffix.lstrip("."))
    if req.guides:
        from pxr import Sdf

        from usdgaze.usd.guides import author_guides

        with Sdf.ChangeBlock():
            for c in report.characters:
                author_guides(layer, c.skeleton, *c.guide)
    atomic_export(layer, out, tx)
    if req.preview is not None:
        default_prim = stage.GetRootLayer().defaultPrim or None
        write_preview(req.preview, out, req.source, info, default_prim, tx)
        report.preview = str(req.preview)
    if req.plot is not None:
        from usdgaze.review.plotting import plot_report

        plot_report(report, req.plot, tx, layer=layer)  # drawn from the composed result, not yet on disk
        report.plot = str(req.plot)
    if req.sublayer_into is not None:
        insert_sublayer(req.sublayer_into, out, animations, tx)
        report.sublayered_into = str(req.sublayer_into)
