"""``build-map``: a manual crop too short to measure a shift in (fewer than 2k + 1 frames, the span of
the angular-velocity differences) fails its trial instead of entering the map as a still example.

Before, a 2-frame crop of a 108 deg trial was reported "ok" (the head turned 0.00 deg in it) and gave
the map an example at (108, 12) with no displacement and a 1/60 s duration: a 108 deg request then
moved no joint. Measured here on the written map file, read back with USD (GazeMapAPI attributes)."""

from __future__ import annotations

import numpy as np
from pxr import Usd

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import ingest_synth as syn

TARGETS = np.array([[108.0, 12.0], [-144.0, 0.0], [36.0, -12.0]])


def _examples(path) -> list[tuple[float, float]]:
    stage = Usd.Stage.Open(str(path))
    prim = next(p for p in stage.TraverseAll() if p.HasAPI("GazeMapAPI"))
    yaw, pitch = (list(prim.GetAttribute(f"gaze:examples:{k}").Get()) for k in ("yaw", "pitch"))
    return sorted(zip(map(float, yaw), map(float, pitch)))


def test_a_two_frame_manual_crop_fails_its_trial(tmp_path, capsys):
    motions = syn.known_motions(TARGETS)
    rows = []
    for i, (yaw, pitch) in enumerate(TARGETS):
        m = motions[i]
        frames = 40 + int(round((float(m.duration) + 0.8) * syn.RATE))
        syn.write_skel_clip(tmp_path / f"t{i}.usda", m, 40, frames)
        crop = "crop = [40, 41]\n" if i == 0 else ""
        rows.append(f'[[trial]]\nname = "t{i}"\nfile = "t{i}.usda"\nyaw = {yaw:g}\npitch = {pitch:g}\n{crop}')
    (tmp_path / "sheet.toml").write_text("\n".join(rows))
    out = tmp_path / "map.usda"
    assert main(["build-map", str(tmp_path / "sheet.toml"), "--out", str(out), "--min-trials", "2"]) == 0
    printed = capsys.readouterr().out
    assert "trial t0 (t0.usda): the crop 40-41 holds 2 frame(s)" in printed
    assert _examples(out) == sorted((float(y), float(p)) for y, p in TARGETS[1:])
