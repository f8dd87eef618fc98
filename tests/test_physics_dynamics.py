"""The MuJoCo body as a planner part: coordinates, one step, and its derivatives.

The derivatives (MuJoCo's finite-difference transition matrices mapped to the state's minimal
coordinates) are checked against central differences of the part's own ``step`` in those
coordinates, with the feet on the ground and in the air, at a turned base (large rotation vectors,
where the SO(3) Jacobians matter).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdgaze.physics import build, retarget
from usdgaze.physics.dynamics import MujocoBody

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"


@pytest.fixture(scope="module")
def body():
    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    return MujocoBody(model, h=0.02), retarget.to_qpos(model, ref)


def _central(f, x, eps=1e-6):
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = eps
        cols.append((f(x + e) - f(x - e)) / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("where", ["ground", "air", "turned"])
def test_linearization_matches_central_differences_of_the_step(body, where):
    dyn, qpos = body
    rng = np.random.default_rng(3)
    q = qpos[400].copy()
    if where == "air":
        q[2] += 0.4
    if where == "turned":  # base turned 160 degrees from the anchor: rotation vector of norm ~2.8
        turn = Rotation.from_euler("z", 160, degrees=True) * Rotation.from_quat(np.roll(q[3:7], -1))
        q[3:7] = np.roll(turn.as_quat(), 1)
        q[2] += 0.4
    x = dyn.to_state(q, rng.normal(0, 0.3, dyn.nv))
    u = rng.normal(0, 0.1, dyn.nu)
    A, B = dyn.linearize(x, u, 0)
    An = _central(lambda z: dyn.step(z, u, 0), x)
    Bn = _central(lambda v: dyn.step(x, v, 0), u)
    assert A.shape == (dyn.nx, dyn.nx) and B.shape == (dyn.nx, dyn.nu)
    assert np.linalg.norm(A - An) / np.linalg.norm(An) < 1e-4
    assert np.linalg.norm(B - Bn) / np.linalg.norm(Bn) < 1e-4
    # The rotation blocks really are nonlinear here: identity Jacobians would be far off.
    if where == "turned":
        assert np.abs(x[3:6]).max() > 1.0


def test_state_round_trips_and_step_is_mujocos_semi_implicit_euler(body):
    dyn, qpos = body
    assert dyn.mj.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER and dyn.mj.opt.timestep == 0.02
    rng = np.random.default_rng(5)
    qv = rng.normal(0, 0.5, dyn.nv)
    x = dyn.to_state(qpos[200], qv)
    assert x.shape == (2 * dyn.nv,)
    q2, v2 = dyn.to_mujoco(x)
    d = mujoco.MjData(dyn.mj)
    d.qpos[:], d.qvel[:] = qpos[200], qv
    mujoco.mj_kinematics(dyn.mj, d)
    xpos = d.xpos.copy()
    d.qpos[:] = q2
    mujoco.mj_kinematics(dyn.mj, d)
    assert np.abs(d.xpos - xpos).max() < 1e-9 and np.array_equal(v2, qv)
    # One step: the new positions follow from the new velocities (q' = q (+) h qdot').
    u = rng.normal(0, 0.2, dyn.nu)
    xn = dyn.step(x, u, 0)
    qn, vn = dyn.to_mujoco(xn)
    expect = q2.copy()
    mujoco.mj_integratePos(dyn.mj, expect, vn, 0.02)
    assert np.abs(qn - expect).max() < 1e-9
    assert not np.allclose(vn, qv)


def test_head_pose_jacobian_matches_central_differences(body):
    """What the eye and belief parts read from the body: the eyes' midpoint and head axes."""
    dyn, qpos = body
    q = qpos[300].copy()
    turn = Rotation.from_euler("z", 120, degrees=True) * Rotation.from_quat(np.roll(q[3:7], -1))
    q[3:7] = np.roll(turn.as_quat(), 1)
    x = dyn.to_state(q)
    p, R = dyn.head_pose(x, 0)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.linalg.det(R) > 0
    assert abs(R[2, 2]) > 0.8  # the head's up is near the world's up in a walk
    dp, dR = dyn.head_pose_jacobian(x, 0)
    num_p = _central(lambda z: dyn.head_pose(z, 0)[0], x)
    num_R = _central(lambda z: dyn.head_pose(z, 0)[1].ravel(), x)
    assert np.linalg.norm(dp - num_p) / np.linalg.norm(num_p) < 1e-5
    assert np.linalg.norm(dR.reshape(9, -1) - num_R) / np.linalg.norm(num_R) < 1e-5


def test_window_linearization_threads_and_interpolation(body):
    """The window's batch: two threads give the serial numbers bit for bit, each step's alone as well
    as the whole window's; with a stride the steps MuJoCo differentiates are exact (checked above
    against central differences) and the others lie on the straight line between their neighbours."""
    model = body[0].model
    rng = np.random.default_rng(11)
    serial, threaded, strided = (MujocoBody(model, h=0.02, workers=w, stride=s) for w, s in ((1, 1), (2, 1), (2, 3)))
    qpos = body[1]
    # An anchor that normalizing again moves by a bit: each thread's copy must take it as it is.
    unit = lambda a: a / np.linalg.norm(a)  # noqa: E731  (as set_anchor normalizes)
    anchor = next(a for a in qpos[400, 3:7] + 1e-3 * rng.normal(size=(100, 4)) if not np.array_equal(unit(unit(a)), unit(a)))
    for dyn in (serial, threaded, strided):
        dyn.set_anchor(anchor)
    X = serial.to_state(qpos[400:408], rng.normal(0, 0.2, (8, serial.nv)))
    U = rng.normal(0, 0.1, (7, serial.nu))
    A, B = serial.linearize_batch(X, U, 0)
    At, Bt = threaded.linearize_batch(X, U, 0)
    assert np.array_equal(A, At) and np.array_equal(B, Bt)
    started = threaded.linearize_start(X, U, 0)  # the threads hand out steps one by one, last first
    for i in range(6, -1, -1):
        assert np.array_equal(started.step(i)[0], A[i]) and np.array_equal(started.step(i)[1], B[i])
    # On a rollout, the next states the window gives (a blown-up one stepped anew) change no bit.
    roll = X[:1].copy()
    for i in range(7):
        roll = np.vstack([roll, serial.step_body(roll[i], U[i], i)])
    want = serial.linearize_batch(roll[:7], U, 0)
    after = roll[1:].copy()
    after[3] = np.nan
    for dyn in (serial, threaded):
        got = dyn.linearize_start(roll[:7], U, 0, after)()
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    As, Bs = strided.linearize_batch(X, U, 0)
    for i in (0, 3, 6):  # differentiated: every third step and the last
        assert np.array_equal(As[i], A[i]) and np.array_equal(Bs[i], B[i])
    assert np.allclose(As[4], (2 * A[3] + A[6]) / 3) and np.allclose(Bs[5], (B[3] + 2 * B[6]) / 3)
    assert not np.allclose(As[4], A[4])  # the interpolation is an approximation, not a copy


def test_window_linearization_reusing_earlier_windows_finite_differences(body):
    """``reuse``: on a rollout, the matrices kept from an earlier window (the same absolute step) and
    mapped to this window's states are the ones differentiated anew, bit for bit, when the states are
    the same (the window called again, then shifted by a step along the same rollout), with one
    thread or two; fewer steps are differentiated; the first ``FD_FRESH`` steps always are."""
    model, qpos = body[0].model, body[1]
    rng = np.random.default_rng(12)
    serial = MujocoBody(model, h=0.02)
    n = 16
    U = rng.normal(0, 0.1, (n + 1, serial.nu))
    X = np.zeros((n + 2, serial.nx))
    X[0] = serial.to_state(qpos[300], rng.normal(0, 0.2, serial.nv))
    for i in range(n + 1):
        X[i + 1] = serial.step_body(X[i], U[i], i)
    windows = [(X[:n], U[:n], 0), (X[:n], U[:n], 0), (X[1:n + 1], U[1:n + 1], 1)]
    want = [serial.linearize_batch(*w) for w in windows]
    for workers in (1, 2):
        reusing = MujocoBody(model, h=0.02, workers=workers, reuse=3)
        fresh = []
        for (Xw, Uw, k0), (A, B) in zip(windows, want):
            fresh.append(reusing.kept.fresh_steps(reusing, np.arange(n), Xw, Uw, k0))
            reusing.kept.calls -= 1  # the call below counts itself
            got = reusing.linearize_start(Xw, Uw, k0)()
            assert np.array_equal(got[0], A) and np.array_equal(got[1], B)
        assert fresh[0].all()  # nothing kept yet
        for f in fresh[1:]:
            assert f[:5].all() and f[-1] == (f is fresh[2]) and 3 <= np.count_nonzero(~f) <= n - 5 - (n - 5) // 3 + 1
    # Where the states moved, the kept matrices are the earlier window's, not new differences.
    kept = MujocoBody(model, h=0.02, reuse=3)
    kept.linearize_batch(X[:n], U[:n], 0)
    Xm = X[:n] + np.r_[np.zeros(6), 1e-4 * np.ones(serial.nx - 6)]
    skipped = np.flatnonzero(~kept.kept.fresh_steps(kept, np.arange(n), Xm, U[:n], 0))
    kept.kept.calls -= 1
    A_kept = kept.linearize_batch(Xm, U[:n], 0)[0]
    A_new = serial.linearize_batch(Xm, U[:n], 0)[0]
    i = skipped[0]
    assert not np.array_equal(A_kept[i], A_new[i])
    assert np.linalg.norm(A_kept[i] - A_new[i]) < 1e-2 * np.linalg.norm(A_new[i])  # a nearby state's
    assert np.array_equal(A_kept[:5], A_new[:5])


def _deepest_foot_point(mj, qpos: np.ndarray, foot_geoms: np.ndarray) -> np.ndarray:
    """Per frame, how far the lowest foot capsule point is below z = 0 (MuJoCo's geom poses)."""
    d = mujoco.MjData(mj)
    out = np.zeros(len(qpos))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(mj, d)
        ends = [d.geom_xpos[g][None] + np.outer([-1, 1], d.geom_xmat[g].reshape(3, 3)[:, 2] * mj.geom_size[g, 1])
                for g in foot_geoms]
        out[k] = max(0.0, -min(float(e[:, 2].min()) - mj.geom_size[g, 0] for e, g in zip(ends, foot_geoms)))
    return out


def test_the_planner_tracks_a_reference_with_its_toes_out_of_the_ground(body):
    """CMU 131_01's lunge puts the model's toes centimetres into the floor; the planner's target turns
    the toe hinges (and only those) out of it, by at most 45 degrees, where the foot allows."""
    from usdgaze.physics.tracking import clear_ground, resample

    dyn, qpos = body
    ref = resample(qpos, np.arange(len(qpos)) / 120.0, 0.02, dyn)
    target = clear_ground(dyn, ref)
    feet = [b for b, r in enumerate(dyn.model.role) if r == "foot"]
    geoms = np.flatnonzero(np.isin(dyn.mj.geom_bodyid - 1, feet))
    before, after = _deepest_foot_point(dyn.mj, ref, geoms), _deepest_foot_point(dyn.mj, target, geoms)
    assert (before > 0.02).sum() >= 30 and before.max() > 0.04
    assert (after > 0.02).sum() <= (before > 0.02).sum() / 3 and np.all(after <= before + 1e-9)
    assert (after > 0.005).sum() <= (before > 0.005).sum() / 6
    qadr, _ = dyn.model.layout()
    toes = [qadr[b] for b, n in enumerate(dyn.model.names) if "toe" in n.lower() and dyn.model.kind[b] == "hinge"]
    assert len(toes) == 2
    others = np.setdiff1d(np.arange(dyn.nq), toes)
    assert np.array_equal(target[:, others], ref[:, others])
    assert 5.0 < np.degrees(np.abs(target[:, toes] - ref[:, toes]).max()) <= 45.0 + 1e-6


def test_a_foot_still_in_the_ground_is_lifted_by_its_leg(body):
    """Where turning the toes out does not clear a foot (the lunge's ankle itself 4-5 cm deep for 12
    steps), the planner's target bends that leg's hip and knee, by the least, until the foot's lowest
    capsule point is on the ground; the pelvis, the other leg and every clear frame stay as they are."""
    from usdgaze.physics.tracking import clear_ground, lift_feet, resample

    dyn, qpos = body
    toes_out = clear_ground(dyn, resample(qpos, np.arange(len(qpos)) / 120.0, 0.02, dyn))
    target = lift_feet(dyn, toes_out)
    feet = [b for b, r in enumerate(dyn.model.role) if r == "foot"]
    geoms = np.flatnonzero(np.isin(dyn.mj.geom_bodyid - 1, feet))
    before, after = _deepest_foot_point(dyn.mj, toes_out, geoms), _deepest_foot_point(dyn.mj, target, geoms)
    assert (before > 0.02).sum() >= 10 and before.max() > 0.04
    assert after.max() < 1e-3
    m = dyn.model
    qadr, _ = m.layout()
    legs = [b for foot in m.feet for b in (m.body_parent[foot], m.body_parent[m.body_parent[foot]])]
    cols = np.concatenate([qadr[b] + np.arange(4 if m.kind[b] == "ball" else 1) for b in legs])
    others = np.setdiff1d(np.arange(dyn.nq), cols)
    assert np.array_equal(target[:, others], toes_out[:, others])
    clear = before == 0.0
    assert np.array_equal(target[clear], toes_out[clear])
    # The least bend: no leg joint turns more than 30 degrees.
    for b in legs:
        a = qadr[b]
        if m.kind[b] == "ball":
            w = np.abs(np.sum(target[:, a:a + 4] * toes_out[:, a:a + 4], axis=1)).clip(0.0, 1.0)
            turn = 2.0 * np.degrees(np.arccos(w))
        else:
            turn = np.degrees(np.abs(target[:, a] - toes_out[:, a]))
        assert turn.max() < 30.0, (m.names[b], turn.max())


def test_lowest_foot_point_is_mujocos_distance_to_the_floor(body):
    """``measures.lowest_z`` (what the foot-depth measure, the stones' verdict and the ground checks
    read) against MuJoCo's own signed distance from each foot shape to the floor plane, on the
    reference's frames (the lunge's feet in the floor and the swings above it)."""
    from usdgaze.physics.measures import bottom_point, foot_depth, lowest_z

    dyn, qpos = body
    mj = dyn.mj
    floor = next(g for g in range(mj.ngeom) if mj.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE)
    feet = [b for b, r in enumerate(dyn.model.role) if r == "foot"]
    geoms = np.flatnonzero(np.isin(mj.geom_bodyid - 1, feet))
    d = mujoco.MjData(mj)
    lows = []
    for q in qpos[::20]:
        d.qpos[:] = q
        mujoco.mj_forward(mj, d)
        # mj_geomDistance is signed: negative where the capsule is in the floor
        gap = min(mujoco.mj_geomDistance(mj, d, int(g), floor, 1.0, None) for g in geoms)
        assert lowest_z(mj, d, geoms) == pytest.approx(gap, abs=1e-9)
        assert lowest_z(mj, d, geoms) == min(float(bottom_point(mj, d, g)[2]) for g in geoms)
        assert foot_depth(mj, d, geoms) == max(0.0, -lowest_z(mj, d, geoms))
        lows.append(gap)
    assert min(lows) < -0.01 < 0.05 < max(lows)  # both cases met: feet in the floor and well above it
    assert lowest_z(mj, d, np.array([], dtype=int)) == np.inf
