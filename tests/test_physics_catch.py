"""The coupled loop (eyes + belief + MuJoCo body) and the ball-catch task, on short standing shots.

Derivatives of the new cost terms are compared with central differences; the shots are measured on
the written layer composed over the input, by UsdSkel FK (eye axes from the bind pose, palms midway
between wrist and hand joints) against the ball's true positions read from the stage.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf

from usdgaze.passes import physics as physics_pass
from usdgaze.physics import build, mpc, retarget, visuomotor
from usdgaze.physics.catch import CatchTask
from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.tracking import BodyTracking, velocities
from usdgaze.planning.compose import Stacked
from usdgaze.vision import eye as eyemod
from usdgaze.vision import loop

from . import catch_stages as cs
from . import measure
from .differences import central

H = 0.03


def _gaze(posed):
    """Per frame: the line of sight (unit, world) from the eyes' midpoint, by FK of the eye joints."""
    fwd = measure.character_forward_skel(posed, "LeftHip", "RightHip")
    axes = [measure.local_forward(posed, e, fwd) for e in ("LeftEye", "RightEye")]
    return 0.5 * (posed.position("LeftEye") + posed.position("RightEye")), \
        measure.sight_line(posed, "LeftEye", "RightEye", *axes)


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    """A coupled window's stack at a standing pose with a ball in view, and the catch task proactive."""
    tmp = tmp_path_factory.mktemp("catch_derivs")
    start, arrival, flight = cs.seeded_throw(1, (0.7, 0.8))
    clip = build.load_clip(cs.throw_stage(tmp / "t.usda", start, arrival, flight, 0.2))
    model, ref = build.body_model(clip, weld_still=False)
    q = retarget.to_qpos(model, ref)
    plan = MujocoBody(model, h=H)
    eye = eyemod.Eye(H)
    Stacked([eye, plan])
    ball = loop.Thing("ball", np.array([[0.5, 2.0, 1.2]]), kind="ballistic")
    filters = loop.Filters([ball], loop.LoopOptions(h=H, sigma_v0=1e4))
    filters.mu[0], filters.sig[0] = np.array([1.5, 0.2, 1.4, -4.0, -0.5, 1.0]), np.array([0.3, 40.0, 2.0])
    tracking = BodyTracking(plan, q, velocities(q, H, plan.mj), mpc._head_body(model))
    task = CatchTask(plan, 0, seed=3)
    task.arrival, task.hand = (0.3, np.array([0.45, 0.1, 1.1])), "right"
    prob = visuomotor._Problem(eye, plan, filters, [0], 0, tracking, [task], loop.LoopOptions(sigma_v0=1e4))
    rng = np.random.default_rng(0)
    xb = plan.to_state(q[0], rng.normal(0, 0.2, plan.nv))
    xb[6:plan.nv] += rng.normal(0, 0.2, plan.nv - 6)  # joints off the reference: no zero residuals
    x = prob.state(np.array([0.2, -0.1, 9.0]), xb, filters)
    return prob, task, x, rng.normal(0, 0.3, prob.stack.nu)


def test_catch_term_gradient_and_gauss_newton_hessian_match_central_differences(problem):
    prob, task, x, u = problem
    assert task.weight(0, H) == task.o.w_proactive
    lx, _, lxx, _, _ = task.derivs(x, u, 0)
    num = central(lambda z: task.l(z, u, 0), x)
    assert np.linalg.norm(num) > 1.0 and np.linalg.norm(lx - num) / np.linalg.norm(num) < 1e-4
    xs = task.dyn.xs
    J = central(lambda z: task._residuals(z[xs][None], False)[0][0], x).T  # residual Jacobian
    assert np.linalg.norm(lxx - 2 * task.weight(0, H) * J.T @ J) / np.linalg.norm(lxx) < 1e-4
    # The lateral term is live beyond the free band: move the feet 40 cm off the arrival's side.
    task.arrival = (0.3, task.arrival[1] + 0.7 * task.left)
    lx2 = task.derivs(x, u, 0)[0]
    num2 = central(lambda z: task.l(z, u, 0), x)
    assert abs(task._residuals(x[xs][None], False)[0][0, 3]) > 1.0
    assert np.linalg.norm(lx2 - num2) / np.linalg.norm(num2) < 1e-4
    task.arrival = (0.3, task.arrival[1] - 0.7 * task.left)


def test_catch_window_derivatives_match_central_differences_of_each_step(problem):
    """The batched cost and expansion the solver uses, on a window of three different states whose
    last step is past the phase (weight 0): each row against central differences of its own step."""
    prob, task, x, u = problem
    rng = np.random.default_rng(4)
    X = np.stack([x, x + rng.normal(0, 0.05, len(x)), x + rng.normal(0, 0.05, len(x))])
    U = np.stack([u, u, u])
    k0 = int(np.floor((task.arrival[0] + task.o.hold_s) / H)) - 1  # steps k0, k0 + 1 in the phase, k0 + 2 not
    assert [task.weight(k0 + i, H) for i in range(3)] == [task.o.w_proactive] * 2 + [0.0]
    c = task.cost_batch(X, U, k0)
    lx, lu, lxx, luu, lux = task.derivs_batch(X, U, k0)
    assert c[2] == 0.0 and not lx[2].any() and not lxx[2].any() and not (lu.any() or luu.any() or lux.any())
    xs = task.dyn.xs
    for i in range(2):
        num = central(lambda z: task.cost_batch(np.r_[X[:i], z[None], X[i + 1:]], U, k0)[i], X[i])
        assert c[i] > 1.0 and np.linalg.norm(lx[i] - num) / np.linalg.norm(num) < 1e-4
        J = central(lambda z: task._residuals(z[xs][None], False)[0][0], X[i]).T
        assert np.linalg.norm(lxx[i] - 2 * task.o.w_proactive * J.T @ J) / np.linalg.norm(lxx[i]) < 1e-4


def test_the_arrival_is_where_the_true_path_crosses_the_catching_plane(problem):
    """The real Kalman filter fed exact observations of a throw; the task's estimated arrival against the
    true continuous path's crossing of the plane 35 cm in front of the shoulders, solved here by bisection.
    (The first grid point past the plane, read with the filter's step-mean velocity as a continuous one,
    measured 7-16 cm off on such throws.)"""
    import mujoco

    from usdgaze.vision.belief import kalman_update

    _, task, x, _ = problem
    plan, h = task.dyn, H
    d = mujoco.MjData(plan.mj)
    d.qpos[:] = plan.to_mujoco(x[plan.xs])[0]
    mujoco.mj_kinematics(plan.mj, d)
    body = {plan.mj.body(i).name: i for i in range(plan.mj.nbody)}
    mid = 0.5 * (d.xpos[body["LeftShoulder"]] + d.xpos[body["RightShoulder"]])
    left = d.xpos[body["LeftHip"]] - d.xpos[body["RightHip"]]
    left[2] = 0.0
    fwd = np.cross(left / np.linalg.norm(left), [0.0, 0.0, 1.0])
    g = np.array([0.0, 0.0, -9.81])
    p0 = mid + 6.0 * fwd + 0.3 * np.cross([0.0, 0.0, 1.0], fwd) + [0.0, 0.0, 0.4]
    aim, t_hit = mid + 0.35 * fwd - [0.0, 0.0, 0.1], 1.1
    v0 = (aim - p0) / t_hit - 0.5 * g * t_hit
    path = lambda t: p0 + t * v0 + 0.5 * t * t * g  # noqa: E731
    ball = loop.Thing("ball", np.array([path(k * h) for k in range(40)]), kind="ballistic")
    params = loop.Filters([ball], loop.LoopOptions(h=h, sigma_v0=1e4)).params
    mu, sig = np.r_[path(0.0), 0.0, 0.0, 0.0], np.array([1.0, 1e4, 0.0])
    task.locked, task.reference = False, None
    task.perceive(visuomotor.Percept(0, h, {0: mu}, {0: sig}, [ball], d, np.array([True])))
    assert task.arrival is None and task.weight(0, h) == 0.0  # a new track's speed (10 m/s prior): no phase yet
    for k in range(1, 20):  # noise-free observations: the filter converges to its own process model
        mu, sig = kalman_update(mu, sig, path(k * h), 1e-8, ball.accel, params)
    k = 19
    lo, hi = k * h, 3.0  # bisection on the true path's distance to the plane
    for _ in range(60):
        m_ = 0.5 * (lo + hi)
        lo, hi = (m_, hi) if (path(m_) - mid) @ fwd > 0.35 else (lo, m_)
    task.locked, task.arrival, task.reference = False, None, None
    task.perceive(visuomotor.Percept(k, h, {0: mu}, {0: sig}, [ball], d, np.array([True])))
    assert abs(task.arrival[0] - lo) < 2e-3
    assert np.linalg.norm(task.arrival[1] - path(lo)) < 0.01
    task.arrival, task.hand, task.locked = (0.3, np.array([0.45, 0.1, 1.1])), "right", False


def test_coupled_cost_gradient_matches_central_differences(problem):
    """AttendCost without the kinematic body's terms, sigma read per step, summed with tracking and task."""
    prob, _, x, u = problem
    cost = prob.cost
    lx, lu = cost.derivs(x, u, 0)[:2]
    num = central(lambda z: cost.l(z, u, 0), x)
    assert np.linalg.norm(lx - num) / np.linalg.norm(num) < 1e-4
    num_u = central(lambda v: cost.l(x, v, 0), u)
    assert np.linalg.norm(lu - num_u) / np.linalg.norm(num_u) < 1e-4
    b0 = prob.stack["belief"].xs.start
    assert abs(lx[b0 + 7]) > 0  # the velocity variance is in the cost (scaled by h^2)


def test_each_coupled_solve_decreases_the_cost(tmp_path):
    start, arrival, flight = cs.seeded_throw(2, (0.7, 0.8))
    src = cs.throw_stage(tmp_path / "t.usda", start, arrival, flight, 0.15)
    clip = build.load_clip(src)
    model, ref = build.body_model(clip, weld_still=False)
    secs = np.arange(0, 0.2, H)
    ball = cs.flight(start, arrival, flight, secs) @ (model.to_model / np.linalg.norm(model.to_model[:, 0])).T
    res = visuomotor.simulate(model, retarget.to_qpos(model, ref), clip.seconds,
                              [loop.Thing("ball", ball, kind="ballistic")],
                              visuomotor.Options(mpc.Options(h=H, horizon_s=0.3)))
    assert len(res.body.solve_costs) == len(res.body.seconds) - 1 >= 4
    for costs in res.body.solve_costs:
        assert all(b <= a for a, b in zip(costs, costs[1:]))
    assert res.body.solve_costs[0][-1] < res.body.solve_costs[0][0]
    assert res.vision.visible[:, 0].all() and not np.isnan(res.vision.sigma_p).any()


def _shot(tmp, throw, seconds):
    start, arrival, flight = throw
    src = cs.throw_stage(tmp / "throw.usda", start, arrival, flight, seconds)
    before = measure.sha256(src)
    out = tmp / "sim.usda"
    reports = physics_pass.run(src, out, mpc.Options(h=H, horizon_s=0.6))
    m = cs.catch_measures(src, out, tmp, flight)
    assert measure.sha256(src) == before
    return src, out, reports[0], m


def test_a_ball_from_the_front_is_watched_and_the_hand_goes_to_it(tmp_path):
    throw = cs.seeded_throw(2, (0.7, 0.8))
    src, out, report, m = _shot(tmp_path, throw, throw[2] + 0.1)
    assert not report.fell
    posed, ball = m["posed"], m["ball"]
    eyes, sight = _gaze(posed)
    to_ball = ball - eyes
    off = measure.angle_between(sight, to_ball / np.linalg.norm(to_ball, axis=1, keepdims=True))
    flying = m["secs"] < throw[2]
    fwd = measure.character_forward_skel(posed, "LeftHip", "RightHip")
    head_off = measure.angle_between(posed.axis("Head", measure.local_forward(posed, "Head", fwd)),
                                     to_ball / np.linalg.norm(to_ball, axis=1, keepdims=True))
    # The eyes point at the ball, much more closely than the head does: a median 3.3 against 14.3 deg
    # over the flight. With look-at proposals every 100 ms (not every step) the eyes drifted off it
    # between them: 9.5 against 24.0 deg (docs/physics.md, "The eyes on a thrown ball").
    assert np.median(off[flying]) < 5.0 and np.median(off[flying]) < 0.5 * np.median(head_off[flying])
    ref = cs.catch_measures(src, src, tmp_path, throw[2])  # the reference itself: arms down
    assert m["at_arrival"] < 0.10 and ref["at_arrival"] > 0.3  # the bar's 10 cm (measured 5.3 cm)
    # The report says the catch (it said nothing of a shot without a problem), its nearest palm as
    # the FK's measures it: the model's palm point and the FK's (midway wrist to hand) differ by cm.
    (said,) = [t for t in report.tasks if t.startswith("catch:")]
    nearest = float(said.split("palm ")[1].split(" cm")[0])
    assert said.endswith(": caught") and abs(nearest - 100 * m["distance"].min()) < 3.0, said
    layer = Sdf.Layer.FindOrOpen(str(out))
    frames = layer.customLayerData["usdgaze:physics"][cs.SKEL]["frames"]
    assert max(v for v in frames["catch.weight"] if v == v) == 0.1  # the proactive phase ran
    est = [p for p in layer.GetPrimAtPath("/UsdGazeAttend").nameChildren[0].nameChildren][0]
    assert est.attributes["gaze:attend:object"].default == cs.BALL


def test_a_ball_from_behind_is_neither_looked_at_nor_reached_for_before_it_is_in_view(tmp_path):
    throw = cs.behind_throw()
    src, out, report, m = _shot(tmp_path, throw, throw[2] + 0.1)
    # Said, but not simulated again: a second simulation would not see the ball any sooner.
    assert not report.fell and len(report.problems) == 1 and "never reached for" in report.problems[0]
    assert report.iterations == 1 and not report.other_attempt
    (said,) = [t for t in report.tasks if t.startswith("catch:")]
    assert said.endswith("not caught (over 10 cm)") and float(said.split("palm ")[1].split(" cm")[0]) > 10, said
    posed, ball = m["posed"], m["ball"]
    fwd = measure.character_forward_skel(posed, "LeftHip", "RightHip")
    head_fwd = posed.axis("Head", measure.local_forward(posed, "Head", fwd))
    eyes, sight = _gaze(posed)
    to_ball = ball - eyes
    to_ball /= np.linalg.norm(to_ball, axis=1, keepdims=True)
    in_view = measure.angle_between(head_fwd, to_ball) <= 60.0
    assert not in_view[0] and in_view.any()
    before = np.arange(len(in_view)) < np.argmax(in_view)
    assert measure.angle_between(sight, to_ball)[before].min() > 30.0
    # Not reached for: neither palm comes nearer the ball's arrival point (the physics alone sways them
    # by a few cm: the standing reference's arms are not held exactly).
    arrival = m["ball"][-1]
    posed = m["posed"]
    for side in ("Left", "Right"):
        palm = 0.5 * (posed.position(f"{side}Wrist") + posed.position(f"{side[0].lower()}hand"))
        d = np.linalg.norm(palm - arrival, axis=1)
        assert (d[0] - d[before]).max() < 0.02


def test_a_catch_naming_no_object_is_one_line_and_writes_nothing(tmp_path, capsys):
    from usdgaze.console.main import main

    start, arrival, flight = cs.seeded_throw(0)
    src = cs.throw_stage(tmp_path / "t.usda", start, arrival, flight, 0.1)
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.GetRelationshipAtPath(f"{cs.SKEL_ROOT}.usdgaze:physics:catch").targetPathList.explicitItems = [
        Sdf.Path("/Objects")]
    layer.Save()
    assert main(["attend", str(src), "--out", str(tmp_path / "o.usda"), "--physics"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "usdgaze:physics:catch" in err[0] and "</Objects> is not an object" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.usda"]


def test_a_ue_style_character_catches_a_ball_on_its_right_with_its_right_hand(tmp_path):
    """The catch on a rig that is not CMU's: a UE-style standing character with fingers (its right hand
    ``hand_r``), a ball landing 20 cm to its right. By UsdSkel FK on the written layer, the right palm
    (midway between wrist and middle knuckle) is within the bar's 10 cm of the ball at arrival, and
    the left hand stays away (before the hands' sides came from the rig, ``hand_r`` was taken for a
    left hand and the left hand reached across the body for the ball: here the character fell at
    1.08 s; in the same scene through the command, the left palm ended 8.9 cm off, the right 84 cm)."""
    rig, arrival = cs.rig_throw_stage(tmp_path, "ue", -0.2)
    out = tmp_path / "sim.usdc"
    report = physics_pass.run(rig.path, out, mpc.Options(horizon_s=0.6))[0]  # the command's step: 0.03 for a catch
    assert not report.fell and report.timestep_s == 0.03
    composed = cs.composed(rig.path, out, tmp_path / "composed.usda")
    k = int(round(1.2 * 30))  # the first frame the ball is at its arrival
    for stage, near in ((composed, True), (rig.path, False)):
        posed = measure.posed(str(stage), rig.skeleton)
        palm = {s: 0.5 * (posed.position(rig.leaf[f"hand_{s}"]) + posed.position(rig.leaf[f"middle1_{s}"]))[k]
                for s in "lr"}
        right, left = (np.linalg.norm(palm[s] - arrival) for s in "rl")
        assert (right < 0.10) == near and left > 0.3, (stage, right, left)
