"""``usdgaze apply``: gaze shifts and look-ats onto UsdSkel animation, written as an override layer."""

from __future__ import annotations

import json
import os

import click
import numpy as np



@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--shift", "shifts", multiple=True, metavar="TIME:YAW:PITCH[:weight=W][:blend=B]",
              help="A gaze shift: TIME a time code, or seconds from the stage start with an 's' suffix; "
                   "YAW (+ toward the character's left) and PITCH (+ up) in degrees; W in [0, 1] the gaze weight, "
                   "eased in over B time codes (or seconds with 's'). Repeatable.")
@click.option("--look-at", "look_at", multiple=True, metavar="TARGET@TIME[:weight=W][:blend=B]",
              help="Look at TARGET from TIME on: a prim path (an Xformable's pivot, a Boundable's bounding-box "
                   "centre, animated or not) or a world point X,Y,Z. W in [0, 1] is the gaze weight, eased in "
                   "over B time codes (or seconds with 's'). Repeatable.")
@click.option("--release", "release", multiple=True, metavar="TIME[:blend=B]",
              help="Return to the base motion's own gaze at TIME: a gaze shift, or with a blend a fade of the "
                   "gaze weight to 0 over B time codes (or seconds with 's'). Repeatable.")
@click.option("--eye-timing", default="saccade", show_default=True, type=click.Choice(["saccade", "model"]),
              help="saccade: the eyes move on the main sequence and pursue; model: the paper's coupled eye timing.")
@click.option("--no-guides", is_flag=True, help="Do not author the guide-purpose lines of sight and point of sight.")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Override layer to write (.usda/.usdc/.usd).")
@click.option("--skel-root", default=None, help="SkelRoot prim path (default: every SkelRoot with a GazeMapAPI, else the only one holding a Skeleton).")
@click.option("--map", "map_spec", default=None, metavar="FILE[:PRIM]", help="Gaze map to use instead of the SkelRoot's or the built-in one.")
@click.option("--sublayer-into", default=None, type=click.Path(dir_okay=False), metavar="ROOT",
              help="Insert the override as the strongest sublayer of ROOT (only ROOT's subLayers change; "
                   "OpenUSD writes the layer anew, so # comments in a text ROOT are not kept).")
@click.option("--preview", default=None, type=click.Path(dir_okay=False), metavar="NEW_ROOT",
              help="Write a new root layer that sublayers [override, input].")
@click.option("--fixation", default=2.0, show_default=True, type=float, help="Distance of the point of sight, metres.")
@click.option("--plot", default=None, type=click.Path(dir_okay=False), metavar="FILE.png",
              help="Also draw wanted vs achieved gaze, segment angles and eye angles (needs matplotlib).")
@click.option("--bind", "bind", multiple=True, metavar="ROLE=JOINT[+JOINT...]",
              help="Bind a gaze role (pelvis, lowerSpine, upperSpine, neck, head, leftEye, rightEye) to joints, "
                   "by path or name, where names do not say it. Repeatable; wins over the map's bindings.")
@click.option("--forward", default=None, metavar="X,Y,Z",
              help="The character's forward in skeleton space, where no left/right joint names tell it or where the "
                   "skeleton's own space is tilted from the world (the report then gives it).")
@click.option("--no-clobber", is_flag=True, help="Refuse to replace an existing --out, --preview or --plot file.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def apply(input_path, shifts, look_at, release, eye_timing, no_guides, out, skel_root, map_spec, sublayer_into,
          preview, fixation, plot, bind, forward, no_clobber, as_json) -> None:
    """Add gaze shifts and look-ats to the skeletal animation in INPUT and write them to --out.

    Without --shift, --look-at or --release, each SkelRoot's GazeScheduleAPI schedule is applied.

    All outputs are written together at the end, or none is. An existing output file is replaced
    (keeping its mode) unless --no-clobber is given; no output may be a file the command reads, or
    a USD layer with prims that usdgaze did not write.
    """
    from usdgaze.api import apply as run
    from usdgaze.core.hints import parse_hints
    from usdgaze.passes.look import LookOptions
    from usdgaze.passes.options import PassOptions

    report = run(input_path, list(shifts), out, skel_root=skel_root, map_spec=map_spec,
                 sublayer_into=sublayer_into, preview=preview, plot=plot, no_clobber=no_clobber,
                 options=PassOptions(fixation_m=fixation, binding=parse_hints(bind, forward)),
                 look_at=list(look_at), release=list(release), look=LookOptions(eye_timing=eye_timing),
                 guides=not no_guides)
    for w in report.warnings:
        click.echo(f"usdgaze: warning: {w}", err=True)
    summary = _summary(report)
    if as_json:
        click.echo(json.dumps(summary, indent=2))
        return
    for c in summary["characters"]:
        click.echo(f"{c['skel_root']}  ({c['frames']} frames, map: {c['map']})")
        click.echo("  chain: " + ", ".join(f"{r}={'+'.join(v) or '-'}" for r, v in c["chain"].items()))
        if c["added_joints"]:
            click.echo("  added eye joints: " + ", ".join(c["added_joints"]))
        click.echo("  directives: " + " ".join(c["directives"]))
        for s in c["shifts"]:
            click.echo(f"  shift {s['at']:>10}  yaw {s['yaw']:7.1f}  pitch {s['pitch']:6.1f}  "
                       f"duration {s['duration_s']:.2f}s  overshoot {s['overshoot']:.2f}  "
                       f"hold error {s['hold_error_deg']}")
    click.echo(f"wrote {report.output}")
    if plot:
        click.echo(f"wrote {plot}")
    if report.preview:
        click.echo(f"wrote {report.preview}  (open it to see the result; mute {os.path.basename(report.output)} to compare)")
    if report.sublayered_into:
        click.echo(f"{report.output} was already the strongest sublayer of {report.sublayered_into} (left as it was)"
                   if report.sublayer_was_there else
                   f"inserted {report.output} as the strongest sublayer of {report.sublayered_into}")


def _summary(report) -> dict:
    chars = []
    for c in report.characters:
        r = c.result
        shifts = []
        for k, s in enumerate(r.shift_timing):
            shifts.append({
                "at": f"{s['time_s']:.3f}s", "yaw": s["yaw"], "pitch": s["pitch"],
                "duration_s": s["duration"], "overshoot": s["overshoot"], "interrupted": s["interrupted"],
                "hold_error_deg": _hold_error(r, k),
            })
        chars.append({
            "skel_root": c.skel_root, "skeleton": c.skeleton, "animation": c.animation, "map": c.map_source,
            "frames": c.frames, "chain": {k: [j.rsplit('/', 1)[-1] for j in v] for k, v in c.chain.items()},
            "added_joints": c.added_joints, "directives": report.directives.get(c.skel_root, []), "shifts": shifts,
        })
    return {"output": report.output, "preview": report.preview, "sublayered_into": report.sublayered_into,
            "characters": chars, "warnings": report.warnings}


def _hold_error(result, k: int) -> str:
    """Largest error of the achieved gaze change while shift k holds (after it settles)."""
    timing = result.shift_timing
    seconds = result.seconds
    start = timing[k]["time_s"]
    end = timing[k + 1]["time_s"] if k + 1 < len(timing) else np.inf
    hold = result.settled & (seconds >= start) & (seconds < end)
    if not np.any(hold):
        return "n/a (no settled frame)"
    return f"{np.abs(result.achieved[hold] - result.requested[hold]).max():.3f} deg"
