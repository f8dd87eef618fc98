"""The ``NAME_physics`` review figure of a layer ``attend --physics`` wrote: the simulated shot's
per-step measures against time, each against the bar the pass judges it by, with the times the
shot's problems name marked.

:func:`physics_panels` builds what is drawn (display units, pure numpy); :func:`physics_figure`
draws it on matplotlib (whose pyplot the caller passes: :func:`usdgaze.review.plotting.pyplot`).
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field

import numpy as np

from usdgaze.review.physics_record import PhysicsMeasures

CURVE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b")
"""Curves, in order within a panel (no red: red marks the problems)."""
PROBLEM_COLOUR = "#d62728"
LIMIT_COLOUR = "0.2"
_TASK_TERMS = {  # per-step key's ending -> (the panel's kind, the curve's label)
    ".stoneDistanceM": ("stones", "toe to its stone"),
    ".clearanceM": ("obstacles", "clearance"),
    ".handToBallM": ("catch", "hand to the ball"),
}
_TASK_TITLES = {"stones": "each foot's toe to its stone across the ground, while down",
                "obstacles": "the smallest distance from the body to a sphere",
                "catch": "the catching hand to the ball"}


@dataclass
class Curve:
    """One drawn series: its label, values in the panel's unit ``(K,)`` and line style."""

    label: str
    values: np.ndarray
    style: str = "-"


@dataclass
class PhysicsPanel:
    """One panel: a measure (or a task's) against seconds, and the bar it is judged by."""

    key: str
    """What it shows: ``pelvis``, ``joints``, ``feet``, ``heading``, ``drift`` or a task's prefix."""
    title: str
    ylabel: str
    curves: list[Curve] = field(default_factory=list)
    limit: float | None = None
    limit_label: str = ""


def _bars() -> dict[str, float]:
    """The pass's own bars (imported here: the review does not need the physics modules to load)."""
    from usdgaze.passes.physics_report import FOOT_TOLERANCE_M, HEADING_TOLERANCE_DEG, STONE_TOLERANCE_M
    from usdgaze.passes.visuomotor import CATCH_TOLERANCE_M
    from usdgaze.physics.mpc import FALL_RATIO

    return {"fall": FALL_RATIO, "foot": FOOT_TOLERANCE_M, "heading": HEADING_TOLERANCE_DEG,
            "stones": STONE_TOLERANCE_M, "obstacles": 0.0, "catch": CATCH_TOLERANCE_M}


def _body_panels(m: PhysicsMeasures, bars: dict[str, float]) -> list[PhysicsPanel]:
    """The whole-body measures every simulated shot records (those the layer holds)."""
    f = m.frames
    out = []

    def add(key, title, ylabel, curves, limit=None, limit_label=""):
        curves = [Curve(label, scale * f[name], style) for name, label, scale, style in curves if name in f]
        if curves:
            out.append(PhysicsPanel(key, title, ylabel, curves, limit, limit_label))

    add("pelvis", "pelvis height (% of the reference's)", "%", [("pelvisRatio", "pelvis height", 100.0, "-")],
        100.0 * bars["fall"], f"fall: below {bars['fall']:.0%}")
    add("joints", "joint error against the reference, mean over the joints (deg)", "deg",
        [("jointErrorDeg", "mean joint error", 1.0, "-")])
    add("feet", "lowest foot below the ground (cm): as written, and as the soft contact let it sink", "cm",
        [("footBelowGroundM", "written foot", 100.0, "-"),
         ("contactDepthM", "simulation's soft contact", 100.0, "--")],
        100.0 * bars["foot"], f"a problem: deeper than {100 * bars['foot']:g} cm")
    add("heading", "heading error: turned about the vertical from the reference (deg)", "deg",
        [("headingErrorDeg", "heading error", 1.0, "-")],
        bars["heading"], f"a problem: over {bars['heading']:g} deg")
    add("drift", "root drift: the root's distance from the reference's across the ground (cm)", "cm",
        [("rootDriftM", "root drift", 100.0, "-")])
    return out


def _task_panels(m: PhysicsMeasures, bars: dict[str, float]) -> list[PhysicsPanel]:
    """A panel per task the shot had (``stones``, ``obstacles``, ``catch``, ``catch2``, ...) with its
    measured distance in cm; the planner's own terms (``proximity``, ``weight``, ``arrivalS``,
    ``handToArrivalM``) are left out."""
    panels: dict[str, PhysicsPanel] = {}
    for key, values in m.frames.items():
        ending = next((e for e in _TASK_TERMS if key.endswith(e)), None)
        if ending is None or not key[: -len(ending)]:
            continue
        prefix = key.split(".", 1)[0]
        kind, label = _TASK_TERMS[ending]
        middle = key[len(prefix) + 1: -len(ending)]
        bar = bars[kind]
        said = {"stones": f"a miss: over {100 * bar:g} cm on average over a contact",
                "obstacles": "a touch: below 0", "catch": f"a miss: never within {100 * bar:g} cm"}[kind]
        title = f"task {prefix}: {_TASK_TITLES[kind]} (cm)"
        panel = panels.setdefault(prefix, PhysicsPanel(prefix, title, "cm", [], 100.0 * bar, said))
        panel.curves.append(Curve(f"{middle} {label}" if middle else label, 100.0 * values))
    return list(panels.values())


def physics_panels(m: PhysicsMeasures) -> list[PhysicsPanel]:
    """What the physics figure draws, in order: pelvis, joints, feet, heading, drift, then each task."""
    bars = _bars()
    return _body_panels(m, bars) + _task_panels(m, bars)


def _mark_problems(ax, spans: list[tuple[float, float]]) -> None:
    """Each time a problem names as a dotted red line, each span as a red band (one legend entry)."""
    for k, (a, b) in enumerate(spans):
        label = "a problem's time" if k == 0 else None
        if b > a:
            ax.axvspan(a, b, color=PROBLEM_COLOUR, alpha=0.15, lw=0, zorder=0, label=label)
        else:
            ax.axvline(a, color=PROBLEM_COLOUR, lw=1.0, ls=":", zorder=0, label=label)


def _title(name: str, problems: list[str]) -> str:
    said = "; ".join(problems) if problems else "none"
    return "\n".join(textwrap.wrap(f"{name}: the simulated shot (attend --physics); problems (red): {said}", 130))


def physics_figure(plt, m: PhysicsMeasures, name: str):
    """One panel per measure against seconds from the stage start, bars dashed, problems in red
    (None where the record holds no measure this draws)."""
    panels = physics_panels(m)
    if not panels:
        return None
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 1.2 + 2.1 * len(panels)), sharex=True, squeeze=False)
    for ax, panel in zip(axes[:, 0], panels):
        for i, curve in enumerate(panel.curves):
            ax.plot(m.seconds, curve.values, curve.style, color=CURVE_COLOURS[i % len(CURVE_COLOURS)], lw=1.4,
                    label=curve.label)
        if panel.limit is not None:
            ax.axhline(panel.limit, color=LIMIT_COLOUR, lw=1.0, ls=(0, (6, 4)), label=panel.limit_label)
        _mark_problems(ax, m.problem_times)
        ax.set_title(panel.title, fontsize=9)
        ax.set_ylabel(panel.ylabel, fontsize=8)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)
    last = axes[-1, 0]
    last.set_xlim(float(m.seconds[0]), float(m.seconds[-1]) if len(m.seconds) > 1 else float(m.seconds[0]) + 1.0)
    last.set_xlabel("seconds from the stage start")
    fig.suptitle(_title(name, m.problems), fontsize=9)
    return fig
