"""The data of a gaze map, independent of storage: examples, joint-role bindings, synthesis settings."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .motion import GazeMotions

ROLES = ("pelvis", "lowerSpine", "upperSpine", "neck", "head", "leftEye", "rightEye")
"""Joint roles a map can bind. ``neck`` and ``head`` together carry the P+ neck segment."""


@dataclass(frozen=True)
class SynthesisSettings:
    """Kovar & Gleicher blending-based synthesis settings (stored as ``gaze:synthesis:*``)."""

    samples: int = 20000
    """Random blends drawn to sample the (yaw, pitch) space densely."""
    blend_size: int = 6
    """How many nearby examples one random blend mixes."""
    neighbors: int = 8
    """k of the k-nearest-neighbour interpolation of blend weights at query time."""
    refine: int = 3
    """Fixed-point corrections of a query against its measured gaze change on the canonical chain."""
    seed: int = 0
    """Seed of the random blends, so that a map always builds the same way."""
    neck_share: float = 0.5
    """Outside the sampled region: share of the missing rotation taken by the neck (the eyes take the rest)."""


@dataclass(frozen=True)
class GazeMapDefinition:
    """A parametric gaze map's source data.

    ``params`` ``(E, 2)``: each example's (yaw, pitch) gaze change in degrees, yaw positive toward the
    character's left, never wrapped (-180 and +180 are a right and a left turn).
    ``motions``: the E gaze displacement motions, in the same order.
    ``bindings``: role -> skeleton joint paths; empty or missing roles are found by name.
    """

    params: np.ndarray
    motions: GazeMotions
    settings: SynthesisSettings = field(default_factory=SynthesisSettings)
    bindings: dict[str, tuple[str, ...]] = field(default_factory=dict)
    forward: tuple[float, float, float] | None = None
    """Character forward in skeleton space, or None to work it out from the rest pose."""

    def __post_init__(self) -> None:
        params = np.asarray(self.params, dtype=float).reshape(-1, 2)
        object.__setattr__(self, "params", params)
        if len(self.motions) != len(params) or self.motions.offsets.ndim != 3:
            raise ValueError(f"{len(params)} example parameters but {len(self.motions)} motions")

    def __len__(self) -> int:
        return len(self.params)
