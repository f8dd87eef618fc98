"""The paper's full system (Eom et al. 5-6): eyes and belief coupled to the MuJoCo body in one loop.

The planner's dynamics are the stacked parts ``[eye, MuJoCo body, belief]`` (``compose.Stacked``):
the eye and belief of ``usdgaze.vision`` read the simulated head through the body's
``head_pose_batch``/``head_jacobian_batch``. The cost is ``AttendCost`` (uncertainty, eye bounds;
its kinematic-body terms left out) + ``BodyTracking`` (reference, root-to-head vector, torques) +
the tasks. Two processes, as in the paper and ``vision/loop.py``: inside the optimizer the belief's
mean is its expectation (deterministic) and no external force is known; the simulation draws seeded
observations, applies the Kalman update, the pushes, and the eye's speed and range limits.

Each step k: sense from the simulated head (field of view, observation noise from the true distance
to the point of sight), choose the tracked objects, let tasks read the belief (``perceive``), seed the
window with look-at proposals (as ``vision.loop``), solve, apply the first control to the simulated
body and eye. Objects are in the model's world (metres, Z up).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from usdgaze.physics import mpc
from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.model import BodyModel
from usdgaze.physics.tracking import BodyTracking, resample, velocities
from usdgaze.planning import ddp
from usdgaze.planning.compose import CostSum, Stacked
from usdgaze.vision import eye as eyemod
from usdgaze.vision import loop
from usdgaze.vision.belief import Belief
from usdgaze.vision.costs import AttendCost, Weights


@dataclass
class Options:
    """The body's MPC settings (step, window, iterations) and the vision system's (alpha, eta, seed...);
    the vision options' ``h``, ``window_s`` and ``iterations`` are the body's."""

    body: mpc.Options = field(default_factory=mpc.Options)
    # A new track's velocity prior is (10 m/s)^2 (the speed of a throw is unknown when it is first seen): with
    # the kinematic loop's (1 m/s)^2 the filter needs ~1 s to learn a 7 m/s throw, too late to catch it.
    vision: loop.LoopOptions = field(default_factory=lambda: loop.LoopOptions(sigma_v0=1e4))


@dataclass
class Result:
    body: mpc.Result  # per step: simulated qpos, reference, measures, task terms
    vision: loop.LoopResult  # per step: eye pose, point of sight, estimates, uncertainty (offsets empty)


@dataclass
class Percept:
    """What a task may read before each solve: the simulated belief (not the true state)."""

    k: int
    h: float
    mu: dict[int, np.ndarray]  # object index -> [p, v] (m, m/s)
    sigma: dict[int, np.ndarray]  # object index -> [sigma_p, sigma_v, sigma_pv]
    things: list[loop.Thing]
    data: object  # mujoco.MjData at the simulated state, kinematics done
    seen: np.ndarray | None = None  # (objects,) bool: observed this step


def _vision_result(n: int, n_obj: int) -> loop.LoopResult:
    return loop.LoopResult(np.zeros((n, 3)), np.zeros((n, 0)), np.zeros((n, 3)), np.full((n, n_obj, 3), np.nan),
                           np.full((n, n_obj), np.nan), np.zeros((n, n_obj), bool), np.zeros((n, n_obj), bool),
                           eyes=np.zeros((n, 3)))


def _trim(v: loop.LoopResult, n: int) -> loop.LoopResult:
    return loop.LoopResult(v.eye[:n], v.offsets[:n], v.sight[:n], v.estimate[:n], v.sigma_p[:n], v.visible[:n],
                           v.optimized[:n], v.eyes[:n], v.solves[:n])


class _Problem:
    """One step's planning problem: the stack over the tracked slots, its cost and start state."""

    def __init__(self, eye, plan, filters: loop.Filters, slots: list[int], k: int, body_cost, tasks,
                 opts: loop.LoopOptions) -> None:
        things = filters.things
        self.sight = eyemod.Sight(eye, plan)
        accel = np.array([things[j].accel for j in slots]).reshape(-1, 3)
        self.stack = Stacked([eye, plan, Belief(len(slots), accel, filters.params, self.sight)])
        imp = np.array([things[j].importance_at(k) for j in slots])
        # The eye's energy only: the body's torques are priced by BodyTracking in N m.
        u_scale = np.r_[np.ones(eye.nu), np.zeros(plan.nu)]
        w = Weights(**{**opts.weights.__dict__, "u_scale": u_scale, "sigma_scale": np.array([1.0, eye.h**2, eye.h])})
        attend = AttendCost(self.stack, self.sight, imp, w, opts.mode if slots else "uncertainty", 0,
                            track_body=False)
        self.cost = CostSum([attend, body_cost, *tasks])
        self.slots = slots

    def state(self, e: np.ndarray, xb: np.ndarray, filters: loop.Filters) -> np.ndarray:
        return np.concatenate([e, xb] + [np.concatenate([filters.mu[j], filters.sig[j]]) for j in self.slots])


def simulate(model: BodyModel, ref_qpos_frames: np.ndarray, ref_seconds: np.ndarray, things: list[loop.Thing],
             options: Options = Options(), pushes: tuple[mpc.Push, ...] = (), tasks: Sequence[mpc.TaskFactory] = (),
             progress=None) -> Result:
    """Simulate body, eyes and belief over the reference's length; ``things``' positions per step of h."""
    import mujoco
    from threadpoolctl import threadpool_limits

    bo, vo = options.body, options.vision
    h = bo.h
    vo = loop.LoopOptions(**{**vo.__dict__, "h": h, "window_s": bo.horizon_s})
    plan = MujocoBody(model, h=h, workers=bo.workers, stride=bo.fd_stride)
    sim = MujocoBody(model, h=h, forces=mpc._schedule(model, pushes, h, plan.mj.nbody))
    eye = eyemod.Eye(h)
    Stacked([eye, plan])  # the slices every later stack gives the eye and the body
    ref_q = resample(ref_qpos_frames, ref_seconds, h, plan)
    ref_v = velocities(ref_q, h, plan.mj)
    tracking = BodyTracking(plan, ref_q, ref_v, mpc._head_body(model), bo.weights)
    made = [factory(plan, ref_q) for factory in tasks]
    filters = loop.Filters(things, vo)
    n = max(2, int(round(bo.horizon_s / h)))
    steps = len(ref_q) - 1
    tail = mpc._inverse_dynamics(plan, ref_q, ref_v, h)
    pad = lambda k: np.r_[np.zeros(eye.nu), tail[min(k, steps)]]  # noqa: E731
    solver = ddp.RecedingHorizon(n, eye.nu + plan.nu, ddp.Options(max_iter=bo.first_iterations),
                                 U_init=np.array([pad(i) for i in range(n)]))
    qpos = np.zeros((steps + 1, plan.nq))
    qpos[0] = ref_q[0]
    qvel = ref_v[0].copy()
    e = np.array([0.0, 0.0, float(eyemod.zeta_for(vo.start_distance_m))])
    ctrl, costs = np.zeros((steps, plan.nu)), []
    vis = _vision_result(steps + 1, len(things))
    feet = np.array([g for g in range(plan.mj.ngeom) if plan.mj.geom_bodyid[g] - 1 in mpc._foot_bodies(model)])
    depth = np.zeros(steps + 1)
    measured: dict[str, list[float]] = {}
    d = mujoco.MjData(plan.mj)
    d.qpos[:] = qpos[0]
    mujoco.mj_kinematics(plan.mj, d)
    down, last_slots, kk = 0, None, steps + 1
    with threadpool_limits(1):
        for k in range(steps + 1):
            plan.set_anchor(ref_q[k, 3:7])
            sim.set_anchor(ref_q[k, 3:7])
            xb = plan.to_state(qpos[k], qvel)
            slots = _sense(k, e, xb, eye, plan, filters, vis)
            if k == steps:
                break
            for task in made:
                if hasattr(task, "perceive"):
                    task.perceive(Percept(k, h, filters.mu, filters.sig, things, d, vis.visible[k]))
            prob = _Problem(eye, plan, filters, slots, k, tracking, made, vo)
            x = prob.state(e, xb, filters)
            solver.U[-1] = pad(k + n - 1)
            if k % loop.PROPOSE_EVERY == 0 or slots != last_slots:
                ts = h * np.arange(n + 1)[:, None]
                targets = [filters.mu[j][:3] + ts * filters.mu[j][3:] + 0.5 * ts**2 * things[j].accel for j in slots]
                solver.U = loop.seed_controls(prob.stack, prob.cost, x, solver.U, k, targets)
            last_slots = slots
            u, sol = solver.step(prob.stack, prob.cost, x, k)
            solver.options = ddp.Options(max_iter=bo.iterations)
            if solver.mu >= solver.options.mu_max:  # no step taken: the next window starts afresh (as mpc)
                solver.mu = solver.options.mu_init
            costs.append([float(c) for c in sol.costs])
            vis.solves.append(costs[-1])
            xn = sim.step_body(xb, u[plan.us], k)
            if not np.all(np.isfinite(xn)):
                kk = k + 1
                break
            e = e + h * eyemod.limit(e, u[eye.us], float(eyemod.speed_bound(k * h)), h)
            qpos[k + 1], qvel = sim.to_mujoco(xn)
            ctrl[k] = u[plan.us]
            down = down + 1 if qpos[k + 1, 2] < mpc.FALL_RATIO * ref_q[k + 1, 2] else 0
            d.qpos[:] = qpos[k + 1]
            mujoco.mj_kinematics(plan.mj, d)
            depth[k + 1] = mpc._foot_depth(plan.mj, d, feet)
            mpc.measure_tasks(made, k + 1, d, measured)
            if progress:
                progress(k + 1, steps)
            if down * h >= bo.stop_after_fall_s:  # on the ground: nothing left to control
                kk = k + 2
                _sense(k + 1, e, plan.to_state(qpos[k + 1], qvel), eye, plan, filters, vis)
                break
    return Result(mpc.shot_result(model, qpos[:kk], ref_q, ref_seconds, ctrl, depth, costs, measured, steps, h),
                  _trim(vis, kk))


def _sense(k: int, e: np.ndarray, xb: np.ndarray, eye, plan, filters: loop.Filters, vis: loop.LoopResult) -> list[int]:
    """Observe from the simulated head, record eye, sight and belief at step k; the slots to plan for."""
    sight = eyemod.Sight(eye, plan)
    x_pose = np.concatenate([e, xb])
    pps, p_eyes, R = (a[0] for a in sight.points(x_pose[None], k))
    vis.visible[k] = filters.sense(k, p_eyes, R[:, 0], pps)
    vis.eye[k], vis.sight[k], vis.eyes[k] = e, pps, p_eyes
    for j in filters.mu:
        vis.estimate[k, j] = filters.mu[j][:3]
        vis.sigma_p[k, j] = filters.sig[j][0]
    slots = filters.choose(k, p_eyes, vis.visible[k])
    vis.optimized[k, slots] = True
    return slots
