"""Write gaze_map.usda, the map that crowd.usda shares between its characters.

Run from anywhere: ``python sample_stages/shared_map/make_map.py``. The output is deterministic,
so re-running it on an unchanged checkout leaves gaze_map.usda byte for byte as committed.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
try:
    import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage exists)
except ModuleNotFoundError:  # source checkout without `pip install -e .`
    sys.path.insert(0, str(HERE.parents[1]))

from usdgaze.usd import plugin as _plugin  # noqa: E402

_plugin.register()

from usdgaze.gaze.defaults import default_definition  # noqa: E402
from usdgaze.usd.schema import dump_map  # noqa: E402


def main() -> None:
    definition = default_definition()
    dump_map(
        definition,
        HERE / "gaze_map.usda",
        custom_layer_data={"usdgaze": {"madeBy": "sample_stages/shared_map/make_map.py"}},
    )


if __name__ == "__main__":
    main()
