"""The review plot: a real PNG from a real pass, and one-line errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from usdgaze import api
from usdgaze.errors import UsdGazeError
from usdgaze.review.plotting import plot_report

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


def test_plot_writes_a_png(tmp_path):
    report = api.apply(CMU, ["2s:60:0", "5s:0:0"], tmp_path / "g.usdc")
    plot_report(report, tmp_path / "g.png")
    data = (tmp_path / "g.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temp left behind


def test_plot_rejects_unknown_extension(tmp_path):
    report = api.apply(CMU, ["2s:60:0"], tmp_path / "g.usdc")
    with pytest.raises(UsdGazeError, match=r"--plot .*g.gif: must end in"):
        plot_report(report, tmp_path / "g.gif")


def test_plot_problems_are_found_before_anything_is_written(tmp_path):
    from usdgaze.console.main import main

    out = tmp_path / "g.usdc"
    code = main(["apply", str(CMU), "--shift", "2s:60:0", "--out", str(out), "--plot", str(tmp_path / "g.gif")])
    assert code == 2 and not out.exists()
