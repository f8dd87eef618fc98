"""A shot cut from a longer take by its stage's playback range: the planner's windows near the shot's
end see the take go on, so the simulated walk keeps walking through its last frame instead of
braking to the last pose held (measured by UsdSkel FK on the written layer)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


def _shot(d: Path, start_s: float, end_s: float) -> tuple[Path, Sdf.Layer]:
    """A root layer over the whole CMU walk whose playback range is ``start_s``-``end_s``."""
    take = Sdf.Layer.FindOrOpen(str(CMU))
    tcps = take.timeCodesPerSecond
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    shot.subLayerPaths[:] = [str(CMU)]
    shot.startTimeCode = take.startTimeCode + round(start_s * tcps)
    shot.endTimeCode = take.startTimeCode + round(end_s * tcps)
    shot.timeCodesPerSecond = shot.framesPerSecond = tcps
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    shot.Save()
    return d / "shot.usda", shot


def _root_path(path: Path, shot: Sdf.Layer) -> np.ndarray:
    """World position of the skeleton's first joint at every time code of the shot."""
    stage = Usd.Stage.Open(str(path))
    skel = next(UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    query = UsdSkel.Cache().GetSkelQuery(skel)
    codes = np.arange(shot.startTimeCode, shot.endTimeCode + 1)
    return np.array([np.array(query.ComputeJointWorldTransforms(UsdGeom.XformCache(Usd.TimeCode(t)))[0])[3, :3]
                     for t in codes])


def test_a_walk_cut_from_its_take_walks_through_its_last_frame(tmp_path):
    src, shot = _shot(tmp_path, 5.0, 5.6)
    out = tmp_path / "body.usdc"
    report = physics_pass.run(src, out, mpc.Options(h=0.03, retry_iterations=0))[0]
    assert report.fell_at_s is None
    view = Sdf.Layer.CreateNew(str(tmp_path / "view.usda"))
    view.subLayerPaths[:] = [str(out), str(src)]
    view.timeCodesPerSecond = view.framesPerSecond = shot.timeCodesPerSecond
    view.Save()
    simulated, reference = _root_path(tmp_path / "view.usda", shot), _root_path(src, shot)
    assert not np.array_equal(simulated, reference)  # the layer moves the body

    n = int(round(0.15 * shot.timeCodesPerSecond))
    seconds = n / shot.timeCodesPerSecond
    speed = lambda p: np.linalg.norm((p[-1] - p[-1 - n])[[0, 2]]) / seconds  # noqa: E731 (Y up)
    # Held to its last pose, the planner braked: 0.905 m/s against the take's 1.271 over the last
    # 0.15 s, 9.1 cm behind it at the end; seeing the take go on, 1.306 m/s and 2.8 cm.
    assert abs(speed(simulated) / speed(reference) - 1.0) < 0.12, (speed(simulated), speed(reference))
    assert np.linalg.norm((simulated[-1] - reference[-1])[[0, 2]]) < 0.05
