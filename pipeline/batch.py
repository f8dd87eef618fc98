"""Kept for old farm scripts: ``python pipeline/batch.py ARGS`` is ``usdgaze batch ARGS``."""

import sys

from usdgaze.console.main import main

if __name__ == "__main__":
    sys.exit(main(["batch", *sys.argv[1:]]))
