"""The ``usdgaze`` command line, one module per command."""
