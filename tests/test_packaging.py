"""The wheel ships every subpackage of usdgaze: pyproject's explicit package list matches the source tree."""

from __future__ import annotations

import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_every_subpackage_is_listed_in_pyproject():
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {".".join(p.parent.relative_to(REPO).parts) for p in (REPO / "usdgaze").rglob("__init__.py")}
    assert on_disk - listed == set(), f"add these to [tool.setuptools] packages in pyproject.toml: {sorted(on_disk - listed)}"
    assert "usdgaze.schemas" in listed
    assert listed - on_disk == {"usdgaze.schemas"}, f"listed but absent: {sorted(listed - on_disk - {'usdgaze.schemas'})}"


def test_the_console_loads_every_command_it_lists():
    from usdgaze.console.main import cli

    for name in cli.list_commands(None):
        assert cli.get_command(None, name) is not None, name
