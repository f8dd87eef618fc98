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


def shot_over_take(d: Path, start_s: float, end_s: float) -> tuple[Path, Sdf.Layer]:
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
    shot.defaultPrim = take.defaultPrim
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
    src, shot = shot_over_take(tmp_path, 5.0, 5.6)
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


def test_the_layer_over_the_take_gives_back_what_the_input_shows_outside_the_range():
    """``through_take`` on an override of frames 3-6 of a 10-frame take: the range keeps the written
    frames; outside it an animated joint has the take's values, a joint the animation does not list
    its rest (a rest matrix made here from a known turn), and an added eye its nearest written frame."""
    from types import SimpleNamespace

    from scipy.spatial.transform import Rotation

    from usdgaze.passes.take import through_take
    from usdgaze.usd.layers import AnimOverride

    rng = np.random.default_rng(3)
    f = 10
    rest_turn = Rotation.from_euler("xyz", [10, 20, 30], degrees=True)
    rest = np.tile(np.eye(4), (2, 1, 1))
    rest[1, :3, :3], rest[1, :3, 3] = rest_turn.as_matrix(), [0.1, 0.2, 0.3]
    take = SimpleNamespace(times=np.arange(f, dtype=float) + 100.0, anim_joints=["a"], joints=["a", "a/b"],
                           rotations=rng.normal(size=(f, 1, 4)).astype(np.float32),
                           translations=rng.normal(size=(f, 1, 3)).astype(np.float32), rest_local=rest)
    shot = SimpleNamespace(times=take.times[3:7])
    written = AnimOverride(animation="/A", times=shot.times, joints=["a", "a/b", "a/b/eye"],
                           rotations=rng.normal(size=(4, 3, 4)).astype(np.float32),
                           translations=rng.normal(size=(4, 3, 3)).astype(np.float32))
    out = through_take(written, take, shot)
    assert np.array_equal(out.times, take.times)
    outside = np.r_[0:3, 7:f]
    for name in ("rotations", "translations"):
        got, mine, given = getattr(out, name), getattr(written, name), getattr(take, name)
        assert got.shape == (f, 3, mine.shape[2]) and got.dtype == np.float32
        assert np.array_equal(got[3:7], mine)
        assert np.array_equal(got[outside, 0], given[outside, 0])  # the take's own bits
        assert np.array_equal(got[0:3, 2], np.repeat(mine[:1, 2], 3, 0))  # the eye: nearest written
        assert np.array_equal(got[7:, 2], np.repeat(mine[-1:, 2], 3, 0))
    q = out.rotations[outside, 1].astype(float)
    assert np.allclose(np.abs(q @ rest_turn.as_quat()), 1.0, atol=1e-6)  # x, y, z, w; either sign
    assert np.allclose(out.translations[outside, 1], [0.1, 0.2, 0.3], atol=1e-7)
    assert out.scales is None
