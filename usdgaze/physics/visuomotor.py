"""The paper's full system (Eom et al. 5-6): eyes and belief coupled to the MuJoCo body in one loop.

The planner's dynamics are the stacked parts ``[eye, MuJoCo body, belief]`` (``compose.Stacked``):
the eye and belief of ``usdgaze.vision`` read the simulated head through the body's
``head_pose_batch``/``head_jacobian_batch``. The cost is ``AttendCost`` (uncertainty, eye bounds;
its kinematic-body terms left out) + ``BodyTracking`` (reference, root-to-head vector, torques) +
the tasks. Two processes, as in the paper and ``vision/loop.py``: inside the optimizer the belief's
mean is its expectation (deterministic) and no external force is known; the simulation draws seeded
observations, applies the Kalman update, the pushes, and the eye's speed and range limits.

Each step k: sense from the simulated head (field of view, each object's radius, observation noise
from the true distance to the point of sight), choose the tracked objects, let tasks read the belief
(``perceive``), seed the window with look-at proposals (as ``vision.loop``), solve, apply the first
control to the simulated body and eye. Objects are in the model's world (metres, Z up). The loop itself is ``mpc.run`` (the body-only
controller's): the same target (the reference with its toes out of the ground), solver restarts, measures
and stop after a fall; this module adds the eyes and the belief as an ``mpc.Controller``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from usdgaze.physics import mpc
from usdgaze.physics.model import BodyModel
from usdgaze.physics.tasks import TaskFactory
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
             options: Options = Options(), pushes: tuple[mpc.Push, ...] = (), tasks: Sequence[TaskFactory] = (),
             progress=None, ahead: tuple[np.ndarray, np.ndarray] | None = None) -> Result:
    """Simulate body, eyes and belief over the reference's length; ``things``' positions per step of h
    (``ahead``: see :func:`usdgaze.physics.mpc.prepare`)."""
    bo = options.body
    eye = eyemod.Eye(bo.h)
    shot = mpc.prepare(model, ref_qpos_frames, ref_seconds, bo, pushes, tasks, lead=[eye], ahead=ahead)
    vo = loop.LoopOptions(**{**options.vision.__dict__, "h": bo.h, "window_s": bo.horizon_s})
    controller = _Coupled(shot, eye, things, bo, vo)
    body = mpc.run(shot, bo, controller, progress)
    return Result(body, _trim(controller.vis, len(body.qpos)))


class _Coupled:
    """The coupled loop's ``mpc.Controller``: senses from the simulated head, plans eye, body and belief
    in one window (seeded with a look-at proposal per tracked object at every step), and simulates the
    eye with its speed and range limits."""

    def __init__(self, shot: mpc.Shot, eye: eyemod.Eye, things: list[loop.Thing], bo: mpc.Options,
                 vo: loop.LoopOptions) -> None:
        self.shot, self.eye, self.things, self.vo = shot, eye, things, vo
        self.filters = loop.Filters(things, vo)
        self.solver = shot.horizon(bo, lead=self.eye.nu, carry_max=mpc.MU_CARRY_MAX)
        self.e = np.array([0.0, 0.0, float(eyemod.zeta_for(vo.start_distance_m))])
        self.vis = _vision_result(shot.steps + 1, len(things))
        self.slots: list[int] = []
        self.u = np.zeros(self.eye.nu + shot.plan.nu)

    def sense(self, k: int, xb: np.ndarray, data) -> None:
        self.slots = _sense(k, self.e, xb, self.eye, self.shot.plan, self.filters, self.vis)

    def control(self, k: int, xb: np.ndarray, data):
        shot, filters, solver, slots = self.shot, self.filters, self.solver, self.slots
        for task in shot.tasks:
            if hasattr(task, "perceive"):
                task.perceive(Percept(k, shot.h, filters.mu, filters.sig, self.things, data, self.vis.visible[k]))
        prob = _Problem(self.eye, shot.plan, filters, slots, k, shot.tracking, shot.tasks, self.vo)
        x = prob.state(self.e, xb, filters)
        n = shot.n
        solver.U[-1] = shot.pad(k + n - 1, self.eye.nu)
        # At every step, not every 100 ms as the kinematic loop (``loop.PROPOSE_EVERY``): with one solver
        # iteration a step the eyes drifted off a thrown ball between proposals, to where the noise term
        # gives the solver no gradient back (median 6.1 deg off it, 2.5 with this; docs/physics.md).
        if slots:
            ts = shot.h * np.arange(n + 1)[:, None]
            targets = [filters.mu[j][:3] + ts * filters.mu[j][3:] + 0.5 * ts**2 * self.things[j].accel for j in slots]
            solver.U = loop.seed_controls(prob.stack, prob.cost, x, solver.U, k, targets)
        self.u, sol = solver.step(prob.stack, prob.cost, x, k)
        self.vis.solves.append([float(c) for c in sol.costs])
        return self.u[shot.plan.us], sol.costs

    def advance(self, k: int) -> None:
        h = self.shot.h
        self.e = self.e + h * eyemod.limit(self.e, self.u[self.eye.us], float(eyemod.speed_bound(k * h)), h)


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
