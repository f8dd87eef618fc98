"""Kept for old farm scripts: ``python pipeline/batch.py ARGS`` is ``usdgaze batch ARGS``."""

import sys


def main(argv: list[str] | None = None) -> int:
    from usdgaze.console.main import main as usdgaze

    return usdgaze(["batch", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
