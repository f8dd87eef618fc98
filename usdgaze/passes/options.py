"""What the gaze passes are asked and give back: shifts, options (eye range included), results."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from usdgaze.core.hints import BindHints


@dataclass(frozen=True)
class Shift:
    """A gaze request: at ``time_s`` seconds (from the stage start), change the gaze by (yaw, pitch) deg."""

    time_s: float
    yaw: float
    pitch: float
    cut: bool = False
    """Reach the request at once (used where the change is invisible, e.g. at zero gaze weight)."""
    timing_change: tuple[float, float] | None = None
    """Gaze change whose timing the shift takes (default: the change of request). A shift that holds
    a target while the base motion swings moves the head little in the world, whatever its request."""
    min_duration_s: float = 0.0
    """Lower bound on the shift's duration (keeps the displacement's own speed bounded)."""


@dataclass(frozen=True)
class EyeRange:
    """Eye-in-head limits in degrees (Eom et al. 2019: abduction/adduction 44.2, elevation 27.7,
    depression 47.1)."""

    yaw: float = 44.2
    up: float = 27.7
    down: float = 47.1


@dataclass(frozen=True)
class PassOptions:
    fixation_m: float = 2.0
    """Distance of the point of sight along the line of sight, in metres."""
    eye_range: EyeRange = EyeRange()
    interocular_m: float = 0.063
    """Spacing of added eyes (mean adult interpupillary distance ~63 mm)."""
    eye_above_head_m: float = 0.07
    """Added eyes sit this far above the head joint (skull base) ..."""
    eye_ahead_of_head_m: float = 0.09
    """... and this far in front of it, for a ~1.5 m head-joint height."""
    tolerance_deg: float = 0.5
    """Hold-phase error above which a request is reported as out of reach."""
    binding: BindHints = BindHints()
    """Role bindings and forward given by the user (``--bind``, ``--forward``); they win over the map's."""


@dataclass
class PassResult:
    """New animation arrays plus what a reviewer wants to see."""

    anim_joints: list[str]
    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    added_joints: list[str] = field(default_factory=list)
    added_rest_local: np.ndarray | None = None
    added_bind_world: np.ndarray | None = None
    changed_joints: list[str] = field(default_factory=list)
    requested: np.ndarray | None = None
    """Wanted change of the line of sight per frame ``(F, 2)`` (deg)."""
    achieved: np.ndarray | None = None
    """Achieved change per frame by FK ``(F, 2)``."""
    eye_angles: np.ndarray | None = None
    """Eye-in-head (yaw, pitch) per frame and eye ``(F, 2, 2)``."""
    settled: np.ndarray | None = None
    """Frames in a hold phase (a shift finished, no new one begun)."""
    seconds: np.ndarray | None = None
    """Sample times in seconds from the stage start."""
    shift_timing: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    eye_positions: np.ndarray | None = None
    """World position of each eye per frame ``(2, F, 3)`` (left first)."""
    point_of_sight: np.ndarray | None = None
    """World point the eyes fixate per frame ``(F, 3)``."""

    def reviewed(self) -> "PassResult":
        """This result without its animation arrays (``None``), for a report kept once they are
        written: a crowd's float64 arrays then need not all be held until the layer is."""
        return replace(self, rotations=None, translations=None, scales=None,
                       added_rest_local=None, added_bind_world=None)
