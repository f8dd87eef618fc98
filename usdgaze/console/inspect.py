"""``usdgaze inspect``: skeletons, the gaze chain bound on each and why, maps and time range."""

from __future__ import annotations

import json

import click


@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--bind", "bind", multiple=True, metavar="ROLE=JOINT[+JOINT...]",
              help="Try a binding as `usdgaze apply --bind` would use it. Repeatable.")
@click.option("--forward", default=None, metavar="X,Y,Z", help="Try a character forward (skeleton space).")
@click.option("--json", "as_json", is_flag=True, help="Print as JSON.")
def inspect(input_path, bind, forward, as_json) -> None:
    """Print the skeletons of INPUT, the gaze chain found on each and why, maps present and the time range.

    Exits 2 after printing where a skeleton cannot bind (apply and attend would refuse it)."""
    from usdgaze.core.hints import parse_hints
    from usdgaze.review.inspection import inspect_stage

    info = inspect_stage(input_path, parse_hints(bind, forward))
    if as_json:
        click.echo(json.dumps(info, indent=2))
    else:
        _print(info)
    skeletons = [s for root in info["skel_roots"] for s in root["skeletons"]]
    failed = [s for s in skeletons if s.get("error")]
    if failed:  # a pre-flight check must tell a rig apply refuses from one it takes
        from usdgaze.errors import UsdGazeError

        raise UsdGazeError(f"{info['file']}: {len(failed)} of {len(skeletons)} skeleton(s) cannot bind "
                           f"({failed[0]['path']} first, said above): apply and attend refuse them")


def _print(info: dict) -> None:
    click.echo(f"{info['file']}: upAxis {info['up_axis']}, metersPerUnit {info['meters_per_unit']:g}, "
               + (f"time codes {info['start']:g}..{info['end']:g}" if info["start"] is not None else "no time range authored")
               + f" at {info['time_codes_per_second']:g}/s")
    for root in info["skel_roots"]:
        click.echo(f"SkelRoot {root['path']}  gaze map: {root['map']}")
        if not root["skeletons"]:
            click.echo("  no Skeleton under this SkelRoot")
        for s in root["skeletons"]:
            click.echo(f"  Skeleton {s['path']}  {s['joints']} joints")
            if s.get("error"):
                click.echo(f"    cannot bind: {s['error']}")
                continue
            if s.get("no_character"):  # beside the SkelRoot's character: left as it is
                click.echo(f"    no character (no head; apply and attend leave it as it is): {s['no_character']}")
                continue
            span = f"time codes {s['first']:g}..{s['last']:g}"
            if not s["animation_bound"]:
                click.echo(f"    animation: none bound (UsdSkel shows the rest pose); the layer defines {s['animation']} "
                           f"holding it, {s['frames']} frames of the stage's range, {span}")
            elif s["held_pose"]:
                click.echo(f"    animation {s['animation']}  one held pose (a default or a single time sample): {s['frames']} frames of "
                           f"the stage's range, {span}")
            else:
                click.echo(f"    animation {s['animation']}  {s['frames']} samples, {span}")
            click.echo(f"    neutral pose: {s['neutral']}")
            for role, joints in s["chain"].items():
                if joints:
                    bound = ", ".join(joints)
                else:
                    bound = "- (eye joints will be added)" if role.endswith("Eye") else "-"
                why = f"  [{s['why'][role]}]" if s["why"].get(role) else ""
                click.echo(f"    {role:<11} {bound}{why}")
            click.echo(f"    forward (skeleton space) {tuple(round(v, 3) for v in s['forward'])}  [{s['forward_from']}]")
            if s.get('frame_note'):
                click.echo(f"    note: {s['frame_note']}")
