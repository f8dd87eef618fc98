"""usdgaze: realistic gaze shifts layered onto UsdSkel animation as a non-destructive override."""

# First, so that a Ctrl-C while the command starts is its one line, not a traceback (only in the CLI).
from usdgaze.files.signals import quiet_stops_while_starting as _quiet_stops

_quiet_stops()

# The schema registry is built once, the first time anything asks it about a schema: the plugin
# must be registered before any other usdgaze (or user) code opens a stage.
from usdgaze.usd import plugin as _plugin

_plugin.register()

__version__ = "0.1.0"
