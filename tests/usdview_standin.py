"""A stand-in for the parts of usdview the Gaze menu uses (usdview is not on PyPI, so it cannot run
here). It is NOT usdview: it holds a real ``Usd.Stage`` and implements the members of
``pxr.Usdviewq.usdviewApi.UsdviewApi`` our commands call, with the same names and meanings, plus the
plugin registry and UI builder that ``PluginContainer.registerPlugins`` / ``configureView`` receive."""

from __future__ import annotations

import sys
import types

from pxr import Tf, Usd


class UsdviewApiStandIn:
    def __init__(self, stage: Usd.Stage, frame: float = 0.0) -> None:
        self.stage = stage
        self.frame = Usd.TimeCode(frame)
        self.status: list[str] = []
        self._selection: list = []
        self.viewport_updates = 0

    @property
    def selectedPrims(self):
        return list(self._selection)

    @property
    def prim(self):
        return self._selection[0] if self._selection else None

    def PrintStatus(self, msg: str) -> None:
        self.status.append(msg)

    def ClearPrimSelection(self) -> None:
        self._selection.clear()

    def AddPrimToSelection(self, prim) -> None:
        self._selection.append(prim)

    def UpdateViewport(self) -> None:
        self.viewport_updates += 1


class CommandPlugin:
    def __init__(self, name, display_name, callback) -> None:
        self.name, self.displayName, self.callback = name, display_name, callback

    def run(self, api) -> None:
        self.callback(api)


class PlugRegistryStandIn:
    """``registerCommandPlugin(name, displayName, callback)`` as usdview's plugin registry has it."""

    def __init__(self) -> None:
        self.commands: dict[str, CommandPlugin] = {}

    def registerCommandPlugin(self, name, displayName, callback):
        assert name not in self.commands, f"{name} registered twice"
        self.commands[name] = CommandPlugin(name, displayName, callback)
        return self.commands[name]


class MenuStandIn:
    def __init__(self, name: str) -> None:
        self.name, self.items = name, []

    def addItem(self, item) -> None:
        self.items.append(item)


class UIBuilderStandIn:
    def __init__(self) -> None:
        self.menus: dict[str, MenuStandIn] = {}

    def findOrCreateMenu(self, name: str) -> MenuStandIn:
        return self.menus.setdefault(name, MenuStandIn(name))


def install_plugin_module() -> None:
    """Make ``from pxr.Usdviewq.plugin import PluginContainer`` importable (usdview's base class:
    an object with registerPlugins and configureView)."""
    if "pxr.Usdviewq.plugin" in sys.modules:
        return

    class PluginContainer:
        def registerPlugins(self, plugRegistry, usdviewApi):
            raise NotImplementedError

        def configureView(self, plugRegistry, plugUIBuilder):
            raise NotImplementedError

    # usdview defines its base as a TfType named after its module; plugInfo.json names that base.
    PluginContainer.__module__ = "pxr.Usdviewq.plugin"
    PluginContainer.__qualname__ = "PluginContainer"
    Tf.Type.Define(PluginContainer)
    package = types.ModuleType("pxr.Usdviewq")
    module = types.ModuleType("pxr.Usdviewq.plugin")
    module.PluginContainer = PluginContainer
    package.plugin = module
    sys.modules["pxr.Usdviewq"] = package
    sys.modules["pxr.Usdviewq.plugin"] = module
