"""The body's tracking cost (``physics.tracking.BodyTracking``): its gradients against central
differences of its own value, and the batched window forms (which the solver uses) against the
per-step ones, on a window reaching past the reference's last step (a shot cut with no take after
it tracks its last state held there: docs/physics-log.md, "The shot's end")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from usdgaze.physics import build, mpc, retarget
from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.tracking import BodyTracking, resample, velocities

from .differences import central, rel

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_01.usdc"
H = 0.03
STEPS = 12  # the reference's steps; windows of N start before its end and run past it
N = 8


@pytest.fixture(scope="module")
def problem():
    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    dyn = MujocoBody(model, h=H)
    q = retarget.to_qpos(model, ref)[120:200]
    ref_q = resample(q, clip.seconds[120:200] - clip.seconds[120], H, dyn)[:STEPS]
    tracking = BodyTracking(dyn, ref_q, velocities(ref_q, H, dyn.mj), mpc._head_body(model))
    rng = np.random.default_rng(3)
    k0 = STEPS - 4
    X = np.array([dyn.to_state(ref_q[min(k0 + i, STEPS - 1)], rng.normal(0, 0.3, dyn.nv)) for i in range(N + 1)])
    X[:, :dyn.nv] += rng.normal(0, 0.05, (N + 1, dyn.nv))  # off the reference: every residual non-zero
    U = rng.normal(0, 0.5, (N, dyn.nu))
    return dyn, tracking, X, U, k0


def test_tracking_gradient_matches_central_differences_before_the_references_end(problem):
    dyn, tr, X, U, k0 = problem
    for i in (0, 3):  # steps k0 and k0 + 3 = the reference's last
        k = k0 + i
        lx, lu, lxx, luu, _ = tr.derivs(X[i], U[i], k)
        assert tr.l(X[i], U[i], k) > 1.0
        assert rel(lx, central(lambda z: tr.l(z, U[i], k), X[i])) <= 1e-5
        assert rel(lu, central(lambda v: tr.l(X[i], v, k), U[i])) <= 1e-5
        assert rel(tr.terminal_derivs(X[i], k)[0], central(lambda z: tr.terminal(z, k), X[i])) <= 1e-5
        # Gauss-Newton in the head vector, exact in the state and the controls: positive semi-definite.
        assert np.linalg.eigvalsh(lxx).min() > -1e-9 and np.linalg.eigvalsh(luu).min() > 0


def test_window_forms_match_the_per_step_forms_across_the_references_end(problem):
    dyn, tr, X, U, k0 = problem
    per_step = np.array([tr.l(X[i], U[i], k0 + i) for i in range(N)])
    assert np.allclose(tr.cost_batch(X[:N], U, k0), per_step, rtol=1e-10, atol=1e-12)
    total = per_step.sum() + tr.terminal(X[N], k0 + N)
    assert tr.total_batch(X, U, k0) == pytest.approx(total, rel=1e-10)
    lx, lu, lxx, luu, lux = tr.derivs_batch(X[:N], U, k0)
    for i in range(N):
        one = tr.derivs(X[i], U[i], k0 + i)
        for got, want in zip((lx[i], lu[i], lxx[i], luu[i], lux[i]), one):
            assert np.allclose(got, want, rtol=1e-9, atol=1e-9), i
    held = tr.ref_state(STEPS - 1)  # past the end: the last state held
    assert all(np.array_equal(tr.ref_state(k), held) for k in range(STEPS, k0 + N + 1))

