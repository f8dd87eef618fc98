"""``usdgaze dump-map``: the built-in gaze map as an editable USD file."""

from __future__ import annotations

import click

from usdgaze import __version__

@click.command("dump-map")
@click.argument("out", type=click.Path(dir_okay=False))
@click.option("--prim", default="/GazeMap", show_default=True, help="Prim path of the map in the new file.")
def dump_map(out, prim) -> None:
    """Write the built-in gaze map to OUT, to edit and use with --map or by reference."""
    from usdgaze.gaze.defaults import default_definition
    from usdgaze.usd.schema import dump_map as dump

    dump(default_definition(), out, prim_path=prim, custom_layer_data={"usdgaze": {"version": __version__, "map": "built-in default"}})
    click.echo(f"wrote {out}")
