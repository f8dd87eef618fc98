"""usdgaze: realistic gaze shifts layered onto UsdSkel animation as a non-destructive override."""

__version__ = "0.1.0"
