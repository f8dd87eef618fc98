"""Thresholds of cleaning and extraction, with Heck's defaults (5.2.2.1-5.2.2.2)."""

from __future__ import annotations

import math

from dataclasses import asdict, dataclass

from usdgaze.errors import UsdGazeError


class SettingsError(UsdGazeError):
    """A threshold is out of range."""


@dataclass(frozen=True)
class BuildSettings:
    """Every tunable of ``build-map``. Lengths are in mm and converted to each file's units."""

    rest_speed_mm_s: float = 6.0
    """V: a frame is still when the mean marker speed is below this (Heck: 6 mm/s)."""
    rest_merge_s: float = 1.0 / 6.0
    """Rests separated by less than this merge into one (Heck: 1/6 s)."""
    min_rest_s: float = 0.25
    """Shorter still periods are not rests (not in the paper: the overshoot peak is a brief stop)."""
    speed_span_s: float = 0.15
    """Half-span of the central differences behind the marker speeds (not in the paper, see cleaning)."""
    velocity_k: int = 3
    """k: head and joint velocities difference frames i-k and i+k (Heck: tunable, no value given)."""
    peak_window_m: int = 6
    """m: frames averaged either side of an overshoot candidate (Heck: tunable, no value given)."""
    pose_window_s: float = 0.05
    """First and last poses are the mean of the still frames this long ending at the crop's ends
    (0: single frames, as the paper; a short mean keeps marker jitter out of P+)."""
    start_speed_deg_s: float = 18.0
    """A joint starts moving at the first frame its local angular speed exceeds this (Heck: 18 deg/s)."""
    start_hold_s: float = 0.05
    """The speed must stay above the start threshold this long (not in the paper: one jittery frame is
    not a start); the crossing is the first of those frames."""
    start_refine: bool = True
    """Move each detected start back to the model's t_j (not in the paper). The quintic ease-in leaves
    t_j at zero speed, so the threshold crossing comes 2-10 frames after it. The segment's angle from
    its first pose is fitted (least squares) with the model's rise ``A * ease((t - t_j) / (t_end - t_j))``,
    A its largest angle (the overshoot peak) and t_end searched between the detection and that peak;
    t_j is kept within [0, detection]. The report keeps both the crossing and the start.
    False: the start is the paper's bare threshold crossing."""
    start_fit_fraction: float = 0.9
    """That fit runs from the crop's first frame to where the angle first reaches this fraction of A."""
    min_trials: int = 3
    """Fewest good trials a map is built from."""
    rate_tolerance: float = 2e-3
    """Relative frame-rate difference still counted as the same rate (USD's 120.0048 vs 120; an NTSC
    capture's 59.94 or 60000/1001 beside 60, 0.1% apart). Each trial is timed by its own rate."""

    def __post_init__(self) -> None:
        checks = (
            ("rest_speed_mm_s", self.rest_speed_mm_s > 0),
            ("rest_merge_s", self.rest_merge_s >= 0),
            ("min_rest_s", self.min_rest_s >= 0),
            ("speed_span_s", self.speed_span_s > 0),
            ("velocity_k", self.velocity_k >= 1),
            ("peak_window_m", self.peak_window_m >= 1),
            ("pose_window_s", self.pose_window_s >= 0),
            ("start_speed_deg_s", self.start_speed_deg_s > 0),
            ("start_hold_s", self.start_hold_s >= 0),
            ("start_fit_fraction", 0 < self.start_fit_fraction <= 1),
            ("min_trials", self.min_trials >= 1),
        )
        for name, ok in checks:
            value = getattr(self, name)
            if not ok or (isinstance(value, float) and not math.isfinite(value)):
                raise SettingsError(f"build setting {name} = {getattr(self, name)} is out of range")

    def as_dict(self) -> dict:
        return asdict(self)
