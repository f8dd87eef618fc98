"""``python -m usdgaze``: the same CLI as the ``usdgaze`` console script."""

import sys

from usdgaze.console.main import main

sys.exit(main(hold=True))
