"""The planner options a shot of ``attend --physics`` is simulated with: the window and the step a user
chose for every shot, else the paper's by task (a shot with stepping stones, with a ball to catch or
moving obstacles), and their checks (no pxr)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from usdgaze.errors import UsdGazeError
from usdgaze.physics import mpc


def check_window(options: mpc.Options, label: str) -> None:
    """The planner windows must hold two steps and stay under 5 s; ``label`` names where they were set."""
    h = max(options.h, options.moving_h or 0.0)  # the longest step a shot may get
    for window in (options.horizon_s, options.stones_horizon_s):
        if window is not None and not (np.isfinite(window) and 2 * h - 1e-9 <= window <= 5.0):
            raise UsdGazeError(f"{label} {window:g} s: expected {2 * h:g} to 5 s (the paper uses 0.6-1.2 s)")


def with_window(options: mpc.Options, window_s: float | None) -> mpc.Options:
    """``options`` with the window a user chose (``--window``, a manifest's ``window``) for every shot,
    stones or not; None: the defaults, the window by task (``mpc.Options.stones_horizon_s``)."""
    return options if window_s is None else replace(options, horizon_s=window_s, stones_horizon_s=None)


def with_timestep(options: mpc.Options, timestep: float | None) -> mpc.Options:
    """``options`` with the step a user chose (``--timestep``, a manifest's ``timestep``) for every shot;
    None: the defaults, the step by task (``mpc.Options.moving_h``)."""
    return options if timestep is None else replace(options, h=timestep, moving_h=None)


def shot_options(options: mpc.Options, prims: dict[str, list], catches: bool = False) -> mpc.Options:
    """The options one shot is simulated with: a shot with stepping stones (``task_prims``) gets their
    window; one without them but with a ball to catch (``catches``) or moving obstacles, their step."""
    if prims["stone"]:
        return options if options.stones_horizon_s is None else replace(options, horizon_s=options.stones_horizon_s)
    if (catches or prims["obstacle"]) and options.moving_h is not None:
        return replace(options, h=options.moving_h)
    return options
