"""``plot`` and ``preview`` of an ``attend --physics`` layer made on a shot cut from a longer take by
its stage's playback range: the pass writes only the range's frames (docs/physics.md, "The shot's
range"), and the review draws those frames. Both commands had refused every such layer as made for
another take (exit 2), the shipped ``stepping_stones_shot.usda`` included.

The layer comes from the real pass: CMU 131_01's 2.0-2.3 s at h 0.03, simulated once (~3 s); what
the review poses is checked against UsdSkel's own FK of the shot with and without the layer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from usdgaze.console.main import main
from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc
from usdgaze.review.composed import read_review

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


def _shot(path: Path, start_s: float, end_s: float) -> Sdf.Layer:
    """A root layer over the whole CMU take whose playback range is ``start_s``-``end_s``."""
    take = Sdf.Layer.FindOrOpen(str(CMU))
    tcps = take.timeCodesPerSecond
    shot = Sdf.Layer.CreateNew(str(path))
    shot.subLayerPaths[:] = [str(CMU)]
    shot.startTimeCode = take.startTimeCode + round(start_s * tcps)
    shot.endTimeCode = take.startTimeCode + round(end_s * tcps)
    shot.timeCodesPerSecond = shot.framesPerSecond = tcps
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    shot.Save()
    return shot


def _joint_positions(root_layer: str, codes: np.ndarray) -> np.ndarray:
    """World position of every joint at each time code, by UsdSkel's FK: ``(F, J, 3)``."""
    stage = Usd.Stage.Open(root_layer)
    skel = next(UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    query = UsdSkel.Cache().GetSkelQuery(skel)
    return np.array([[np.array(m)[3, :3] for m in query.ComputeJointWorldTransforms(UsdGeom.XformCache(Usd.TimeCode(t)))]
                     for t in codes])


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    folder = tmp_path_factory.mktemp("physics_shot_review")
    layer = _shot(folder / "shot.usda", 2.0, 2.3)
    out = folder / "body.usdc"
    physics_pass.run(folder / "shot.usda", out, mpc.Options(h=0.03, retry_iterations=0))
    return folder, layer, out


def test_plot_and_preview_draw_a_physics_layer_made_on_a_shot_range(shot, tmp_path, capsys):
    folder, layer, out = shot
    src = str(folder / "shot.usda")
    samples = Sdf.Layer.FindOrOpen(str(out)).ListTimeSamplesForPath("/root/Body/BodySkel/scaled_131_01.rotations")
    assert (samples[0], samples[-1]) == (layer.startTimeCode, layer.endTimeCode)  # the range only, not the take
    assert main(["plot", src, "--layer", str(out), "--out", str(tmp_path / "p")]) == 0
    assert "Body_physics.png" in [p.name for p in (tmp_path / "p").iterdir()]
    assert main(["preview", src, "--layer", str(out), "--out", str(tmp_path / "sheet.png")]) == 0
    assert (tmp_path / "sheet.png").stat().st_size > 10_000
    assert "error" not in capsys.readouterr().err


def test_the_review_poses_the_shot_range_as_usdskel_does(shot):
    folder, layer, out = shot
    src = str(folder / "shot.usda")
    codes = np.arange(layer.startTimeCode, layer.endTimeCode + 1)
    view = Sdf.Layer.CreateNew(str(folder / "view.usda"))
    view.subLayerPaths[:] = [str(out), src]
    view.timeCodesPerSecond = view.framesPerSecond = layer.timeCodesPerSecond
    view.Save()
    character = read_review(src, str(out)).characters[0]
    # Seconds from the shot's start (the stage's), one per time code of its range.
    assert np.allclose(character.seconds, (codes - layer.startTimeCode) / layer.timeCodesPerSecond, rtol=0, atol=1e-9)
    base, gaze = _joint_positions(src, codes), _joint_positions(str(folder / "view.usda"), codes)
    assert np.abs(character.base.positions - base).max() < 1e-4
    assert np.abs(character.gaze.positions - gaze).max() < 1e-4
    assert np.abs(gaze - base).max() > 0.01  # the simulated body is not the reference


def test_a_physics_layer_over_another_range_is_still_refused(shot, tmp_path, capsys):
    folder, layer, out = shot
    _shot(tmp_path / "other.usda", 2.0, 2.5)
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "other.usda"), "--layer", str(out), "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "review it over the input it was made for" in err[0], err
