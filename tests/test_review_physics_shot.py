"""``plot`` and ``preview`` of an ``attend --physics`` layer made on a shot cut from a longer take by
its stage's playback range: the pass simulates the range and writes the take's own samples outside
it (docs/physics.md, "The shot's range"). Both commands had refused the layers of the range alone
as made for another take (exit 2), the shipped ``stepping_stones_shot.usda``'s included, and
composed over the take such a layer froze the character before and after the range.

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

from .test_physics_take import shot_over_take

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


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
    _, layer = shot_over_take(folder, 2.0, 2.3)
    out = folder / "body.usdc"
    physics_pass.run(folder / "shot.usda", out, mpc.Options(h=0.03, retry_iterations=0))
    return folder, layer, out


def test_plot_and_preview_draw_a_physics_layer_made_on_a_shot_range(shot, tmp_path, capsys):
    folder, layer, out = shot
    src = str(folder / "shot.usda")
    path = "/root/Body/BodySkel/scaled_131_01.rotations"
    samples = Sdf.Layer.FindOrOpen(str(out)).ListTimeSamplesForPath(path)
    assert samples == Sdf.Layer.FindOrOpen(str(CMU)).ListTimeSamplesForPath(path)  # the take's, not the range's
    assert main(["plot", src, "--layer", str(out), "--out", str(tmp_path / "p")]) == 0
    assert "Body_physics.png" in [p.name for p in (tmp_path / "p").iterdir()]
    assert main(["preview", src, "--layer", str(out), "--out", str(tmp_path / "sheet.png")]) == 0
    assert (tmp_path / "sheet.png").stat().st_size > 10_000
    assert "error" not in capsys.readouterr().err


def test_the_review_poses_the_take_as_usdskel_does_and_only_the_range_moves(shot):
    folder, layer, out = shot
    src = str(folder / "shot.usda")
    codes = np.array(Sdf.Layer.FindOrOpen(str(out)).ListTimeSamplesForPath("/root/Body/BodySkel/scaled_131_01.rotations"))
    view = Sdf.Layer.CreateNew(str(folder / "view.usda"))
    view.subLayerPaths[:] = [str(out), src]
    view.timeCodesPerSecond = view.framesPerSecond = layer.timeCodesPerSecond
    view.Save()
    character = read_review(src, str(out)).characters[0]
    # Seconds from the shot's start (the stage's), one per sample of the take (which the layer holds,
    # the test above).
    assert np.allclose(character.seconds, (codes - layer.startTimeCode) / layer.timeCodesPerSecond, rtol=0, atol=1e-9)
    base, gaze = _joint_positions(src, codes), _joint_positions(str(folder / "view.usda"), codes)
    assert np.abs(character.base.positions - base).max() < 1e-4
    assert np.abs(character.gaze.positions - gaze).max() < 1e-4
    inside = (codes > layer.startTimeCode) & (codes <= layer.endTimeCode)
    assert np.abs(gaze[inside] - base[inside]).max() > 0.01  # the simulated body is not the reference
    outside = codes != np.clip(codes, layer.startTimeCode, layer.endTimeCode)
    assert outside.sum() > 10 * inside.sum() and np.abs(gaze[outside] - base[outside]).max() < 1e-6  # the take's


def test_validate_checks_a_physics_layer_against_the_take_it_was_made_for(shot, tmp_path, capsys):
    """A physics layer records its characters, so ``validate --layer`` checks it as it checks apply's:
    clean over its own shot; over a take cut shorter (its first 2.5 s), another take."""
    from .test_physics_pass import excerpt

    folder, layer, out = shot
    assert main(["validate", str(folder / "shot.usda"), "--layer", str(out)]) == 0
    short = excerpt(tmp_path / "short.usda", 2.5)
    capsys.readouterr()
    assert main(["validate", str(short), "--layer", str(out)]) == 3
    found = capsys.readouterr().out.strip().splitlines()
    assert len(found) == 1 and "OtherTake" in found[0] and "the input below it" in found[0], found
