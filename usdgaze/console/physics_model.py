"""``usdgaze physics-model``: write the MuJoCo (MJCF) body model of a skeleton for inspection."""

from __future__ import annotations

import click

from usdgaze.console.types import FiniteRange


@click.command("physics-model")
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False), help="MJCF file to write (.xml).")
@click.option("--mass", "mass", default=75.0, show_default=True, type=FiniteRange(1.0, 500.0),
              help="Total body mass, kg.")
@click.option("--timestep", default=None, type=float,
              help="Simulation step h, seconds: 0.001-0.05. Default: the step attend --physics takes for "
                   "the stage's task (0.03 with a ball to catch or moving obstacles, else 0.02).")
@click.option("--skel-root", default=None, help="SkelRoot prim path when the stage has several.")
def physics_model(input_path, out, mass, timestep, skel_root) -> None:
    """Write the MuJoCo body model attend --physics simulates for INPUT's skeleton: a body per joint,
    de Leva (1996) segment masses, hinge knees and elbows, ball joints elsewhere, motors, a ground plane
    (Z-up, metres)."""
    from usdgaze.passes.physics_shots import write_model

    info = write_model(input_path, out, total_mass=mass, timestep=timestep, skel_root=skel_root)
    kinds = ", ".join(f"{n} {k}" for k, n in info["joints"].items() if n)
    click.echo(f"{out}: {info['bodies']} bodies ({kinds}), {info['mass']:g} kg, h {info['timestep']:g} s, "
               f"from {info['skeleton']}")
