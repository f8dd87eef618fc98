"""Write gaze_map.usda, the map that crowd.usda shares between its characters.

Run from anywhere: ``python sample_stages/shared_map/make_map.py``. The output is deterministic,
so re-running it on an unchanged checkout leaves gaze_map.usda byte for byte as committed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
try:
    import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage exists)
except ModuleNotFoundError:  # source checkout without `pip install -e .`
    sys.path.insert(0, str(HERE.parents[1]))

from usdgaze import _plugin  # noqa: E402

_plugin.register()

from usdgaze import motion  # noqa: E402
from usdgaze import rotations as rot  # noqa: E402
from usdgaze.definition import GazeMapDefinition  # noqa: E402
from usdgaze.schema import dump_map  # noqa: E402


def tiny_definition() -> GazeMapDefinition:
    """Three examples (look left, right, up) with a plausible eye-head-trunk split; a stand-in."""
    params = np.array([[40.0, 0.0], [-40.0, 0.0], [0.0, 20.0]])
    shares = np.array([0.0, 0.05, 0.1, 0.45])  # pelvis, lower spine, upper spine, neck of the change
    body = rot.yaw_pitch_rotation(params[:, None, 0] * shares, params[:, None, 1] * shares)
    eyes = motion.aim_eyes(body, params[:, 0], params[:, 1])
    offsets = np.concatenate([body, eyes[:, None, :]], axis=1)
    amplitude = np.hypot(params[:, 0], params[:, 1])
    # duration, pelvis/lowerSpine/upperSpine/neck starts, overshoot time, overshoot
    timing = np.column_stack(
        [0.25 + 0.004 * amplitude]
        + [np.full(len(params), v) for v in (0.3, 0.25, 0.2, 0.1, 0.6, 0.1)]
    )
    return GazeMapDefinition(params, motion.GazeMotions(offsets, timing))


def main() -> None:
    definition = tiny_definition()
    dump_map(
        definition,
        HERE / "gaze_map.usda",
        custom_layer_data={"usdgaze": {"madeBy": "sample_stages/shared_map/make_map.py"}},
    )


if __name__ == "__main__":
    main()
