"""Eye, belief and cost derivatives against central differences; the Kalman filter against its textbook form."""

from __future__ import annotations

import numpy as np
import pytest

from tests.test_ddp import _base_chain, _fd, _rel_err
from usdgaze.planning.compose import Stacked
from usdgaze.planning.kinbody import KinematicBody
from usdgaze.vision import eye as eyemod
from usdgaze.vision.belief import SLOT, Belief, VisionParams, kalman_update
from usdgaze.vision.costs import AttendCost
from usdgaze.vision.loop import Filters, LoopOptions, Thing, run

H = 0.025


def _problem(pos_a, pos_b, seed=0):
    body = KinematicBody(_base_chain(seed=seed), H)
    eye = eyemod.Eye(H)
    sight = eyemod.Sight(eye, body)
    belief = Belief(2, [[0, 0, -9.81], [0, 0, 0]], VisionParams(0.2, 0.3, H), sight)
    stack = Stacked([eye, body, belief])
    rng = np.random.default_rng(seed)
    x = np.zeros(stack.nx)
    x[:3] = [0.2, -0.1, 8.0]
    x[3:11] = rng.normal(0, 0.2, 8)
    b = x[11:].reshape(2, SLOT)
    b[:, :3] = [pos_a, pos_b]
    b[:, 3:6] = rng.normal(0, 1, (2, 3))
    b[:, 6:] = [[0.3, 0.5, 0.1], [0.1, 0.2, 0.05]]
    return stack, sight, x, rng.normal(0, 1, stack.nu)


@pytest.mark.parametrize("where", ["in view", "at the edge of the field of view"])
def test_stacked_eye_body_belief_derivatives(where):
    # an object near the +-60 deg edge exercises the visibility weight's derivative
    b = [1.0, 1.6, 1.6] if where != "in view" else [1.5, -0.5, 1.5]
    stack, _, x, u = _problem([2.0, 0.3, 1.6], b)
    for k in (0, 3):
        fx, fu = stack.linearize(x, u, k)
        assert _rel_err(fx, _fd(lambda y: stack.step(y, u, k), x)) <= 1e-4
        assert _rel_err(fu, _fd(lambda v: stack.step(x, v, k), u)) <= 1e-4
        for part in stack.parts:  # each part's own rows
            rows = slice(part.xs.start, part.xs.stop)
            assert _rel_err(fx[rows], _fd(lambda y: stack.step(y, u, k)[rows], x)) <= 1e-4, part.name


def test_point_of_sight_jacobian():
    stack, sight, x, _ = _problem([2.0, 0.3, 1.6], [1.5, -0.5, 1.5])
    pps, _, _, J, _, _ = sight.jacobian(x[None], 2)
    assert _rel_err(J[0], _fd(lambda y: sight.points(y[None], 2)[0][0], x)) <= 1e-4
    assert np.allclose(sight.point(x, 2)[0], pps[0])


@pytest.mark.parametrize("mode", ["uncertainty", "distance", "sequential"])
def test_cost_derivatives(mode):
    stack, sight, x, u = _problem([2.0, 0.3, 1.6], [1.5, -0.5, 1.5])
    c = AttendCost(stack, sight, np.array([1.0, 0.5]), mode=mode, target=1)
    u = u * 30  # past the pursuit bound: the speed penalty is active
    lx, lu, lxx, luu, _ = c.derivs(x, u, 9)  # step 9: inside a recharge window
    assert _rel_err(lx, _fd(lambda y: np.array(c.l(y, u, 9)), x)) <= 1e-4
    assert _rel_err(lu, _fd(lambda v: np.array(c.l(x, v, 9)), u)) <= 1e-4
    assert _rel_err(luu, _fd(lambda v: c.derivs(x, v, 9)[1], u)) <= 1e-4
    tx, _ = c.terminal_derivs(x, 9)
    assert _rel_err(tx, _fd(lambda y: np.array(c.terminal(y, 9)), x)) <= 1e-4


@pytest.mark.parametrize("per_second", [True, False])
def test_kalman_update_matches_the_matrix_filter(per_second):
    """The 3-vector covariance update equals the full 6x6 Kalman filter of appendix A, with the
    process noise alpha per second (Q = alpha h I a step) or, literally, alpha I a step."""
    p = VisionParams(alpha=0.2, eta=0.3, h=H, per_second=per_second)
    rng = np.random.default_rng(1)
    mu, s = rng.normal(0, 1, 6), np.array([0.4, 0.9, 0.2])
    z, r, a = rng.normal(0, 1, 3), 0.3, np.array([0, 0, -9.81])
    I3 = np.eye(3)
    F = np.block([[I3, H * I3], [0 * I3, I3]])
    Sig = np.block([[s[0] * I3, s[2] * I3], [s[2] * I3, s[1] * I3]])
    Hm = np.hstack([I3, 0 * I3])
    Sb = F @ Sig @ F.T + (0.2 * H if per_second else 0.2) * np.eye(6)
    K = Sb @ Hm.T @ np.linalg.inv(Hm @ Sb @ Hm.T + r * I3)
    mb = F @ mu + np.r_[np.zeros(3), H * a]
    mu_ref = mb + K @ (z - Hm @ mb)
    Sig_ref = (np.eye(6) - K @ Hm) @ Sb
    mu_new, s_new = kalman_update(mu, s, z, r, a, p)
    assert np.allclose(mu_new, mu_ref) and np.allclose(s_new, [Sig_ref[0, 0], Sig_ref[3, 3], Sig_ref[0, 3]])
    assert np.allclose(Sig_ref, np.kron([[s_new[0], s_new[2]], [s_new[2], s_new[1]]], I3))


def test_eye_distance_scale():
    d, dd = eyemod.distance(np.array([3.4, 8.5, 15.3, eyemod.ZETA_HI]))
    assert np.allclose(d[:3], [0.25, 1.0, 9.0]) and d[3] > 30
    assert np.allclose(dd, _fd(lambda z: eyemod.distance(z)[0], np.array([3.4, 8.5, 15.3, eyemod.ZETA_HI])).diagonal())
    assert np.allclose(eyemod.distance(eyemod.zeta_for(np.array([0.5, 2.0])))[0], [0.5, 2.0])
    bound = eyemod.speed_bound(np.array([0.0, 0.19, 0.21, 0.39, 0.41]))
    assert np.allclose(np.degrees(bound), [800, 800, 100, 100, 800])


def test_every_planner_solve_decreases_its_cost_monotonically():
    K = 24
    base = _base_chain(K, seed=3)
    t = np.arange(K)[:, None] * H
    balls = [Thing("a", np.array([6.0, 1.0, 1.8]) + t * [-4.0, -0.5, 0.0], kind="moving"),
             Thing("b", np.array([6.0, -1.5, 1.2]) + t * [-3.0, 0.6, 0.0], kind="moving")]
    res = run(base, balls, LoopOptions(h=H, window_s=0.3), K)
    assert all(np.all(np.diff(c) < 0) for c in res.solves)
    assert sum(len(c) > 1 for c in res.solves) >= K // 2  # most solves took at least one step


def test_a_sphere_is_in_view_when_any_part_of_it_is_within_60_deg_of_the_head_forward():
    """Geometry by hand: a 25 cm sphere 1.2 m away subtends asin(0.25 / 1.2) = 12.02 deg, so it is seen
    with its centre up to 72.0 deg off the head's forward; a point only to 60 deg. The head, not the
    line of sight, is the axis: the eyes looking 40 deg left see no further left."""
    def at(deg: float, dist: float = 1.2) -> np.ndarray:  # in the ground plane, degrees left of +X
        return dist * np.array([np.cos(np.radians(deg)), np.sin(np.radians(deg)), 0.0])

    def seen(pos, radius, head_deg=0.0, sight_deg=0.0):
        thing = Thing("o", np.array([pos]), radius=radius)
        filters = Filters([thing], LoopOptions(h=H))
        return bool(filters.sense(0, np.zeros(3), at(head_deg, 1.0), at(sight_deg, 2.0))[0])

    assert seen(at(71.5), 0.25) and not seen(at(72.5), 0.25)  # 12.02 deg wider for the sphere
    assert seen(at(59.5), 0.0) and not seen(at(60.5), 0.0) and not seen(at(71.5), 0.0)  # a point: 60 deg
    # 0.6 m away it subtends asin(0.25 / 0.6) = 24.62 deg: seen to 84.6 deg, on either side
    assert seen(at(-84.0, 0.6), 0.25) and not seen(at(-85.0, 0.6), 0.25)
    assert not seen(at(72.5), 0.25, sight_deg=40.0) and not seen(at(60.5), 0.0, sight_deg=40.0)
    assert seen(at(101.5), 0.25, head_deg=30.0) and not seen(at(102.5), 0.25, head_deg=30.0)


def test_at_most_four_objects_in_the_optimization_the_nearest_in_view_all_updated():
    K = 12
    base = _base_chain(K, seed=0)
    t = np.arange(K)[:, None] * H
    eyes = base.eyes[0]
    things = [Thing(f"o{i}", eyes + [2.0 + 0.7 * i, 0.3 * (-1) ** i, 0.0] + t * [-0.5, 0.0, 0.0], kind="moving")
              for i in range(6)]
    res = run(base, things, LoopOptions(h=H, window_s=0.2), K)
    assert res.optimized.sum(1).max() == 4
    known = ~np.isnan(res.sigma_p)
    for k in range(K):
        d = np.linalg.norm(res.estimate[k] - res.eyes[k], axis=1)
        cand = np.flatnonzero(known[k] & res.visible[k])
        nearest = set(cand[np.argsort(d[cand])][:4])
        assert set(np.flatnonzero(res.optimized[k])) == nearest
    assert known[-1].all()  # the two left out keep being observed and updated


def test_sight_needs_only_the_body_part_protocol():
    """A body offering just head_pose / head_pose_jacobian (the BodyPart minimum) gives the same sight."""
    stack, sight, x, _ = _problem([2.0, 0.3, 1.6], [1.5, -0.5, 1.5])
    body = sight.body

    class Minimal:
        def head_pose(self, x, k):
            return body.head_pose(x, k)

        def head_pose_jacobian(self, x, k):
            return body.head_pose_jacobian(x, k)

    minimal = eyemod.Sight(sight.eye, Minimal())
    minimal.body.xs = body.xs
    X = np.stack([x, x * 0.9])
    for a, b in zip(sight.jacobian(X, 1), minimal.jacobian(X, 1)):
        assert np.allclose(a, b)
    assert np.allclose(sight.points(X, 1)[0], minimal.points(X, 1)[0])


def test_unwatched_uncertainty_saturates_in_steps_per_step_but_grows_for_tenths_of_a_second_per_second():
    """Why alpha is read per second (docs/attend.md): an object left after being fixated (r from
    ~0 to 1) under alpha 0.2. Added every step, its sigma_p is within 5 % of its fixed point after 4
    steps (100 ms; measured 0.46, 0.74, 0.89, 0.95), so there is nothing to come back for; added per
    second, it is at 58 % after 10 steps and still growing after 20 (0.5 s)."""
    grown = {}
    for per_second in (False, True):
        p = VisionParams(alpha=0.2, eta=0.3, h=H, per_second=per_second)
        mu, s = np.zeros(6), np.array([0.0, 1.0, 0.0])
        for _ in range(400):  # settle while fixated
            mu, s = kalman_update(mu, s, np.zeros(3), 1e-4, np.zeros(3), p)
        sp = []
        for _ in range(400):  # then left: observed with r = 1 (peripheral)
            mu, s = kalman_update(mu, s, np.zeros(3), 1.0, np.zeros(3), p)
            sp.append(s[0])
        grown[per_second] = np.array(sp) / sp[-1]
    assert grown[False][3] > 0.95
    assert grown[True][9] < 0.7 and grown[True][19] < 0.95 and np.all(np.diff(grown[True][:20]) > 0)
