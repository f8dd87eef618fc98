"""Every command the console lists loads."""

from __future__ import annotations


def test_the_console_loads_every_command_it_lists():
    from usdgaze.console.main import cli

    for name in cli.list_commands(None):
        assert cli.get_command(None, name) is not None, name
