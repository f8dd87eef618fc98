"""Review plots of a gaze pass (matplotlib, an optional extra: ``pip install 'usdgaze[plot]'``).

Every panel function draws arrays into a matplotlib ``Axes``; :func:`figures` lays them out from a
:class:`~usdgaze.review.composed.Review` (what ``usdgaze plot`` writes, one PNG per figure) and
:func:`plot_report` stacks the main ones into the single file of ``apply --plot``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from usdgaze.core.names import unique
from usdgaze.errors import UsdGazeError
from usdgaze.review import analysis

JOINT_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22")
ROLE_COLOURS = ("#8c564b", "#9467bd", "#2ca02c", "#1f77b4", "#d62728", "#e377c2")
"""Cascade curves: pelvis, lower spine, upper spine, neck, head, eye (tests find the curves by these)."""
YAW_COLOUR, PITCH_COLOUR = "#1f77b4", "#ff7f0e"
_FORMATS = {".png", ".pdf", ".svg"}


def pyplot():
    """matplotlib's pyplot on the headless Agg backend, or a one-line error."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsdGazeError("plotting needs matplotlib: pip install 'usdgaze[plot]'") from None
    return plt


def check_plot_path(path: str | os.PathLike, flag: str = "--plot"):
    """matplotlib's pyplot if ``path`` can be drawn to, else a one-line error naming ``flag`` (call
    before any work)."""
    path = Path(path)
    if path.suffix.lower() not in _FORMATS:
        raise UsdGazeError(f"{flag} {path}: must end in .png, .pdf or .svg")
    if not path.parent.is_dir():
        raise UsdGazeError(f"{path}: folder {path.parent} does not exist")
    try:
        return pyplot()
    except UsdGazeError:
        raise UsdGazeError(f"{path}: plotting needs matplotlib: pip install 'usdgaze[plot]'") from None


# -- panels (arrays in, drawing out) ----------------------------------------------------------------

def panel_cascade(ax, elapsed: np.ndarray, angles: np.ndarray, labels: list[str], title: str) -> None:
    """Each joint's angle turned since a shift began (Heck Fig. 5.2: cascade, overshoot, settle)."""
    roles: dict[str, int] = {}
    for i, label in enumerate(labels):
        role = label.split(" (")[0]
        k = roles.setdefault(role, len(roles))
        nth = sum(1 for other in labels[:i] if other.split(" (")[0] == role)
        # Joints sharing a role turn alike: same colour, a dash pattern each so none hides another.
        ax.plot(elapsed, angles[:, i], color=ROLE_COLOURS[k % len(ROLE_COLOURS)], lw=1.8 - 0.4 * nth,
                ls=("-", "--", ":", "-.")[nth % 4], label=label)
    ax.set_xlim(0.0, float(elapsed[-1]) if len(elapsed) else 1.0)
    ax.set_ylim(0.0, max(1.0, float(np.nanmax(angles)) * 1.1) if angles.size else 1.0)
    ax.set_title(title)
    ax.set_xlabel("seconds since the shift began")
    ax.set_ylabel("joint rotation since then (deg)")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)


def panel_gaze(ax, seconds, requested, achieved, shift_times, name: str) -> None:
    """Requested (steps) against achieved (by FK) change of the line of sight of character ``name``.
    Without shifts (an attend layer, look-at directives alone) nothing was requested as a change: the
    achieved change alone (a dashed "requested 0" made the planner's glances read as errors)."""
    for i, (axis, colour) in enumerate((("yaw", YAW_COLOUR), ("pitch", PITCH_COLOUR))):
        if len(shift_times):
            ax.plot(seconds, requested[:, i], "--", color=colour, lw=1, label=f"{axis} requested")
        ax.plot(seconds, achieved[:, i], color=colour, lw=1.6, label=f"{axis} achieved (FK)")
    for t in shift_times:
        ax.axvline(t, color="0.85", lw=0.8, zorder=0)
    ax.set_title(f"{name}: requested vs achieved change of the line of sight" if len(shift_times) else
                 f"{name}: change of the line of sight against the base (no shifts requested)")
    ax.set_ylabel("change of the line of sight (deg)")
    ax.set_xlabel("seconds from the stage start")
    ax.legend(loc="best", fontsize=7)


def panel_eyes(ax, seconds, eye_angles, limits: dict[str, float], recorded: bool, title: str) -> None:
    """Eye-in-head yaw and pitch of both eyes, against the limits the pass used."""
    styles = (("left", "-"), ("right", ":"))
    for e, (side, ls) in enumerate(styles):
        ax.plot(seconds, eye_angles[:, e, 0], ls, color=YAW_COLOUR, lw=1.2, label=f"{side} eye yaw")
        ax.plot(seconds, eye_angles[:, e, 1], ls, color=PITCH_COLOUR, lw=1.2, label=f"{side} eye pitch")
    # NaN where the character is scaled to nothing (hidden): a shot of only such frames has no angle.
    seen = eye_angles[np.isfinite(eye_angles)]
    low = min(-limits["yaw"], -limits["down"], float(seen.min()) if seen.size else 0.0)
    high = max(limits["yaw"], limits["up"], float(seen.max()) if seen.size else 0.0)
    ax.set_ylim(low - 5.0, high + 5.0)
    where = "as the pass recorded" if recorded else "defaults: the layer does not record them"
    for value, name, colour in ((limits["yaw"], "yaw limit", YAW_COLOUR), (-limits["yaw"], None, YAW_COLOUR),
                                (limits["up"], "up limit", PITCH_COLOUR), (-limits["down"], "down limit", PITCH_COLOUR)):
        ax.axhline(value, color=colour, lw=1.0, ls=(0, (6, 4)), label=name)
    ax.set_title(f"{title} (dashed: eye range, {where})")
    ax.set_ylabel("eye in head (deg)")
    ax.set_xlabel("seconds from the stage start")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)


def panel_speed(ax, seconds, speed, change_speed, shift_times, title: str) -> None:
    """Line-of-sight speed in space, and of the gaze change against the base motion."""
    ax.plot(seconds, speed, color="#999999", lw=1.0, label="line of sight in space")
    ax.plot(seconds, change_speed, color="#d62728", lw=1.4, label="gaze change against the base")
    ax.legend(loc="upper right", fontsize=7)
    for t in shift_times:
        ax.axvline(t, color="0.85", lw=0.8, zorder=0)
    ax.set_title(title)
    ax.set_ylabel("line-of-sight speed (deg/s)")
    ax.set_xlabel("seconds from the stage start")


def panel_main_sequence(ax, peaks: np.ndarray, title: str) -> None:
    """Per shift, the peak speed of the gaze change against the saccade main sequence."""
    top = max(90.0, float(peaks[:, 0].max()) * 1.1) if len(peaks) else 90.0
    a = np.linspace(0.0, top, 200)
    ax.plot(a, analysis.main_sequence(a), color="0.4", lw=1.2,
            label=f"main sequence {analysis.MAIN_SEQUENCE_VMAX:g}(1-exp(-A/{analysis.MAIN_SEQUENCE_C:g}))")
    if len(peaks):
        ax.plot(peaks[:, 0], peaks[:, 1], "o", color="#d62728", label="shifts (peak speed)")
    ax.set_xlim(0.0, top)
    ax.set_title(title)
    ax.set_xlabel("amplitude (deg)")
    ax.set_ylabel("peak speed (deg/s)")
    ax.legend(loc="lower right", fontsize=7)


def panel_target_error(ax, seconds, errors: dict[str, np.ndarray], title: str) -> None:
    """Angle between the line of sight and the direction to each look-at target (deg)."""
    for i, (name, err) in enumerate(errors.items()):
        ax.plot(seconds, err, color=JOINT_COLOURS[i % len(JOINT_COLOURS)], lw=1.4, label=name)
    if len(seconds) > 1:  # one frame (a held pose, a one-frame shot): matplotlib's own limits, not its warning
        ax.set_xlim(float(seconds[0]), float(seconds[-1]))
    ax.set_ylim(bottom=0.0)
    ax.set_title(title)
    ax.set_ylabel("target error (deg)")
    ax.set_xlabel("seconds from the stage start")
    ax.legend(loc="best", fontsize=7)


def panel_attention(ax_top, ax_bottom, seconds, point_of_sight: np.ndarray, objects: dict[str, np.ndarray],
                    uncertainty: dict[str, np.ndarray], title: str) -> None:
    """Eom Fig. 4: which object the point of sight is on, and each object's uncertainty, over time.

    ``point_of_sight`` ``(F, 3)``; ``objects`` name -> positions ``(F, 3)``; ``uncertainty`` name ->
    ``(F,)`` (e.g. the trace of the estimate's position covariance).
    """
    names = list(objects)
    dist = np.stack([np.linalg.norm(point_of_sight - objects[n], axis=-1) for n in names], axis=1)
    nearest = np.argmin(dist, axis=1)
    for i, name in enumerate(names):
        colour = JOINT_COLOURS[i % len(JOINT_COLOURS)]
        on = np.where(nearest == i, i, np.nan)
        ax_top.plot(seconds, on, color=colour, lw=6, solid_capstyle="butt")
        ax_bottom.plot(seconds, uncertainty[name], color=colour, lw=1.4, label=name)
    ax_top.set_yticks(range(len(names)), names)
    ax_top.set_ylim(-0.5, len(names) - 0.5)
    ax_top.set_title(f"{title}: object nearest the point of sight")
    ax_bottom.set_ylabel("uncertainty")
    ax_bottom.set_xlabel("seconds from the stage start")
    ax_bottom.legend(loc="best", fontsize=7)


# -- figures ---------------------------------------------------------------------------------------

def names(review) -> list[str]:
    """A file-name-safe name per character: the SkelRoot's name, or its whole path where names repeat,
    or its Skeleton's path where one SkelRoot holds several skeletons (each its own character); a
    name that still repeats (``/a_b`` and ``/a/b``) gets ``_2``, ``_3``: no character's plots overwrite
    another's."""
    def safe(path: str) -> str:
        return path.strip("/").replace("/", "_") or "character"

    leaves = [c.skel_root.rsplit("/", 1)[-1] or "character" for c in review.characters]
    if len(set(leaves)) == len(leaves):
        return leaves
    full = [safe(c.skel_root) for c in review.characters]
    full = [safe(c.skeleton) if full.count(n) > 1 else n for c, n in zip(review.characters, full)]
    taken: set[str] = set()
    return [unique(n, taken) for n in full]


def attention_names(review) -> list[str]:
    """A name per attend inspection scope of ``review``, for its ``NAME_attention`` file: its character's
    (the SkelRoot it records; attend plans a SkelRoot's first skeleton, so that one's name), else,
    for a layer whose scopes record none, the one character whose path spells the scope's name, else
    the scope's name, made unique. /A_B and /A/B both spell ``A_B``: the scope's name alone gave one
    character's attention the other's name, and a third's file overwrote a second's."""
    from usdgaze.usd.attendio import scope_name

    by_root: dict[str, str] = {}
    for c, n in zip(review.characters, names(review)):
        by_root.setdefault(c.skel_root, n)
    spelled: dict[str, set[str]] = {}
    for root, n in by_root.items():
        spelled.setdefault(scope_name(root), set()).add(n)
    taken, claimed, out = set(by_root.values()), set(), []
    for a in review.attention:
        if a.character is not None:
            own = by_root.get(a.character)
        else:  # an older layer: the scope's name, where exactly one character spells it
            own = next(iter(spelled[a.name])) if len(spelled.get(a.name, ())) == 1 else None
        if own is not None and own not in claimed:
            claimed.add(own)
            out.append(own)
        else:  # no character of this review: a name no character's files use
            out.append(unique(a.name, taken))
    return out


def shift_lines(c) -> list[float]:
    """The times of ``c``'s requests that lie on its frames: a vertical line at one outside them (a
    shift before a shot's range) had stretched the time axis past the frames drawn."""
    lo, hi = (float(c.seconds[0]), float(c.seconds[-1])) if len(c.seconds) else (np.inf, -np.inf)
    return [t for t, _, _ in c.shifts if lo - 1e-9 <= t <= hi + 1e-9]


def _character_figures(plt, review, c, name: str) -> dict[str, object]:
    """One character's figures by file stem: its cascades, gaze, eyes, speed and targets (where it has
    eyes: a physics pass writes none for a rig without them), and its physics measures (where the
    layer records them)."""
    out = {}
    times = shift_lines(c)
    cascades = analysis.shift_cascade(c, c.shifts)
    if cascades:
        fig, axes = plt.subplots(len(cascades), 1, figsize=(10, 3.2 * len(cascades)), squeeze=False)
        for ax, s in zip(axes[:, 0], cascades):
            panel_cascade(ax, s.elapsed, s.angles, s.labels,
                          f"{name}: shift {s.index + 1} at {s.time_s:g} s to yaw {s.yaw:g}, pitch {s.pitch:g}")
        out[f"{name}_cascade"] = fig
    if c.eyes is not None:
        fig, ax = plt.subplots(figsize=(9, 3.6))
        panel_gaze(ax, c.seconds, analysis.requested_steps(c.seconds, c.shifts), analysis.achieved_change(c),
                   times, name)
        out[f"{name}_gaze"] = fig
        fig, ax = plt.subplots(figsize=(10, 3.6))
        panel_eyes(ax, c.seconds, analysis.eye_in_head(c), review.eye_range, review.eye_range_recorded,
                   f"{name}: eye in head")
        out[f"{name}_eyes"] = fig
        change = analysis.change_speed(c)
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw={"width_ratios": (2, 1)})
        panel_speed(a1, c.seconds, analysis.sight_speed(c), change, times, f"{name}: line-of-sight speed")
        panel_main_sequence(a2, analysis.peak_speeds(c, c.shifts, change), "peak per shift vs the main sequence")
        out[f"{name}_speed"] = fig
        errors = analysis.target_errors(c)
        if errors:
            fig, ax = plt.subplots(figsize=(10, 3.6))
            panel_target_error(ax, c.seconds, errors, f"{name}: look-at target error")
            out[f"{name}_targets"] = fig
    if c.physics is not None:
        from usdgaze.review.physics_plots import physics_figure

        fig = physics_figure(plt, c.physics, name)
        if fig is not None:
            out[f"{name}_physics"] = fig
    return out


def figures(review) -> dict[str, object]:
    """Every review figure, by file stem (``<character>_<kind>``), as matplotlib Figures."""
    plt = pyplot()
    out = {}
    for c, name in zip(review.characters, names(review)):
        out.update(_character_figures(plt, review, c, name))
    for a, name in zip(review.attention, attention_names(review)):
        fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 5), sharex=True,
                                          gridspec_kw={"height_ratios": (1, 2)})
        panel_attention(top, bottom, a.seconds, a.point_of_sight, a.objects, a.uncertainty, name)
        out[f"{name}_attention"] = fig
    for fig in out.values():
        _mark_lone_points(fig)
        fig.tight_layout()
        if fig._suptitle is not None:  # tight_layout set it flush on the first panel's title: a line apart
            fig.subplots_adjust(top=fig.subplotpars.top - 0.2 / fig.get_figheight())
    return out


def _mark_lone_points(fig) -> None:
    """A curve of one sample (a one-frame clip) is a line of no length, which matplotlib does not
    draw: it gets a dot, so a still pose's gaze and eye angles show."""
    for ax in fig.axes:
        for line in ax.get_lines():
            if len(line.get_xdata()) == 1 and line.get_marker() in ("None", "", None):
                line.set_marker("o")
                line.set_markersize(5)


_NO_DATE = {"pdf": {"CreationDate": None}, "svg": {"Date": None}}
"""matplotlib stamps PDF and SVG files with the time they were written: the same run must give the same bytes."""


def save_figure(fig, path: str | os.PathLike, outputs, dpi: int = 100) -> None:
    """Stage ``fig`` through the command's writer and close it (the same figure, the same bytes)."""
    plt = pyplot()
    fmt = Path(path).suffix.lstrip(".").lower()
    try:
        # SVG's clip-path ids are random unless salted.
        with plt.rc_context({"svg.hashsalt": "usdgaze"}):
            outputs.stage_with(path, lambda temp: fig.savefig(temp, dpi=dpi, format=fmt, metadata=_NO_DATE.get(fmt)))
    finally:
        plt.close(fig)


def write_plots(review, out_dir: str | os.PathLike, outputs, fmt: str = "png") -> list[Path]:
    """Write every figure of ``review`` into ``out_dir`` (claimed, staged; the caller commits)."""
    written = []
    drawn = figures(review)
    try:
        for stem, fig in drawn.items():
            path = Path(out_dir) / f"{stem}.{fmt}"
            outputs.claim(path, "--out", follow=False)
            save_figure(fig, path, outputs)
            written.append(path)
    finally:  # a refused path leaves no figure open in a process that goes on (a batch worker)
        for fig in drawn.values():
            pyplot().close(fig)
    return written


def summary_figure(review):
    """One stacked figure per character: requested vs achieved, the first shift's cascade, eye angles."""
    plt = pyplot()
    chars = review.characters
    fig, axes = plt.subplots(3 * len(chars), 1, figsize=(10, 9.5 * len(chars)), squeeze=False)
    for n, (c, name) in enumerate(zip(chars, names(review))):
        panel_gaze(axes[3 * n, 0], c.seconds, analysis.requested_steps(c.seconds, c.shifts), analysis.achieved_change(c),
                   shift_lines(c), name)
        cascades = analysis.shift_cascade(c, c.shifts)
        if cascades:
            s = cascades[0]
            panel_cascade(axes[3 * n + 1, 0], s.elapsed, s.angles, s.labels,
                          f"shift 1 at {s.time_s:g} s: per-joint rotation (cascade, overshoot, settle)")
        panel_eyes(axes[3 * n + 2, 0], c.seconds, analysis.eye_in_head(c), review.eye_range,
                   review.eye_range_recorded, "eye in head")
    _mark_lone_points(fig)
    fig.tight_layout()
    return fig


def plot_report(report, path: str | os.PathLike, outputs=None, layer=None) -> None:
    """``apply --plot``: the summary figure of what ``report`` wrote, read back from the composed result.

    ``layer`` is the override as an ``Sdf.Layer`` when it is staged but not yet on disk (apply draws
    before its transaction commits); else ``report.output`` is read.
    """
    from usdgaze.files.transaction import outputs_of
    from usdgaze.review.composed import read_review

    check_plot_path(path)
    review = read_review(report.input, layer if layer is not None else report.output, playback=True)
    with outputs_of(outputs) as tx:
        if not tx.claimed(path):
            tx.claim(path, "--plot")
        save_figure(summary_figure(review), path, tx, dpi=110)
