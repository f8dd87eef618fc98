"""The Python API of the gaze pass: read stage -> arrays -> model -> arrays -> write layer."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from usdgaze import __version__
from usdgaze.apply_types import ApplyReport, ApplyRequest, CharacterReport
from usdgaze.characters import (bind, bound_skeletons, built_map, clip_directives, own_map, root_directives,
                                select_roots)
from usdgaze.core.clip import SkelClip
from usdgaze.core.hints import to_record as hints_record
from usdgaze.core.rig import Chain, CharacterFrame
from usdgaze.errors import UsdGazeError
from usdgaze.files.transaction import Outputs
from usdgaze.gaze.defaults import default_definition
from usdgaze.passes.look import LookOptions, apply_look, to_skel
from usdgaze.passes.options import PassOptions, PassResult
from usdgaze.passes.requests import DirectiveRequest, check_directives
from usdgaze.usd import schema
from usdgaze.usd.guides import line_width
from usdgaze.usd.layers import (
    AnimOverride,
    OverrideLayer,
    atomic_export,
    check_output_path,
    layer_info,
    reload_if_open,
    write_preview,
)
from usdgaze.usd.sublayers import check_sublayer_target, insert_sublayer, masked_overrides
from usdgaze.values import ShiftRequest, check_pass_options, cli_label
from usdgaze.files.kinds import require_file

# The Python API: these names are imported from here (usdgaze.api.bind, select_roots, ApplyRequest, ...).
__all__ = ["ApplyReport", "ApplyRequest", "CharacterReport", "ShiftRequest", "apply", "bind", "built_map",
           "check_request", "run", "select_roots"]


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
        tx.check_replaceable()  # every input recorded: before the pass
        roots = select_roots(stage, req.source, req.skel_root)
        report, written = _run_pass(stage, roots, forced, requests, req)
        custom = _provenance(req.source, requests, report, req.options, req.look)
        custom["usdgaze"].update(req.record)
        _stage_outputs(tx, req, stage, report, written, custom)
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
    require_file(req.source)
    tx.read(req.source)  # first, so a clash names the input as such
    if req.make_folders:
        for path in (req.out, req.preview, req.plot):
            if path is not None:
                tx.make_folder(Path(path).parent)
    tx.claim(check_output_path(req.out), "--out")
    if req.preview is not None:
        tx.claim(check_output_path(req.preview, "--preview"), "--preview")
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
        _read_root_layers(tx, req.sublayer_into, req.out)


def _read_root_layers(tx: Outputs, root: str | os.PathLike, out: str | os.PathLike) -> None:
    """Record the layers ``root`` composes as read: ``--out`` naming one of them (the set dressing it
    sublayers beside the input) had replaced it with the override. Only an earlier usdgaze override in
    that slot is ``--out``'s to replace, as a rerun does."""
    from usdgaze.files.identity import FileId
    from usdgaze.usd.layers import is_override
    from usdgaze.usd.stage import layer_dependencies, without_usd_warnings

    with without_usd_warnings():  # a sublayer may be this command's output, not written yet
        files = layer_dependencies(os.path.realpath(root))
    own, out_id = FileId.of(root), FileId.of(out)
    for f in files:
        fid = FileId.of(f)
        if fid == own or (fid == out_id and is_override(f)):
            continue
        tx.read(f, f"layer composed by --sublayer-into {root}")


def _open_input(tx: Outputs, source: str):
    from usdgaze.usd.stage import composed_files, open_stage

    stage = open_stage(source)
    for path in composed_files(stage):
        tx.read(path, "layer composed by the input")  # the input itself was read first
    return stage


def _run_pass(stage, roots, forced, requests, req) -> tuple[ApplyReport, OverrideLayer]:
    """Read every skeleton under ``roots`` and run the gaze pass on it; each character's result goes
    into the override layer as it is done (the report keeps what the summary and guides need)."""
    from usdgaze.usd.layers import composed_override_notes
    from usdgaze.usd.skelio import animations_elsewhere, skeletons_under

    source = req.source
    report = ApplyReport(output=str(req.out), input=req.source)
    report.warnings.extend(composed_override_notes(stage, source))
    written = OverrideLayer(layer_info(stage), fmt=Path(req.out).suffix.lstrip("."), custom_later=True)
    seen_anims: dict[str, str] = {}
    others = animations_elsewhere(stage, roots)
    for root in roots:
        root_requests = root_directives(root, source, requests)
        report.directives[str(root.GetPath())] = [r.flag for r in root_requests]
        own = own_map(root, source)
        definition = forced or own or default_definition()
        map_source = req.map_spec if forced else (f"{source}:{root.GetPath()} (GazeMapAPI)" if own else f"built-in default (usdgaze {__version__})")
        gaze_map = built_map(definition)
        skels = skeletons_under(root)
        if not skels:
            raise UsdGazeError(f"{source}:{root.GetPath()}: no Skeleton under this SkelRoot")

        bound, notes = bound_skeletons(root, skels, source, lambda skel: _read_and_bind(
            stage, skel, root, own, forced, req, seen_anims, others))
        report.warnings.extend(notes)
        for _, (clip, chain, frame) in bound:
            report.warnings.extend(clip.notes + ([frame.note] if frame.note else []))
            if clip.neutral_source.startswith("restTransforms (") and "not authored" not in clip.neutral_source:
                report.warnings.append(f"{clip.source}:{clip.skeleton}: neutral pose from {clip.neutral_source}")
            directives, targets, names = clip_directives(stage, clip, root_requests, report.warnings)
            result = apply_look(clip, chain, frame, gaze_map, directives, targets, req.options, req.look, names)
            report.warnings.extend(result.warnings)
            written.add(AnimOverride.of(clip, result, move_roots=bool(chain.leg_roots)))
            report.characters.append(_character_report(clip, chain, frame, map_source, result.reviewed()))
            if req.guides:
                report.characters[-1].guide = (
                    clip.times, np.stack([to_skel(clip, p) for p in result.eye_positions]),
                    to_skel(clip, result.point_of_sight), result.point_of_sight,
                    line_width(0.003, clip.meters_per_unit, clip.skel_to_world))
            if req.progress:
                req.progress(clip)
    return report, written


def _read_and_bind(stage, skel, root, own, forced, req, seen_anims: dict, others) -> tuple:
    """(clip, chain, frame) of one skeleton; ``seen_anims`` (animation: skeleton) refuses an animation that
    drives two skeletons, ``others`` one that drives a character not being written."""
    from usdgaze.usd.skelio import check_not_shared, read_clip

    source = req.source
    clip = read_clip(stage, skel, root, source)
    clip.owns_arrays = True  # read for this call alone: the pass may build its result in place
    if clip.animation in seen_anims:
        raise UsdGazeError(
            f"{source}:{clip.animation}: drives both {seen_anims[clip.animation]} and {clip.skeleton}; "
            "an override of it would move both alike: give each skeleton its own SkelAnimation"
        )
    check_not_shared(others, clip.animation, source)
    seen_anims[clip.animation] = clip.skeleton
    # A --map file's gaze:binding:* bind the roles the SkelRoot's own map leaves unbound.
    return (clip, *bind(clip, own, req.options.binding, forced, f"--map {req.map_spec}"))


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
                   written: OverrideLayer, custom: dict) -> None:
    """Stage the override, then the preview, plot or sublayer edit; the caller's ``with`` commits them."""
    animations = [c.animation for c in report.characters]
    if req.sublayer_into is not None:  # refuse before anything is staged
        check_sublayer_target(req.sublayer_into, animations, req.source, bound=tuple(written.bound))
    out = Path(req.out)
    layer, info = written.finish(custom), written.info
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
        report.sublayer_was_there = not insert_sublayer(req.sublayer_into, out, animations, tx, input_path=req.source)
        report.sublayered_into = str(req.sublayer_into)
        report.warnings.extend(masked_overrides(req.sublayer_into, out, animations, req.source))
