"""``usdgaze dump-map``: the built-in gaze map as an editable USD file."""

from __future__ import annotations

import click

from usdgaze import __version__


@click.command("dump-map")
@click.argument("out", type=click.Path(dir_okay=False))
@click.option("--prim", default="/GazeMap", show_default=True,
              help="Prim path of the map in the new file: a root prim path (one name under /, e.g. /GazeMap), "
                   "made the file's default prim.")
@click.option("--no-clobber", is_flag=True, help="Refuse to replace an existing file.")
def dump_map(out, prim, no_clobber) -> None:
    """Write the built-in gaze map to OUT, to edit and use with --map or by reference."""
    from usdgaze.files.transaction import Outputs
    from usdgaze.gaze.defaults import default_definition
    from usdgaze.usd.schema import check_map_path, dump_map as dump

    with Outputs(no_clobber=no_clobber) as tx:
        tx.claim(check_map_path(out), "OUT")
        dump(default_definition(), out, prim_path=prim, outputs=tx,
             custom_layer_data={"usdgaze": {"version": __version__, "map": "built-in default"}})
    click.echo(f"wrote {out}")
