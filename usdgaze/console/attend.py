"""``usdgaze attend``: where and when a character looks among moving objects (Eom et al. 2019)."""

from __future__ import annotations

import json

import click

from usdgaze.console.types import FiniteRange


@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Override layer to write (.usda/.usdc/.usd).")
@click.option("--objects", default=None, metavar="PATH,...",
              help="Prims to look at (default: every prim with GazeObjectAPI).")
@click.option("--alpha", default=0.2, show_default=True, type=float,
              help="Process noise of the vision system's belief, per second (0: glance once; 0.2: steady tracking).")
@click.option("--cost", default="uncertainty", show_default=True, type=click.Choice(["uncertainty", "distance", "sequential"]),
              help="Attention cost: the paper's uncertainty, the distance-sum baseline, or one object after another.")
@click.option("--window", "window_s", default=None, type=float,
              help="Planner window, seconds, for every shot (with --physics the stepping stones' task still "
                   "looks 0.6 s ahead, docs/physics.md).  [default: 0.8; with --physics 0.6, and 1.0 for a shot "
                   "with stepping stones]")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**32 - 1),
              help="Seed of the simulated observation noise.")
@click.option("--realize", default="direct", show_default=True, type=click.Choice(["direct", "map"]),
              help="direct: write the planner's eyes, neck and spine; map: turn its fixations into look-at "
                   "directives realized through the gaze map (cascade, overshoot, saccades).")
@click.option("--skel-root", default=None,
              help="SkelRoot prim path (default: every SkelRoot with a GazeMapAPI, else the only one holding a Skeleton).")
@click.option("--bind", "bind", multiple=True, metavar="ROLE=JOINT[+JOINT...]",
              help="Bind a gaze role (pelvis, lowerSpine, upperSpine, neck, head, leftEye, rightEye) to joints, "
                   "by path or name, where names do not say it. Repeatable; wins over the map's bindings.")
@click.option("--forward", default=None, metavar="X,Y,Z",
              help="The character's forward in skeleton space, where no left/right joint names tell it or where the "
                   "skeleton's own space is tilted from the world (the report then gives it).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--physics", is_flag=True,
              help="Simulate the whole body on MuJoCo under the full-body MPC, tracking the base motion (root "
                   "included; pushes authored on the SkelRoot act on it). With objects in the stage the eyes and "
                   "belief are simulated with the body, and balls the SkelRoot's usdgaze:physics:catch names are "
                   "caught.")
@click.option("--discard-failed", is_flag=True, help="With --physics: when a shot has a problem (a fall, a foot over 2 cm "
              "below the ground, a task missed), write nothing and exit 2.")
@click.option("--threads", default=1, show_default=True, type=click.IntRange(1, 64),
              help="With --physics: threads for the planner's finite differences (results identical to one).")
@click.option("--fd-stride", default=1, show_default=True, type=click.IntRange(1, 8),
              help="With --physics: MuJoCo derivatives every N planner steps, interpolated between (faster; "
                   "2 roughly halves the time, docs/physics.md).")
@click.option("--timestep", default=None, type=FiniteRange(0.01, 0.05),
              help="With --physics: the simulation's and the planner's step h, seconds, for every shot (the paper: "
                   "0.02-0.03 by task).  [default: 0.02; 0.03 for a shot with a ball to catch or moving obstacles "
                   "and no stepping stones]")
@click.option("--fd-reuse", default=1, show_default=True, type=click.IntRange(1, 8),
              help="With --physics: keep a step's MuJoCo derivatives for up to N solves while its contacts "
                   "stay the same (faster; 3 saves about a quarter, feet sink deeper, docs/physics.md).")
@click.option("--iterations", default=1, show_default=True, type=click.IntRange(1, 10),
              help="With --physics: solver iterations per planner step.")
@click.option("--retry-iterations", default=2, show_default=True, type=click.IntRange(0, 10),
              help="With --physics: simulate a shot that fell, sank a foot over 2 cm or missed a task again "
                   "with this many iterations per step, and where that fails too with twice as many (at most 10); "
                   "the best is kept (never where it is not more than --iterations, e.g. 0; one iteration let 3 of "
                   "12 stepping-stone shots fall, and with their 1.0 s window the first simulation often falls, "
                   "docs/physics.md).")
@click.option("--raw-contacts", is_flag=True,
              help="With --physics: write the simulated feet as MuJoCo's soft ground left them (a loaded foot sinks "
                   "1-3 cm into it), not lifted out of it by their legs (docs/physics.md).")
@click.option("--mass", default=75.0, show_default=True, type=FiniteRange(1.0, 500.0),
              help="With --physics: the body's total mass, kg (de Leva's segment shares of it; as physics-model).")
@click.pass_context
def attend(ctx, input_path, out, objects, alpha, cost, window_s, seed, realize, skel_root, bind, forward, as_json,
           physics, discard_failed, threads, fd_stride, timestep, fd_reuse, iterations, retry_iterations,
           raw_contacts, mass) -> None:
    """Let the character in INPUT look at the moving objects of the stage; write eyes, neck and spine to --out."""
    from usdgaze.core.hints import parse_hints

    _check_combination(ctx, physics)
    if physics:
        from usdgaze.passes.physics_options import with_timestep, with_window
        from usdgaze.physics.mpc import Options

        options = with_window(with_timestep(Options(workers=threads, fd_stride=fd_stride, fd_reuse=fd_reuse,
                                                    iterations=iterations, retry_iterations=retry_iterations,
                                                    ground_feet=not raw_contacts), timestep), window_s)
        return _physics(input_path, out, options, skel_root, discard_failed, as_json, seed,
                        parse_hints(bind, forward), mass)
    from usdgaze.attend import AttendSettings, attend as run

    paths = [p.strip() for p in objects.split(",") if p.strip()] if objects is not None else None
    settings = AttendSettings(alpha=alpha, cost=cost, seed=seed, realize=realize,
                              window_s=AttendSettings.window_s if window_s is None else window_s,
                              binding=parse_hints(bind, forward))
    from usdgaze.batch.progress import StepBar

    bar = StepBar(desc="planning")  # a bar of the planner's steps on a terminal: a long shot takes minutes
    try:
        report = run(input_path, out, paths, settings, skel_root=skel_root, progress=bar)
    finally:
        bar.close()
    for w in report.warnings:  # as apply says them: on stderr, JSON or not
        click.echo(f"usdgaze: warning: {w}", err=True)
    summary = {"output": report.output, "characters": report.characters, "objects": report.objects,
               "planner": report.planner, "warnings": report.warnings}
    if as_json:
        click.echo(json.dumps(summary, indent=2))
        return
    p = report.planner
    for c in report.characters:
        click.echo(f"{c['skel_root']}  ({c['frames']} frames; drives {', '.join(c['changed_joints'])})")
        for o in c["objects"]:  # as this character saw them
            seen = "never seen" if o["first_seen_s"] is None else f"first seen at {o['first_seen_s']:.2f} s"
            click.echo(f"  {o['path']}: {seen}, tracked {100 * o['tracked_share']:.0f}% of the time")
    click.echo(f"planner: {p['steps']} steps of {p['h']} s, window {p['window_s']} s, "
               f"{p['mean_iterations']} iterations/step, {p['frames_per_second']} frames/s")
    click.echo(f"wrote {report.output}")


def _sank(r) -> str:
    """How deep the simulation's soft ground let a foot sink, where the written feet were lifted out of it."""
    lifted = r.contact_depth_m - r.max_foot_below_ground_m
    return f" (sank {100 * r.contact_depth_m:.1f} cm into the soft ground, lifted by the legs)" if lifted > 5e-4 else ""


def _check_combination(ctx, physics: bool) -> None:
    from click.core import ParameterSource

    from usdgaze.attend import KINEMATIC_ONLY, PHYSICS_ONLY
    from usdgaze.errors import UsdGazeError

    given = [name for name in ctx.params if ctx.get_parameter_source(name) != ParameterSource.DEFAULT]
    flag = lambda name: "--" + name.replace("_", "-")  # noqa: E731
    if physics:
        wrong = [flag(name) for name in KINEMATIC_ONLY if name in given]
        if wrong:
            raise UsdGazeError(f"{wrong[0]} is not taken with --physics: the coupled loop reads every "
                               "GazeObjectAPI prim with its own belief settings (docs/physics.md)")
    else:
        wrong = [flag(name) for name in PHYSICS_ONLY if name in given]
        if wrong:
            raise UsdGazeError(f"{wrong[0]} is an option of --physics")


def _physics(input_path, out, options, skel_root, discard_failed, as_json, seed, binding, mass) -> None:
    """``--physics``: the physics pass (usdgaze.passes.physics); one line per shot, a fall said plainly."""
    from dataclasses import asdict

    from usdgaze.batch.progress import StepBar
    from usdgaze.passes.physics import run

    bar = StepBar()  # a bar of the simulated steps on a terminal: a long shot takes minutes
    try:
        reports = run(input_path, out, options, skel_root=skel_root, keep_failed=not discard_failed, seed=seed,
                      binding=binding, total_mass=mass, progress=bar)
    finally:
        bar.close()
    for w in dict.fromkeys(w for r in reports for w in r.warnings):  # on stderr, as apply says them
        click.echo(f"usdgaze: warning: {w}", err=True)
    if as_json:
        click.echo(json.dumps({"output": str(out), "shots": [asdict(r) for r in reports]}, indent=2))
        return
    for r in reports:
        state = "; ".join(r.problems) if r.problems else "stayed up"
        if r.other_attempt:  # simulated twice (``passes.physics._simulate_shot``)
            state += f" with {r.iterations} iteration(s) a step (simulated again; {'; '.join(r.other_attempt)})"
        if r.reference_notes:  # the reference's own fault, whatever the simulation did
            state += f"; {'; '.join(r.reference_notes)}"
        click.echo(f"{r.skeleton}: {state}; pelvis >= {r.min_pelvis_ratio:.0%} of the reference, mean joint error "
                   f"{r.mean_joint_error_deg:.1f} deg, feet <= {100 * r.max_foot_below_ground_m:.1f} cm below ground{_sank(r)}, "
                   f"root <= {100 * r.max_root_drift_m:.1f} cm from the reference's across the ground, "
                   f"{r.simulated_s:.2f} s simulated in {r.wall_s:.1f} s (step {r.timestep_s:g} s, window {r.window_s:g} s)")
        for line in r.tasks:
            click.echo(f"  {line}")
    click.echo(f"wrote {out}")
