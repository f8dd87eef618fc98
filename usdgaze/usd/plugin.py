"""Registers the codeless GazeMapAPI schema plugin with OpenUSD.

OpenUSD builds its schema registry once, the first time anything in the process asks it about a
schema (defining or opening a typed prim is enough), from the plugins known at that moment; a
plugin registered later is ignored without a word. So ``import usdgaze`` calls :func:`register` before anything else.
"""

from __future__ import annotations

import warnings
from pathlib import Path

PLUGIN_NAME = "usdGaze"
"""``Name`` in plugInfo.json (the schema's ``libraryName``)."""
SCHEMA_NAME = "GazeMapAPI"
"""The applied API schema's identifier, as written in ``apiSchemas``."""

_registered = False


def plugin_dir() -> Path:
    """The folder holding the schema's plugInfo.json and generatedSchema.usda."""
    here = Path(__file__).resolve().parents[1] / "schemas"  # an installed wheel's usdgaze/schemas
    if (here / "plugInfo.json").is_file():
        return here
    # Source checkout (editable installs too): ``usdgaze.schemas`` is setuptools' mapping of schemas/.
    checkout = Path(__file__).resolve().parents[2] / "schemas"
    if (checkout / "plugInfo.json").is_file():
        return checkout
    import importlib.resources  # a package mapped elsewhere (importlib.resources costs ~6 ms: last)

    try:
        installed = Path(str(importlib.resources.files("usdgaze.schemas")))
    except ModuleNotFoundError:
        installed = None
    if installed is not None and (installed / "plugInfo.json").is_file():
        return installed
    raise FileNotFoundError(f"usdgaze's schema plugin (plugInfo.json) is in none of {here}, {checkout}, {installed}")


def register() -> None:
    """Make ``GazeMapAPI`` known to OpenUSD; calling it again does nothing.

    A plugin of the same name that is already registered (``PXR_PLUGINPATH_NAME`` pointing at
    this or another copy of the schema) is kept as it is.
    """
    global _registered
    if _registered:
        return
    from pxr import Plug, Usd

    registry = Plug.Registry()
    if registry.GetPluginWithName(PLUGIN_NAME) is None:
        registry.RegisterPlugins(str(plugin_dir()))
    _registered = True
    # The same plugInfo.json declares usdgaze's UsdValidation validators (a Python plugin): OpenUSD
    # imports usdgaze.review.validators, which registers their tasks, the first time one is asked for.
    if not Usd.SchemaRegistry.GetTypeFromSchemaTypeName(SCHEMA_NAME):
        warnings.warn(
            f"OpenUSD's schema registry was built before usdgaze registered {SCHEMA_NAME}, so gaze maps "
            f"cannot be read or written in this process: import usdgaze before opening any stage, or set "
            f"PXR_PLUGINPATH_NAME={plugin_dir()}",
            RuntimeWarning,
            stacklevel=2,
        )
