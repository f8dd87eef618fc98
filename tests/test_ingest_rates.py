"""build-map at capture rates above 60 Hz: k and m count frames, so at 240 Hz they span a quarter of
the time they span at 60 Hz, and the head's still frames at the crop's start (float32 coordinates,
a tenth of a millimetre of jitter, as the vendor files in tests/data/c3d have) flip the sign of its
velocity there. The overshoot peak is still the one the known motion has (ground truth from
tests/ingest_synth.py, never the pipeline's output)."""

from __future__ import annotations

import numpy as np

from . import ingest_synth as syn
from usdgaze.ingest.build import build


def test_overshoot_peak_at_240_hz_is_the_known_one(tmp_path):
    rate = 240.0
    params = np.array([[-144.0, 0.0], [-72.0, 0.0], [72.0, 0.0], [108.0, 0.0], [180.0, 0.0]])
    motions = syn.known_motions(params)
    rng = np.random.default_rng(4)
    trials = []
    for i, (yaw, pitch) in enumerate(params):
        points, onset = syn.simulate_trial(motions[i], rng, rate=rate, noise=0.2 * syn.NOISE_MM)
        tr = syn.TrialTruth(syn.trial_name(yaw, pitch), float(yaw), float(pitch), motions[i], onset, len(points), rate)
        tr.file = tmp_path / f"{tr.name}.c3d"
        syn.write_points(tr.file, syn.LABELS, points, rate)
        trials.append(tr)
    syn.write_sheet(tmp_path / "sheet.csv", trials)
    (tmp_path / "markers.toml").write_text(syn.MARKERSET_TOML)
    result = build(tmp_path / "sheet.csv", tmp_path / "markers.toml")
    for truth, report in zip(trials, result.reports):
        ex = report.extraction
        assert ex is not None and ex.peak_frame is not None, (truth.name, report.error, report.warnings)
        late = (report.crop[0] + ex.peak_frame - truth.peak_frame) / rate
        assert abs(late) < 0.03, (truth.name, late)  # 0.6-0.8 s early (at the onset) before
        assert abs(ex.timing[6] - float(np.ravel(truth.motion.timing)[6])) < 0.01, (truth.name, ex.timing[6])
