"""The look pass's directives in time: which body shifts, eye epochs and gaze-weight keys they make.

A look's body shifts come from :class:`~usdgaze.passes.body.TargetPlanner`; a shift or a release is
one body shift; a fading release keeps the previous behaviour while the weight falls, then cuts to
the base. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from usdgaze.gaze import motion
from usdgaze.passes.body import TargetPlanner
from usdgaze.passes.options import EyeRange, Shift
from usdgaze.passes.schedule import Scheduler

if TYPE_CHECKING:
    from usdgaze.passes.look import LookOptions

KINDS = ("shift", "look", "release")


@dataclass(frozen=True)
class Directive:
    """From ``time_s`` on: change the gaze by (yaw, pitch) (shift), look at target ``target`` (look),
    or return to the base motion's gaze (release); the gaze weight eases to ``weight`` over ``blend_s``.

    A release with ``blend_s > 0`` fades the weight to 0 instead of making a gaze shift.
    """

    time_s: float
    kind: str
    yaw: float = 0.0
    pitch: float = 0.0
    target: int = -1
    weight: float = 1.0
    blend_s: float = 0.0


@dataclass
class Epoch:
    """A stretch of frames under one directive, and what the eyes do in it."""

    start: int
    directive: Directive
    events: list  # (frame, "target" | "direction" | "base", cut)


def gaze_weights(directives: list[Directive], seconds: np.ndarray, base_shown: np.ndarray | None = None) -> np.ndarray:
    """Gaze weight per frame: each key eases from the weight at its time to its own over its blend.

    ``base_shown`` (per frame): where the animation shows the base motion's own gaze, whatever the
    weight; a look or shift that starts there eases in from 0 (from the weight left there, 1 before
    any key, a half-weight look with a blend had swung 95% of the way to its goal and back to 50%).
    """
    w = np.ones(len(seconds))
    for d in directives:
        rows = seconds >= d.time_s
        if not np.any(rows):
            continue
        first = int(np.argmax(rows))
        from_base = base_shown is not None and d.kind != "release" and (first == 0 or base_shown[first - 1])
        w0 = 0.0 if from_base else w[first]
        s = motion.ease((seconds[rows] - d.time_s) / d.blend_s) if d.blend_s > 0 else np.ones(int(rows.sum()))
        w[rows] = w0 + (d.weight - w0) * s
    return w


def plan_directives(gaze_map, directives: list[Directive], seconds: np.ndarray, rel: dict[int, np.ndarray],
                    base_ae: np.ndarray, limits: EyeRange, opts: LookOptions, scheduler: Scheduler
                    ) -> tuple[list[Shift], list[Epoch], list[Directive]]:
    """Body shifts, eye epochs and weight keys for the directives (sorted by time); ``scheduler``
    schedules the shifts as the planners add them."""
    shifts: list[Shift] = []
    epochs: list[Epoch] = []
    keys: list[Directive] = []
    # A fading release keeps the previous behaviour while the weight falls, then cuts to the base.
    timeline = []
    for d in directives:
        if d.kind == "release" and d.blend_s > 0:
            keys.append(Directive(d.time_s, "release", weight=0.0, blend_s=d.blend_s))
            keys.append(Directive(d.time_s + d.blend_s, "release", weight=1.0))
            timeline.append((d.time_s + d.blend_s, d, True))
        elif d.kind == "release":
            # A release is a gaze shift from what is shown back to the base: it keeps the weight it
            # finds (a partial look's gaze had jumped to the full one on its first frame and back).
            held = float(gaze_weights(keys, np.array([d.time_s]))[0])
            keys.append(Directive(d.time_s, "release", weight=held))
            timeline.append((d.time_s, d, False))
        else:
            keys.append(d)
            timeline.append((d.time_s, d, False))
    timeline.sort(key=lambda e: e[0])
    starts = [int(np.searchsorted(seconds, t)) for t, _, _ in timeline]
    for k, ((t, d, cut), a) in enumerate(zip(timeline, starts)):
        end = starts[k + 1] if k + 1 < len(starts) else len(seconds)
        epoch = Epoch(a, d, [])
        epochs.append(epoch)
        if a >= len(seconds):
            continue
        if d.kind == "look":
            TargetPlanner(gaze_map, shifts, epoch.events, seconds, rel[d.target], base_ae, limits, opts,
                          scheduler).run(epoch.start, end)
            continue
        yaw, pitch = (d.yaw, d.pitch) if d.kind == "shift" else (0.0, 0.0)
        # Past half a turn plus the eye range the eyes aim at that reach (look._goals): a body turned
        # further would carry the head past their goal and the eyes back across the head.
        yaw = float(np.clip(yaw, -180.0 - limits.yaw, 180.0 + limits.yaw))
        shifts.append(Shift(float(t), yaw, pitch, cut=cut))
        epoch.events.append((a, "direction" if d.kind == "shift" else "base", cut))
    return shifts, epochs, keys

