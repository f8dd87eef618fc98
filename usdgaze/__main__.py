"""``python -m usdgaze``: the same CLI as the ``usdgaze`` console script."""

import sys

from .cli import main

sys.exit(main())
