"""Review plots of a gaze pass (matplotlib, an optional extra: ``pip install 'usdgaze[plot]'``)."""

from __future__ import annotations

import os
from pathlib import Path

from usdgaze.errors import UsdGazeError
from usdgaze.files.transaction import Outputs, outputs_of
from usdgaze.gaze.motion import SEGMENTS


def check_plot_path(path: str | os.PathLike):
    """matplotlib's pyplot if ``path`` can be drawn to, else a one-line error (call before any work)."""
    path = Path(path)
    if path.suffix.lower() not in {".png", ".pdf", ".svg"}:
        raise UsdGazeError(f"{path}: plot must end in .png, .pdf or .svg")
    if not path.parent.is_dir():
        raise UsdGazeError(f"{path}: folder {path.parent} does not exist")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsdGazeError(f"{path}: plotting needs matplotlib: pip install 'usdgaze[plot]'") from None
    return plt


def plot_report(report, path: str | os.PathLike, outputs: Outputs | None = None) -> None:
    """One figure per character, stacked: wanted vs achieved gaze change, segment angles, eye angles."""
    plt = check_plot_path(path)
    fig = _figure(plt, report)
    try:
        with outputs_of(outputs) as tx:
            if not tx.claimed(path):
                tx.claim(path, "--plot")
            # The format follows the temporary's suffix, which is the target's.
            tx.stage_with(path, lambda temp: fig.savefig(temp, dpi=110))
    finally:
        plt.close(fig)


def _figure(plt, report):
    chars = report.characters
    fig, axes = plt.subplots(3 * len(chars), 1, figsize=(10, 7.5 * len(chars)), sharex=False, squeeze=False)
    for n, c in enumerate(chars):
        r = c.result
        t = r.seconds
        ax = axes[3 * n, 0]
        for i, (name, colour) in enumerate((("yaw", "tab:blue"), ("pitch", "tab:orange"))):
            ax.plot(t, r.requested[:, i], "--", color=colour, lw=1, label=f"{name} wanted")
            ax.plot(t, r.achieved[:, i], color=colour, lw=1.5, label=f"{name} achieved (FK)")
        for s in r.shift_timing:
            ax.axvline(s["time_s"], color="0.8", lw=0.8)
        ax.set_title(f"{c.skel_root}: change of the line of sight against the base motion")
        ax.set_ylabel("deg")
        ax.legend(loc="best", fontsize=8)
        ax = axes[3 * n + 1, 0]
        for i, seg in enumerate(SEGMENTS):
            ax.plot(t, r.segment_angles[:, i], lw=1.2, label=seg)
        ax.set_title("model displacement per segment (cascade, overshoot, settle)")
        ax.set_ylabel("deg")
        ax.legend(loc="best", fontsize=8)
        ax = axes[3 * n + 2, 0]
        for e, side in enumerate(("left", "right")):
            ax.plot(t, r.eye_angles[:, e, 0], lw=1, label=f"{side} eye yaw")
            ax.plot(t, r.eye_angles[:, e, 1], lw=1, label=f"{side} eye pitch")
        for limit in (44.2, -44.2, 27.7, -47.1):
            ax.axhline(limit, color="0.7", lw=0.6, ls=":")
        ax.set_title("eye in head (dotted: eye range)")
        ax.set_ylabel("deg")
        ax.set_xlabel("seconds from the stage start")
        ax.legend(loc="best", fontsize=8, ncol=2)
    fig.tight_layout()
    return fig
