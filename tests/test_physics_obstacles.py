"""Moving obstacles of the second seed (section 7) on the MuJoCo body: spheres coming at the walker
from ahead near the reference's own position and time (tests/obstacle_stages.py), measured against
the written body's bones (joint to parent joint, 8 cm thick) by UsdSkel forward kinematics; the
obstacle cost's derivatives, in both its forms, against central differences."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import mpc, obstacles

from . import measure
from .attend_support import compose, positions
from .differences import central, rel
from .obstacle_stages import RADIUS_M, gaps, obstacle_scene

SKEL = "/root/Body/BodySkel"
OPTIONS = mpc.Options(h=0.03, horizon_s=0.6)  # the window these figures are of
OBSTACLE_SEED = 6  # spheres from ahead (obstacle_stages.crossing): the reference walks 24 cm into one


def _first_estimate(layer: Sdf.Layer, obj: str) -> float:
    """The first time code at which the written inspection prims hold an estimate of ``obj``."""
    for char in layer.GetPrimAtPath("/UsdGazeAttend").nameChildren:
        for child in char.nameChildren:
            if child.attributes["gaze:attend:object"].default == obj:
                est = child.attributes["gaze:attend:estimate"].path
                return next(t for t in layer.ListTimeSamplesForPath(est)
                            if np.all(np.isfinite(layer.QueryTimeSample(est, t))))
    raise AssertionError(f"no inspection prim for {obj}")


def test_approaching_obstacles_the_reference_walks_into_are_seen_and_not_touched(tmp_path):
    """One of the five seeded runs of the bar (docs/physics.md: no contact in the 5 approaching
    scenes): with the eyes and belief coupled and the cost on the body's capsules, two spheres coming
    at the walker from ahead, both of which the reference walks into (24 and 9 cm deep). The shallower
    one starts 66 deg off the head's forward, 1.2 m away: only its edge (asin(0.25 / 1.2) = 12 deg) is
    in the field of view, and it is tracked from the first frame (the written inspection prims, the
    angle by UsdSkel FK of the written head; as a point it was never seen before it touched,
    docs/physics.md). The simulated body, by UsdSkel FK on the written layer, clears both (by 6.0 cm
    when measured), does not fall, and the report agrees."""
    src, prims = obstacle_scene(tmp_path, OBSTACLE_SEED, toward=True)
    ref = measure.posed(str(src), SKEL)
    assert gaps(ref, src, prims, RADIUS_M).min() < -0.2  # the reference walks into one
    out = tmp_path / "avoided.usda"
    report = physics_pass.run(src, out, OPTIONS)[0]
    composed = compose(tmp_path, src, out)
    posed = measure.posed(str(composed), SKEL)
    after = gaps(posed, composed, prims, RADIUS_M)
    assert after.min() > 0 and not report.fell, (after.min(), report.problems)
    layer = Sdf.Layer.FindOrOpen(str(out))
    frames = layer.customLayerData["usdgaze:physics"][SKEL]["frames"]
    assert max(frames["obstacles.proximity"][1:]) > 0.1  # the belief saw them coming
    touched = min(frames["obstacles.clearanceM"][1:]) < 0
    assert touched == any("touched an obstacle" in p for p in report.problems)
    # ... and says the smallest gap, met or not, near the FK's (the model's capsules against the bones')
    (said,) = [t for t in report.tasks if t.startswith("obstacles:")]
    assert "(touched)" not in said and float(said.split("obstacle ")[1].split(" cm")[0]) > 0, said
    # At the first frame, by UsdSkel FK of the written head: the sphere farthest off its forward has
    # its centre outside +-60 deg and its edge inside; both are tracked from that frame on.
    fwd = measure.character_forward_skel(posed, "LeftHip", "RightHip")
    head_fwd = posed.axis("Head", measure.local_forward(posed, "Head", fwd))[0]
    eyes = 0.5 * (posed.position("LeftEye")[0] + posed.position("RightEye")[0])
    stage = Usd.Stage.Open(str(composed))
    to = np.array([positions(stage, p, posed.times[:1])[0] for p in prims]) - eyes
    dist = np.linalg.norm(to, axis=1)
    off = np.degrees(np.arccos(to @ head_fwd / dist))
    edge = np.degrees(np.arcsin(RADIUS_M / dist))
    assert 63 < off.max() and np.all(off - edge < 60), (off, edge)
    assert all(_first_estimate(layer, p) == posed.times[0] for p in prims)


@pytest.mark.parametrize("form", ["body", "root"])
def test_obstacle_cost_derivatives_match_central_differences(stone_walk, form):
    """Both forms (ours on every capsule, the paper's on the root), six obstacles (the four nearest
    kept), running and terminal (with the extrapolated sub-window: position and velocity)."""
    dyn, ref_q, _ = stone_walk
    rng = np.random.default_rng(1)
    t = 0.03 * np.arange(len(ref_q))
    centres = ref_q[:, None, :3] + rng.normal(0, 0.4, (1, 6, 3)) + np.outer(t, [0.8, -0.3, 0])[:, None]
    centres[:, :, 2] = np.abs(centres[:, :, 2])  # above the ground, at the body's height
    task = obstacles.ObstacleTask(dyn, centres, np.full(6, 0.25), form=form)
    for k in (3, 30):
        x = dyn.to_state(ref_q[k], rng.normal(0, 0.5, dyn.nv))
        u = np.zeros(dyn.nu)
        lx, _, lxx, _, _ = task.derivs(x, u, k)
        assert task.l(x, u, k) > 0.05
        assert rel(lx, central(lambda z: task.l(z, u, k), x)) <= 1e-4
        tx, txx = task.terminal_derivs(x, k)
        assert np.abs(tx[dyn.nv:dyn.nv + 2]).max() > 0
        assert rel(tx, central(lambda z: task.terminal(z, k), x)) <= 1e-4
        assert np.all(np.linalg.eigvalsh(lxx) > -1e-9) and np.all(np.linalg.eigvalsh(txx) > -1e-9)
        if form == "root":
            p = x[:2].copy()
            assert rel(task.exact_hessian(p, k), central(lambda z: task._terms(z, k)[1], p)) <= 1e-4
        else:  # more than the root moves the cost: the arms and legs have gradients of their own
            assert np.count_nonzero(np.abs(lx[6:dyn.nv]) > 1e-6 * np.abs(lx).max()) > 10


def test_capsule_point_jacobians_match_central_differences(stone_walk):
    """What the body form's gradient and Gauss-Newton Hessian are built on: ``v @ dp/dq`` for
    points fixed on the capsules (hand, head, shin), against differences of the posed point."""
    dyn, ref_q, _ = stone_walk
    caps = obstacles.Capsules(dyn)
    rng = np.random.default_rng(2)
    x = dyn.to_state(ref_q[10])
    x[:dyn.nv] += rng.normal(0, 0.1, dyn.nv)
    xb = x[: 2 * dyn.nv]
    geoms = np.array([len(caps.geoms) - 5, len(caps.geoms) // 2, 3])
    bodies = caps.body[geoms]
    xpos, xmat = caps.points.pose(xb)
    local = rng.normal(0, 0.05, (3, 3))
    p = xpos[bodies] + np.einsum("nij,nj->ni", xmat[bodies], local)
    vecs = rng.normal(0, 1, (3, 3))
    caps.segments(xb)
    got = caps.project(xb, geoms, p, vecs)

    def posed(q):
        xp, xm = caps.points.pose(np.r_[q, xb[dyn.nv:]])
        return np.sum(vecs * (xp[bodies] + np.einsum("nij,nj->ni", xm[bodies], local)), axis=1)

    assert rel(got, central(posed, xb[: dyn.nv]).T) <= 1e-6
