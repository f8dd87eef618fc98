"""The farm batch entry on the shipped manifest shape: real sample stages, real layers."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from pxr import Sdf

from . import measure

ROOT = Path(__file__).resolve().parents[1]


def _manifest(tmp_path: Path, body: str) -> Path:
    shutil.copytree(ROOT / "sample_stages" / "cmu", tmp_path / "cmu")
    path = tmp_path / "jobs" / "manifest.toml"
    path.parent.mkdir()
    path.write_text(body)
    return path


def _batch(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "pipeline" / "batch.py"), *args],
                          capture_output=True, text=True, timeout=300)


def test_batch_runs_every_job_and_reports_each(tmp_path):
    manifest = _manifest(tmp_path, """
[defaults]
shifts = ["2s:60:0", "5s:0:0"]

[[job]]
name = "good"
input = "../cmu/cmu_131_01.usdc"
out = "out/good.usdc"
preview = "out/good_preview.usda"

[[job]]
name = "bad"
input = "../cmu/missing.usdc"
out = "out/bad.usdc"
""")
    before = measure.sha256(tmp_path / "cmu" / "cmu_131_01.usdc")
    proc = _batch(str(manifest), "--workers", "2", "--report", str(tmp_path / "report.json"))
    assert proc.returncode == 2, proc.stderr  # one bad job: bad-input exit code, the good one still ran
    records = {r["name"]: r for r in json.loads((tmp_path / "report.json").read_text())}
    assert records["good"]["exit_code"] == 0 and records["bad"]["exit_code"] == 2
    assert "missing.usdc" in records["bad"]["message"] and "\n" not in records["bad"]["message"]
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "jobs" / "out" / "good.usdc"))
    assert list(layer.customLayerData["usdgaze"]["shifts"]) == ["2s:60:0", "5s:0:0"]
    assert not (tmp_path / "jobs" / "out" / "bad.usdc").exists()
    assert measure.sha256(tmp_path / "cmu" / "cmu_131_01.usdc") == before


def test_task_index_runs_one_job_for_farm_arrays(tmp_path):
    manifest = _manifest(tmp_path, """
[[job]]
input = "../cmu/cmu_131_01.usdc"
out = "a.usdc"
shifts = ["2s:30:0"]

[[job]]
input = "../cmu/cmu_131_02.usdc"
out = "b.usdc"
shifts = ["2s:-30:0"]
""")
    proc = _batch(str(manifest), "--task-index", "1")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "jobs" / "b.usdc").exists() and not (tmp_path / "jobs" / "a.usdc").exists()
    proc = _batch(str(manifest), "--task-index", "5")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1


def test_bad_manifest_is_one_line(tmp_path):
    manifest = _manifest(tmp_path, '[[job]]\ninput = "x.usdc"\nout = "y.usdc"\nshifts = ["1:2:3"]\ncolour = "red"\n')
    proc = _batch(str(manifest))
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "colour" in proc.stderr
