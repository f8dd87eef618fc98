"""``usdgaze inspect``: what a stage holds, as the gaze pass will see it."""

from __future__ import annotations

from usdgaze.errors import NoHeadError, UsdGazeError
from usdgaze.files.kinds import require_file


def inspect_stage(path: str, hints=None) -> dict:
    """Skeletons, the chain found on each (and why), maps present and the time range, as plain data.

    ``hints``: :class:`usdgaze.core.hints.BindHints` to try, as ``apply --bind/--forward`` would use them.
    """
    from pxr import UsdGeom

    from usdgaze.usd import schema
    from usdgaze.usd.checks import check_stage
    from usdgaze.usd.skelio import no_skel_root, skel_roots, skeletons_under
    from usdgaze.usd.stage import open_stage

    require_file(path)
    stage = open_stage(path)
    check_stage(stage, str(path))
    info = {
        "file": str(path),
        "up_axis": str(UsdGeom.GetStageUpAxis(stage)),
        "meters_per_unit": float(UsdGeom.GetStageMetersPerUnit(stage)),
        "start": float(stage.GetStartTimeCode()) if stage.HasAuthoredTimeCodeRange() else None,
        "end": float(stage.GetEndTimeCode()) if stage.HasAuthoredTimeCodeRange() else None,
        "time_codes_per_second": float(stage.GetTimeCodesPerSecond()),
        "skel_roots": [],
    }
    for root in skel_roots(stage):
        has = schema.has_map(root)
        try:  # one SkelRoot's broken map is its own entry's problem, as a skeleton's is
            definition, map_error = schema.root_map(root, str(path)), None
        except UsdGazeError as exc:
            definition, map_error = None, str(exc)
        entry = {"path": str(root.GetPath()),
                 "map": (f"{'GazeMapAPI, cannot read it' if has else 'none usable'}: {map_error}" if map_error else
                         f"GazeMapAPI, {len(definition)} examples" if has else "none (the built-in map is used)"),
                 "skeletons": [_skeleton(stage, skel, root, path, definition, map_error, hints)
                               for skel in skeletons_under(root)]}
        binds = any("error" not in s for s in entry["skeletons"])
        for s in entry["skeletons"]:  # headless beside a character: no character, as apply and attend leave it
            if s.pop("no_head", False) and binds:
                s["no_character"] = s.pop("error")
        info["skel_roots"].append(entry)
    if not info["skel_roots"]:
        raise no_skel_root(stage, str(path))
    return info


def _skeleton(stage, skel, root, path, definition, map_error: str | None, hints) -> dict:
    """One skeleton's entry: its binding as apply finds it, or the error (``no_head``: it has none)."""
    from usdgaze import api
    from usdgaze.usd.skelio import read_clip

    s = {"path": str(skel.GetPath()), "joints": len(skel.GetAttribute("joints").Get() or [])}
    try:
        if map_error:
            raise UsdGazeError(map_error)
        clip = read_clip(stage, skel, root, str(path))
        chain, frame = api.bind(clip, definition, hints)
    except NoHeadError as exc:  # a face's or a prop's skeleton: no character, if another binds
        s["error"], s["no_head"] = str(exc), True
    except UsdGazeError as exc:
        s["error"] = str(exc)
    else:
        s.update(animation=clip.animation, animation_bound=clip.animation_bound, held_pose=clip.held_pose,
                 frames=len(clip.times), first=float(clip.times[0]),
                 last=float(clip.times[-1]),
                 chain={r: [clip.joints[j].rsplit("/", 1)[-1] for j in idx] for r, idx in chain.roles.items()},
                 why={r: chain.reasons.get(r, "") for r in chain.roles},
                 forward=[float(v) for v in frame.forward], forward_from=frame.source,
                 frame_note=frame.note,
                 neutral=clip.neutral_source)
    return s
