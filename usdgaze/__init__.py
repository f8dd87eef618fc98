"""usdgaze: realistic gaze shifts layered onto UsdSkel animation as a non-destructive override."""

# The schema registry is built once, the first time anything asks it about a schema: the plugin
# must be registered before any other usdgaze (or user) code opens a stage.
from usdgaze.usd import plugin as _plugin

_plugin.register()

__version__ = "0.1.0"
