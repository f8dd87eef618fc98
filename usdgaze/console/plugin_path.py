"""``usdgaze plugin-path``: the folder for PXR_PLUGINPATH_NAME."""

from __future__ import annotations

import click

@click.command("plugin-path")
def plugin_path() -> None:
    """Print the folder to put on PXR_PLUGINPATH_NAME so usdview, Houdini and others know GazeMapAPI."""
    from usdgaze.usd.plugin import plugin_dir

    click.echo(str(plugin_dir()))
