"""The iLQR/DDP solver against textbook answers, and the body part's derivatives against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from usdgaze.planning import ddp
from usdgaze.planning.compose import CostSum, SecondOrder, Stacked
from usdgaze.planning.kinbody import BaseChain, KinematicBody


class LinearQuadratic:
    """x' = A x + B u, cost x'Qx + u'Ru per step, terminal x'Px."""

    def __init__(self, A, B, Q, R, P):
        self.A, self.B, self.Q, self.R, self.P = A, B, Q, R, P
        self.nx, self.nu = B.shape

    def step(self, x, u, k):
        return self.A @ x + self.B @ u

    def linearize(self, x, u, k):
        return self.A, self.B

    def l(self, x, u, k):
        return x @ self.Q @ x + u @ self.R @ u

    def derivs(self, x, u, k):
        return 2 * self.Q @ x, 2 * self.R @ u, 2 * self.Q, 2 * self.R, np.zeros((self.nu, self.nx))

    def terminal(self, x, k):
        return x @ self.P @ x

    def terminal_derivs(self, x, k):
        return 2 * self.P @ x, 2 * self.P


def _double_integrator(h=0.05):
    A = np.array([[1.0, h], [0.0, 1.0]])
    B = np.array([[0.5 * h * h], [h]])
    return A, B, np.diag([1.0, 0.1]), np.array([[0.01]])


def test_lqr_matches_riccati_solution():
    """With the DARE solution as terminal cost, the optimal policy is the stationary LQR gain."""
    A, B, Q, R = _double_integrator()
    P = solve_discrete_are(A, B, Q, R)
    K_lqr = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    prob = LinearQuadratic(A, B, Q, R, P)
    x0 = np.array([1.0, -0.5])
    sol = ddp.solve(prob, prob, x0, np.zeros((40, 1)), options=ddp.Options(mu_init=0.0, mu_min=0.0))
    assert sol.converged and len(sol.costs) == 2  # one Newton step solves an LQ problem
    x = x0.copy()
    for i in range(40):
        u = -K_lqr @ x
        assert np.allclose(sol.U[i], u, atol=1e-8)
        assert np.allclose(sol.K[i], -K_lqr, atol=1e-8)
        x = A @ x + B @ u
    assert sol.cost == pytest.approx(x0 @ P @ x0, rel=1e-9)


def test_a_sum_of_costs_solves_as_the_summed_problem():
    """Q split over two costs (one batched, one per step) gives the LQR answer of the summed Q."""
    A, B, Q, R = _double_integrator()
    P = solve_discrete_are(A, B, Q, R)
    K_lqr = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    first = LinearQuadratic(A, B, 0.25 * Q, 0.5 * R, 0.5 * P)

    class Batched(LinearQuadratic):
        def cost_batch(self, X, U, k0):
            return np.einsum("ni,ij,nj->n", X, self.Q, X) + np.einsum("ni,ij,nj->n", U, self.R, U)

        def derivs_batch(self, X, U, k0):
            n = len(U)
            return (2 * X @ self.Q, 2 * U @ self.R, np.broadcast_to(2 * self.Q, (n, 2, 2)),
                    np.broadcast_to(2 * self.R, (n, 1, 1)), np.zeros((n, 1, 2)))

    second = Batched(A, B, 0.75 * Q, 0.5 * R, 0.5 * P)
    x0 = np.array([1.0, -0.5])
    sol = ddp.solve(first, CostSum([first, second]), x0, np.zeros((40, 1)),
                    options=ddp.Options(mu_init=0.0, mu_min=0.0))
    assert sol.cost == pytest.approx(x0 @ P @ x0, rel=1e-9)
    assert np.allclose(sol.K[0], -K_lqr, atol=1e-8)


class Pendulum:
    """A nonlinear problem: swing a damped pendulum from hanging to upright."""

    nx, nu = 2, 1
    h = 0.05

    def step(self, x, u, k):
        th, om = x
        om_n = om + self.h * (-9.81 * np.sin(th) - 0.1 * om + u[0])
        return np.array([th + self.h * om_n, om_n])

    def linearize(self, x, u, k):
        th, om = x
        h = self.h
        a = np.array([-9.81 * np.cos(th) * h, 1 - 0.1 * h])
        fx = np.array([[1 + h * a[0], h * a[1]], a])
        return fx, np.array([[h * h], [h]])

    def l(self, x, u, k):
        return 1e-3 * u @ u

    def derivs(self, x, u, k):
        return np.zeros(2), 2e-3 * u, np.zeros((2, 2)), 2e-3 * np.eye(1), np.zeros((1, 2))

    def terminal(self, x, k):
        d = x - [np.pi, 0.0]
        return 100 * d @ d

    def terminal_derivs(self, x, k):
        return 200 * (x - [np.pi, 0.0]), 200 * np.eye(2)


def test_cost_decreases_monotonically_on_a_nonlinear_problem():
    p = Pendulum()
    sol = ddp.solve(p, p, np.zeros(2), np.zeros((60, 1)), options=ddp.Options(max_iter=100))
    costs = np.array(sol.costs)
    assert len(costs) > 5
    assert np.all(np.diff(costs) < 0)
    assert costs[-1] < 1e-2 * costs[0]
    assert abs(sol.X[-1, 0] - np.pi) < 0.05
    fx, _ = p.linearize(np.array([0.3, 0.2]), np.zeros(1), 0)
    assert np.allclose(fx, _fd(lambda x: p.step(x, np.zeros(1), 0), np.array([0.3, 0.2])), atol=1e-6)


def test_receding_horizon_regulates_to_the_lqr_closed_loop():
    A, B, Q, R = _double_integrator()
    P = solve_discrete_are(A, B, Q, R)
    K_lqr = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    prob = LinearQuadratic(A, B, Q, R, P)
    mpc = ddp.RecedingHorizon(horizon=10, nu=1, options=ddp.Options(mu_init=0.0, mu_min=0.0))
    xs, us = mpc.run(prob, prob, np.array([1.0, 0.0]), 0, 30)
    assert np.allclose(us[:, 0], -(xs[:-1] @ K_lqr.T)[:, 0], atol=1e-7)
    with pytest.raises(ValueError):
        ddp.RecedingHorizon(horizon=1, nu=1)


def test_a_receding_horizon_started_over_regularized_recovers():
    """A window that ends 'converged' only because a huge mu made its steps negligible must not hand
    that mu on for good: the driver then never takes a step again (it shrinks mu only after a step)."""
    A, B, Q, R = _double_integrator()
    prob = LinearQuadratic(A, B, Q, R, solve_discrete_are(A, B, Q, R))
    mpc = ddp.RecedingHorizon(horizon=10, nu=1, options=ddp.Options(mu_init=1e9, mu_min=1e-6, tol=1e-3))
    x, steps = np.array([1.0, 0.0]), []
    for k in range(40):
        u, sol = mpc.step(prob, prob, x, k)
        steps.append(len(sol.costs) - 1)
        x = prob.step(x, u, k)
    assert steps[0] == 0 and sum(steps[20:]) > 0 and abs(x[0]) < 0.5


class _WrongSign(LinearQuadratic):
    """The double integrator whose linearization has its controls' sign flipped: every step the solver
    proposes raises the true cost, so each solve ends at the regularization's ceiling."""

    def linearize(self, x, u, k):
        fx, fu = super().linearize(x, u, k)
        return fx, -fu


def test_a_receding_horizon_restarts_after_the_ceiling_and_runs_more_iterations_first():
    A, B, Q, R = _double_integrator()
    P = solve_discrete_are(A, B, Q, R)
    bad = _WrongSign(A, B, Q, R, P)
    opts = ddp.Options(max_iter=1, mu_max=1e3)
    for restart, expect in ((True, opts.mu_init), (False, opts.mu_max)):
        mpc = ddp.RecedingHorizon(horizon=10, nu=1, options=opts, restart_at_ceiling=restart)
        u, sol = mpc.step(bad, bad, np.array([1.0, 0.0]), 0)
        assert sol.mu > opts.mu_max and len(sol.costs) == 1  # no step taken
        assert mpc.mu == expect
    # carry_max: a solve that grew mu within itself hands the next window at most that much
    mpc = ddp.RecedingHorizon(horizon=10, nu=1, options=opts, carry_max=1e-2)
    u, sol = mpc.step(bad, bad, np.array([1.0, 0.0]), 0)
    assert sol.mu > 1e-2 and mpc.mu == 1e-2
    good = LinearQuadratic(A, B, Q, R, P)
    mpc = ddp.RecedingHorizon(horizon=10, nu=1, options=ddp.Options(max_iter=1, tol=0.0),
                              first=ddp.Options(max_iter=4, tol=0.0), U_init=np.full((10, 1), 0.3))
    x, iterations = np.array([1.0, 0.0]), []
    for k in range(3):
        u, sol = mpc.step(good, good, x, k)
        iterations.append(sol.iterations)
        x = good.step(x, u, k)
    assert iterations[0] > 1 and iterations[1:] == [1, 1]


def _fd(f, x, eps=1e-6):
    cols = [(f(x + eps * e) - f(x - eps * e)) / (2 * eps) for e in np.eye(len(x))]
    return np.stack(cols, axis=-1)


def _rel_err(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-12)


def _base_chain(n=5, seed=0):
    rng = np.random.default_rng(seed)
    up = np.array([0.0, 0.0, 1.0])
    spine = np.c_[rng.normal(0, 0.1, (n, 2)), np.full(n, 1.3)]
    neck = spine + [0.0, 0.0, 0.25]
    eyes = neck + [0.08, 0.0, 0.12]
    yaw = rng.normal(0, 0.3, n)
    fwd = np.c_[np.cos(yaw), np.sin(yaw), np.zeros(n)]
    left = np.c_[-np.sin(yaw), np.cos(yaw), np.zeros(n)]
    axes = np.stack([fwd, left, np.tile(up, (n, 1))], axis=-1)
    return BaseChain(spine, neck, eyes, axes, left, up)


def test_kinematic_body_head_pose_jacobian_matches_central_differences():
    body = KinematicBody(_base_chain(), h=0.025)
    other = SecondOrder(2, 0.025, name="other")
    stack = Stacked([other, body])  # the body's slice does not start at 0
    x = np.random.default_rng(1).normal(0, 0.4, stack.nx)
    for k in range(5):
        dp, dR = body.head_pose_jacobian(x, k)
        assert _rel_err(dp, _fd(lambda y: body.head_pose(y, k)[0], x)) <= 1e-4
        assert _rel_err(dR, _fd(lambda y: body.head_pose(y, k)[1], x)) <= 1e-4
        _, R = body.head_pose(x, k)
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)
    fx, fu = stack.linearize(x, np.ones(stack.nu), 0)
    u = np.linspace(-1, 1, stack.nu)
    assert _rel_err(fx, _fd(lambda y: stack.step(y, u, 0), x)) <= 1e-4
    assert _rel_err(fu, _fd(lambda v: stack.step(x, v, 0), u)) <= 1e-4
    bx, bu = stack.linearize_batch(np.tile(x, (3, 1)), np.tile(u, (3, 1)), 0)
    assert np.array_equal(bx[1], fx) and np.array_equal(bu[2], fu)


def test_zero_offsets_give_the_base_head_pose():
    base = _base_chain()
    body = KinematicBody(base, h=0.025)
    Stacked([body])
    for k in range(5):
        p, R = body.head_pose(np.zeros(8), k)
        assert np.allclose(p, base.eyes[k]) and np.allclose(R, base.head_axes[k])
    p, _ = body.head_pose(np.zeros(8), 99)  # past the end: the last frame holds
    assert np.allclose(p, base.eyes[-1])
