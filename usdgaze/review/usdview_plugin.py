"""usdview's Gaze menu: a ``PluginContainer`` that usdview finds through the plugInfo.json of
usdgaze's schema plugin (``PXR_PLUGINPATH_NAME=$(usdgaze plugin-path)``). Only usdview imports this
module; the commands themselves live in :mod:`usdgaze.review.usdview` and take usdview's API object."""

from pxr import Tf
from pxr.Usdviewq.plugin import PluginContainer

from usdgaze.review import usdview

MENU = "Gaze"
COMMANDS = (
    ("toggleGazeLayer", "Toggle Gaze Layer (mute/unmute)", usdview.toggle_gaze_layer),
    ("selectChainJoints", "Select Gaze Chain Joints", usdview.select_chain_joints),
    ("showLinesOfSight", "Show/Hide Lines of Sight", usdview.show_lines_of_sight),
    ("printSummary", "Print Map and Schedule", usdview.summary),
)


class GazePluginContainer(PluginContainer):
    """Registers the Gaze menu's commands and lays out the menu."""

    def registerPlugins(self, plugRegistry, usdviewApi):
        self._commands = [
            plugRegistry.registerCommandPlugin(f"GazePluginContainer.{key}", label, function)
            for key, label, function in COMMANDS
        ]

    def configureView(self, plugRegistry, plugUIBuilder):
        menu = plugUIBuilder.findOrCreateMenu(MENU)
        for command in self._commands:
            menu.addItem(command)


Tf.Type.Define(GazePluginContainer)
