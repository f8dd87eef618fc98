"""Registers the codeless GazeMapAPI schema plugin with OpenUSD.

OpenUSD builds its schema registry once, the first time anything in the process asks it about a
schema (defining or opening a typed prim is enough), from the plugins known at that moment; a
plugin registered later is ignored without a word. So ``import usdgaze`` calls :func:`register` before anything else.
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

PLUGIN_NAME = "usdGaze"
"""``Name`` in plugInfo.json (the schema's ``libraryName``)."""
SCHEMA_NAME = "GazeMapAPI"
"""The applied API schema's identifier, as written in ``apiSchemas``."""

_registered = False


@contextlib.contextmanager
def _stops_held():
    """SIGINT and SIGTERM, where Python handles them, held back while OpenUSD's modules load and
    delivered again after. Raised inside OpenUSD's module loader, the KeyboardInterrupt of a Ctrl-C at
    ``import usdgaze`` was printed as a warning and swallowed: the import went on (a pxr module half
    made) and so did the command, which wrote its output and exited 0."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():  # handlers live in the main thread
        yield
        return
    pending: list[int] = []
    saved = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(sig)
        if callable(handler):  # Python's KeyboardInterrupt or a host's handler; SIG_DFL/SIG_IGN act in C
            saved[sig] = handler
            signal.signal(sig, lambda signum, frame: pending.append(signum))
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        for sig in dict.fromkeys(pending):
            signal.raise_signal(sig)  # the original handler runs now, outside OpenUSD's loader


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
    with _stops_held():
        from pxr import Plug, Tf, Usd

        try:
            known = Plug.Registry().GetPluginWithName(PLUGIN_NAME)
        except Tf.ErrorException as exc:
            # A plugInfo.json on PXR_PLUGINPATH_NAME that OpenUSD cannot read: it reports that once, on
            # the first call after reading the plugins, and goes on without it, as its own tools do.
            from usdgaze.errors import usd_failure

            warnings.warn(f"OpenUSD: {usd_failure(exc)}", RuntimeWarning, stacklevel=2)
            known = Plug.Registry().GetPluginWithName(PLUGIN_NAME)
        if known is None:
            Plug.Registry().RegisterPlugins(str(plugin_dir()))
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


def has_api(prim, name: str, error: type | None = None) -> bool:
    """Whether ``prim`` has usdgaze's applied API schema ``name`` (``prim.HasAPI``).

    When OpenUSD's schema registry was built before :func:`register` (a host that opened a stage
    before importing usdgaze), ``HasAPI`` is False even where ``apiSchemas`` lists the schema: the
    prim's map, schedule or object would be silently ignored. That is a one-line ``error``
    (:class:`~usdgaze.errors.UsdGazeError` by default) naming the prim instead.
    """
    if not prim:
        return False
    if prim.HasAPI(name):
        return True
    from pxr import Usd

    if name in prim.GetPrimTypeInfo().GetAppliedAPISchemas() and not Usd.SchemaRegistry.GetTypeFromSchemaTypeName(name):
        from usdgaze.errors import UsdGazeError

        stage = prim.GetStage()
        where = f"{stage.GetRootLayer().identifier if stage else '<no stage>'}:{prim.GetPath()}"
        raise (error or UsdGazeError)(
            f"{where}: has {name} applied, but OpenUSD does not know {name} in this process (its schema "
            f"registry was built before usdgaze was imported); import usdgaze before opening any stage, "
            f"or set PXR_PLUGINPATH_NAME={plugin_dir()}"
        )
    return False
