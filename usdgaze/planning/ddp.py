"""A general iLQR/DDP solver and a receding-horizon driver (pure numpy).

The solver minimises  sum_{i<N} l(x_i, u_i, k0+i) + lf(x_N, k0+N)  subject to
x_{i+1} = f(x_i, u_i, k0+i), with Gauss-Newton (first-order dynamics) DDP, i.e. iLQR: a backward
Riccati-like pass over quadratic expansions of the cost and linearizations of the dynamics, then a
forward pass along the new feedback policy.

* Levenberg-Marquardt regularization: ``Quu + mu I`` (``regularization="control"``), or ``mu I`` on
  V_xx, i.e. ``Quu + mu fu'fu`` (``"state"``, Tassa et al. 2012, better when controls have mixed
  units); mu grows when the regularized Quu is not positive definite or no step decreases the cost,
  and shrinks after every accepted step.
* Line search: step sizes ``alphas`` are tried in order; a step is accepted only if the true cost
  decreases (and by at least ``armijo`` of the predicted decrease), so the cost is monotone
  non-increasing within a solve (``Solution.costs``).
* ``k`` is the absolute step index, so time-varying problems (references, object trajectories) are
  written once and a receding-horizon driver only moves ``k0``.

Dynamics and costs are protocols. Per-step methods are required; a batched method
(``linearize_batch``, ``derivs_batch``, ``cost_batch``) is used when present, because the
linearization of a whole window vectorizes over steps while the rollout cannot. A dynamics may
also offer ``forward_pass(X, U, kff, K, alpha, k0) -> (X_new, U_new) | None`` to roll a policy out
its own way (``compose.Stacked`` does, for parts that no other part reads), and
``linearize_start(X, U, k0[, after])`` to linearize on threads while the solver takes the costs:
its result, called, gives the window's (fx, fu), and with ``step(i)`` one step's as soon as it is
made, which the backward pass reads from the window's end.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable, Protocol, Sequence, runtime_checkable

import numpy as np
# Raw LAPACK: np.linalg's checks cost more than these tiny solves. Imported with this module, so that
# scipy's BLAS is loaded before any caller's ``threadpool_limits`` block: a BLAS first loaded inside
# one keeps its own threads (two spinning threads made a backward pass ~17x slower on 2 cores).
from scipy.linalg.lapack import dpotrf, dpotrs


@runtime_checkable
class Dynamics(Protocol):
    """x_{k+1} = step(x_k, u_k, k); linearize gives (df/dx, df/du) at (x, u, k)."""

    nx: int
    nu: int

    def step(self, x: np.ndarray, u: np.ndarray, k: int) -> np.ndarray: ...

    def linearize(self, x: np.ndarray, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]: ...


@runtime_checkable
class Cost(Protocol):
    """Running cost l(x, u, k) and terminal cost lf(x, k) with their first and second derivatives.

    ``derivs(x, u, k)`` returns (lx, lu, lxx, luu, lux) with lux of shape (nu, nx);
    ``terminal_derivs(x, k)`` returns (lx, lxx).
    """

    def l(self, x: np.ndarray, u: np.ndarray, k: int) -> float: ...

    def derivs(self, x: np.ndarray, u: np.ndarray, k: int) -> tuple[np.ndarray, ...]: ...

    def terminal(self, x: np.ndarray, k: int) -> float: ...

    def terminal_derivs(self, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class Options:
    """Solver settings. ``tol`` is the relative cost decrease below which a solve stops."""

    max_iter: int = 30
    tol: float = 1e-7
    mu_init: float = 1e-6
    mu_min: float = 1e-9
    mu_max: float = 1e10
    mu_grow: float = 10.0
    mu_shrink: float = 0.3
    alphas: Sequence[float] = (1.0, 0.5, 0.25, 0.1, 0.03, 0.01)
    armijo: float = 1e-4
    regularization: str = "control"  # "control": Quu + mu I; "state": V_xx + mu I (Quu + mu fu'fu)


@dataclass
class Solution:
    """The optimised trajectory, the feedback policy u = U + K (x - X), and the cost per iteration."""

    X: np.ndarray
    U: np.ndarray
    K: np.ndarray
    cost: float
    costs: list[float] = field(default_factory=list)
    iterations: int = 0
    converged: bool = False
    mu: float = 0.0


def rollout(dyn: Dynamics, x0: np.ndarray, U: np.ndarray, k0: int = 0) -> np.ndarray:
    """States x_0..x_N under the open-loop controls U."""
    X = np.zeros((len(U) + 1, dyn.nx))
    X[0] = x0
    if hasattr(dyn, "forward_pass"):
        fast = dyn.forward_pass(X, U, np.zeros_like(U), np.zeros((len(U), dyn.nu, dyn.nx)), 0.0, k0)
        if fast is not None:
            return fast[0]
    for i, u in enumerate(U):
        X[i + 1] = dyn.step(X[i], u, k0 + i)
    return X


def total_cost(cost: Cost, X: np.ndarray, U: np.ndarray, k0: int = 0) -> float:
    """Sum of running costs plus the terminal cost."""
    n = len(U)
    if hasattr(cost, "total_batch"):
        return float(cost.total_batch(X, U, k0))
    if hasattr(cost, "cost_batch"):
        running = float(np.sum(cost.cost_batch(X[:n], U, k0)))
    else:
        running = sum(cost.l(X[i], U[i], k0 + i) for i in range(n))
    return running + float(cost.terminal(X[n], k0 + n))


def linearize_trajectory(dyn: Dynamics, X: np.ndarray, U: np.ndarray, k0: int = 0):
    """(fx, fu) stacked over the window: shapes (N, nx, nx), (N, nx, nu)."""
    return linearize_start(dyn, X, U, k0)()


def linearize_start(dyn: Dynamics, X: np.ndarray, U: np.ndarray, k0: int = 0, rollout: bool = False) -> Callable[[], tuple]:
    """``linearize_trajectory`` begun: a dynamics with ``linearize_start`` (threads) runs it while the
    caller expands the cost; the result, called, gives (fx, fu). ``rollout``: ``X`` (``N + 1`` states)
    is the rollout of ``U``, so its states after each step are the steps' next states, which such a
    dynamics may take instead of stepping again (``after``)."""
    if hasattr(dyn, "linearize_start"):
        n = len(U)
        if rollout and len(X) > n:
            return dyn.linearize_start(X[:n], U, k0, X[1:n + 1])
        return dyn.linearize_start(X[:n], U, k0)
    result = _linearize_now(dyn, X, U, k0)
    return lambda: result


def _linearize_now(dyn: Dynamics, X: np.ndarray, U: np.ndarray, k0: int):
    if hasattr(dyn, "linearize_batch"):
        return dyn.linearize_batch(X[: len(U)], U, k0)
    pairs = [dyn.linearize(X[i], U[i], k0 + i) for i in range(len(U))]
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def expand_cost(cost: Cost, X: np.ndarray, U: np.ndarray, k0: int = 0):
    """Running-cost derivatives stacked over the window, plus the terminal ones."""
    n = len(U)
    if hasattr(cost, "derivs_batch"):
        running = cost.derivs_batch(X[:n], U, k0)
    else:
        parts = [cost.derivs(X[i], U[i], k0 + i) for i in range(n)]
        running = tuple(np.stack([p[j] for p in parts]) for j in range(5))
    return running, cost.terminal_derivs(X[n], k0 + n)


def window_rows(pending) -> Callable[[int], tuple]:
    """Step ``i`` -> its (fx, fu) from a started linearization: as each step is made where the
    dynamics offers ``step`` (the MuJoCo body's threads), else from the whole window's."""
    if hasattr(pending, "step"):
        return pending.step
    fx, fu = pending()
    return lambda i: (fx[i], fu[i])


def _backward(rows: Callable[[int], tuple], running, terminal, mu: float, state_reg: bool = False):
    """Feedforward k, gains K and the predicted decrease terms; None if Quu + mu I is not PD.
    ``rows(i)``: step ``i``'s (fx, fu), read from the window's end (``window_rows``)."""
    lx, lu, lxx, luu, lux = running
    vx, vxx = terminal
    n, nu = lu.shape
    nx = lx.shape[1]
    kff = np.empty((n, nu))
    K = np.empty((n, nu, nx))
    rhs = np.empty((nu, 1 + nx))
    QU = np.empty((n, nu))  # kept for the predicted decrease, summed once after the pass
    QUU = np.empty((n, nu, nu))
    # One Cholesky factor serves as the positive-definiteness test and the solve of Quu_reg [k K] = -[qu qux].
    if state_reg:  # mu I on V_xx (Tassa et al. 2012): the same push in every control's own units
        fx = np.stack([rows(i)[0] for i in range(n)])
        fu = np.stack([rows(i)[1] for i in range(n)])
        reg_uu = mu * (fu.transpose(0, 2, 1) @ fu)
        reg_ux = mu * (fu.transpose(0, 2, 1) @ fx)
    for i in range(n - 1, -1, -1):
        A, B = rows(i)
        At, Bt = A.T, B.T
        vxx_b = vxx @ B
        qx = lx[i] + At @ vx
        qu = lu[i] + Bt @ vx
        qxx = lxx[i] + At @ vxx @ A
        quu = luu[i] + Bt @ vxx_b
        qux = lux[i] + vxx_b.T @ A
        if state_reg:
            quu_reg = quu + reg_uu[i]
            qux_r = qux + reg_ux[i]
        else:
            quu_reg = quu.copy()
            quu_reg.flat[:: nu + 1] += mu
            qux_r = qux
        c, info = dpotrf(quu_reg, lower=1, clean=0, overwrite_a=1)
        if info != 0:
            return None
        np.negative(qu, out=rhs[:, 0])  # solving for -[qu qux] gives [k K] with no negation afterwards
        np.negative(qux_r, out=rhs[:, 1:])
        sol, _ = dpotrs(c, rhs, lower=1)
        k_i, K_i = sol[:, 0], sol[:, 1:]
        kff[i], K[i], QU[i], QUU[i] = k_i, K_i, qu, quu
        KtQ = K_i.T @ quu
        vx = qx + KtQ @ k_i + K_i.T @ qu + qux.T @ k_i
        M = K_i.T @ qux
        vxx = qxx + KtQ @ K_i + M + M.T
        vxx = 0.5 * (vxx + vxx.T)
    d1 = float(np.einsum("ni,ni->", kff, QU))
    d2 = 0.5 * float(np.einsum("ni,nij,nj->", kff, QUU, kff))
    return kff, K, d1, d2


def _forward(dyn, cost, X, U, kff, K, alpha, k0):
    if hasattr(dyn, "forward_pass"):  # a dynamics that rolls a policy out faster than step by step
        fast = dyn.forward_pass(X, U, kff, K, alpha, k0)
        if fast is not None:
            return fast[0], fast[1], total_cost(cost, fast[0], fast[1], k0)
    Xn = np.empty_like(X)
    Un = np.empty_like(U)
    Xn[0] = X[0]
    for i in range(len(U)):
        Un[i] = U[i] + alpha * kff[i] + K[i] @ (Xn[i] - X[i])
        Xn[i + 1] = dyn.step(Xn[i], Un[i], k0 + i)
    return Xn, Un, total_cost(cost, Xn, Un, k0)


def solve(dyn: Dynamics, cost: Cost, x0: np.ndarray, U0: np.ndarray, k0: int = 0,
          options: Options | None = None) -> Solution:
    """Minimise the window cost from x0, starting from the controls U0 (shape (N, nu))."""
    opt = options or Options()
    U = np.array(U0, dtype=float).reshape(-1, dyn.nu)
    X = rollout(dyn, np.asarray(x0, dtype=float), U, k0)
    # threads, where the dynamics has them, differentiate the rollout while its cost is taken
    pending = linearize_start(dyn, X, U, k0, rollout=True) if opt.max_iter >= 1 else None
    J = total_cost(cost, X, U, k0)
    costs = [J]
    mu = opt.mu_init
    K = np.zeros((len(U), dyn.nu, dyn.nx))
    converged = False
    it = 0
    for it in range(1, opt.max_iter + 1):
        if it > 1:
            pending = linearize_start(dyn, X, U, k0, rollout=True)
        running, terminal = expand_cost(cost, X, U, k0)
        rows = window_rows(pending)  # the backward pass starts on the steps made first
        accepted = False
        while mu <= opt.mu_max and not accepted:
            back = _backward(rows, running, terminal, mu, opt.regularization == "state")
            if back is None:
                mu = _grow(mu, opt)
                continue
            kff, K_new, d1, d2 = back
            if -(d1 + d2) < opt.tol * max(abs(J), 1e-12):  # nothing left to gain: converged
                # ... at this regularization: relax it for the next solve, or a large mu that made the
                # steps tiny would be kept by every later window (it shrinks only after a step)
                mu = max(mu * opt.mu_shrink, opt.mu_min)
                break
            for alpha in opt.alphas:
                expected = -(alpha * d1 + alpha * alpha * d2)
                Xn, Un, Jn = _forward(dyn, cost, X, U, kff, K_new, alpha, k0)
                if np.isfinite(Jn) and Jn < J and (expected <= 0 or (J - Jn) >= opt.armijo * expected):
                    accepted = True
                    break
            if not accepted:
                mu = _grow(mu, opt)
        if not accepted:
            converged = back is not None and mu <= opt.mu_max
            break
        rel = (J - Jn) / max(abs(J), 1e-12)
        X, U, J, K = Xn, Un, Jn, K_new
        costs.append(J)
        mu = max(mu * opt.mu_shrink, opt.mu_min)
        if rel < opt.tol:
            converged = True
            break
    return Solution(X=X, U=U, K=K, cost=J, costs=costs, iterations=it, converged=converged, mu=mu)


def _grow(mu: float, opt: Options) -> float:
    return max(mu * opt.mu_grow, opt.mu_min, 1e-12)


def shift_controls(U: np.ndarray) -> np.ndarray:
    """Warm start for the next window: drop the first control, repeat the last."""
    return np.concatenate([U[1:], U[-1:]], axis=0)


class RecedingHorizon:
    """Model-predictive control: solve a window, apply its first control, shift, repeat.

    The Levenberg-Marquardt parameter the last solve ended with starts the next one; with
    ``restart_at_ceiling``, one that ended at ``mu_max`` (a solve that took no step) starts the next
    window from ``mu_init`` instead: the next window is another problem (a new state, one more
    reference step), and a ceiling kept would make every later solve take no step either.
    ``first``: the options of the first solve (e.g. more iterations from a cold start), else ``options``.
    ``carry_max``: the most regularization the next window starts from. A line search that fails on a
    discontinuity (a contact that starts inside the window) grows mu within one solve until its step is
    tiny; carried on, that mu keeps the next windows' steps tiny too although their problems no longer
    straddle the same event (the full-body loop then replays its warm start for tenths of a second).

    ``step`` takes the problem of the current window (the dynamics and cost may change between calls,
    e.g. when the set of tracked objects changes; only ``nu`` must stay the same), warm-starts from the
    previous solution shifted by one step, and returns the first control and the solution.
    """

    def __init__(self, horizon: int, nu: int, options: Options | None = None,
                 U_init: np.ndarray | None = None, first: Options | None = None,
                 restart_at_ceiling: bool = False, carry_max: float | None = None) -> None:
        if horizon < 2:
            raise ValueError("the receding horizon needs at least two steps")
        self.horizon = horizon
        self.options = options or Options()
        self.first = first
        self.restart_at_ceiling = restart_at_ceiling
        self.carry_max = carry_max
        self.U = np.zeros((horizon, nu)) if U_init is None else np.array(U_init, dtype=float)
        self.last: Solution | None = None
        self.mu = (first or self.options).mu_init

    def step(self, dyn: Dynamics, cost: Cost, x: np.ndarray, k: int) -> tuple[np.ndarray, Solution]:
        # The regularization is warm-started too: consecutive windows are nearly the same problem.
        base = self.first if self.first is not None and self.last is None else self.options
        sol = solve(dyn, cost, x, self.U, k, dataclasses.replace(base, mu_init=self.mu))
        self.last = sol
        self.mu = min(max(sol.mu, base.mu_min), base.mu_max)
        if self.restart_at_ceiling and self.mu >= self.options.mu_max:
            self.mu = self.options.mu_init
        if self.carry_max is not None:
            self.mu = min(self.mu, self.carry_max)
        self.U = shift_controls(sol.U)
        return sol.U[0].copy(), sol

    def run(self, dyn: Dynamics, cost: Cost, x0: np.ndarray, k0: int, n_steps: int,
            simulate: Callable[[np.ndarray, np.ndarray, int], np.ndarray] | None = None):
        """Closed loop for ``n_steps``; ``simulate`` is the true system (default: the model)."""
        sim = simulate or dyn.step
        xs = [np.asarray(x0, dtype=float)]
        us = []
        for k in range(k0, k0 + n_steps):
            u, _ = self.step(dyn, cost, xs[-1], k)
            us.append(u)
            xs.append(sim(xs[-1], u, k))
        return np.array(xs), np.array(us)
