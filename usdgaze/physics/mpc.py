"""Receding-horizon full-body control on MuJoCo: the planner (``usdgaze.planning.ddp``) tracking a
reference while the true simulation may be pushed, with the per-step measures a shot report needs.

Two processes, as in the paper: the planner's internal model (``plan``, no knowledge of external
forces or of what the eyes will see) and the simulation it drives (``sim``, with the push). Each
control step solves a window of ``horizon_s`` warm-started from the previous solution shifted by one
step, its new last control the reference's inverse-dynamics torques (``support.inverse_dynamics``: with
no ground, the weight then shared among the feet), then applies the first control.

One loop (``run``) serves the body alone (``BodyController``) and the coupled eyes, belief and body
(``physics.visuomotor``): both track the same target (``prepare``: the reference with its toes out of
the ground), warm-start and restart the solver the same way (``Shot.horizon``), and measure and stop
after a fall the same way; a ``Controller`` adds what it senses and plans besides the body.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, Sequence

import numpy as np

from usdgaze.physics import feasible, lookahead, support
from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.measures import (blown_up, foot_depth, foot_depths, foot_geoms, heading_errors_deg,
                                      joint_errors_deg, start_lift)
from usdgaze.physics.model import BodyModel
from usdgaze.physics.tasks import TaskFactory, judge_tasks, measure_tasks
from usdgaze.physics.tracking import BodyTracking, Weights, clear_ground, lift_feet, resample, velocities

FALL_RATIO = 0.8  # the bar: pelvis below 80% of the reference's height is a fall
# The most regularization a window of the coupled loop starts from (``ddp.RecedingHorizon(carry_max=)``,
# ``physics.visuomotor``; the body-only loop carries mu as before: with this cap its whole CMU walk
# kept 3.07 deg but its deepest foot went from 1.7 to 4.0 cm, docs/physics.md): a toe whose
# contact starts within the 1.5 cm ground margin gets the contact's whole damping at once (its hinge
# jumped 8-11 rad/s in one step on the stones walk), so line searches straddling that event fail at
# every step size and mu grows 1e4-1e7 within a solve; carried on, the coupled stones walk's
# solver took no real step for 0.4 s and fell (docs/physics.md). 1e-2 is small against the torque
# cost's own curvature on the motors' controls, 2 w_eng gear^2 (0.008 at the toes, 1.25 at the hips).
MU_CARRY_MAX = 1e-2


@dataclass
class Push:
    """An external force (N, model world) on one body over ``[start_s, start_s + duration_s)``."""

    body: int
    force: np.ndarray
    start_s: float
    duration_s: float


@dataclass
class Options:
    h: float = 0.02
    # A shot with a ball to catch or moving obstacles and no stepping stones: its step (None: ``h``). The
    # paper sets h to 0.02 or 0.03 s by task; the catch keeps its bar at 0.03 at about 1.5x the frames/s,
    # the stones do not (docs/physics.md, "The step by task").
    moving_h: float | None = 0.03
    horizon_s: float = 0.6
    # A shot with stepping stones: its window (None: ``horizon_s``); the paper's varies by task, 0.6-1.2 s.
    # 1.0 landed 12 of 12 bar shots, 0.6 landed 11 (``physics.lookahead``; docs/physics-log.md).
    stones_horizon_s: float | None = 1.0
    iterations: int = 1  # solver iterations a step after the first window
    # The physics pass simulates a shot with a problem (a fall, a stone missed, an obstacle touched) again
    # with this many, and once more with twice as many where that fails too (none where it is <=
    # iterations; ``passes.physics.retry_ladder``): with one, 3 of 12 stepping-stone shots fell, and
    # throws fell in 1 of 5 in some configurations (docs/physics-log.md, "A shot with a problem is
    # simulated again", "A third simulation").
    retry_iterations: int = 2
    first_iterations: int = 5
    workers: int = 1  # threads for the window's finite differences
    fd_stride: int = 1  # finite differences every this many steps of the window, interpolated between
    # > 1: a step's finite differences are kept from earlier windows for up to this many solves (past the
    # window's first reuse.FD_FRESH steps, which are taken anew each solve); 1: every step anew
    fd_reuse: int = 1
    stop_after_fall_s: float = 0.2  # simulation ends this long after the pelvis first stays below the bar
    # The states kept (and written) with each foot MuJoCo's soft ground let sink lifted out of it by its
    # leg (``tracking.lift_feet``, as the reference is); ``Result.contact_depth_m`` keeps how deep the
    # simulation sank it. False: the simulated states as they are.
    ground_feet: bool = True
    weights: Weights = field(default_factory=Weights)


@dataclass
class Result:
    """One simulated shot, per control step ``k`` (time ``seconds[k]``)."""

    seconds: np.ndarray
    qpos: np.ndarray  # (K, nq) simulated
    ref_qpos: np.ndarray  # (K, nq)
    ctrl: np.ndarray  # (K - 1, nu)
    pelvis_ratio: np.ndarray  # (K,) simulated / reference base height
    joint_error_deg: np.ndarray  # (K,) mean over simulated joints
    foot_below_ground_m: np.ndarray  # (K,) deepest foot point of ``qpos`` below z = 0 (0 if none)
    solve_costs: list[list[float]]
    fell_at: float | None  # seconds of the first frame below FALL_RATIO, or of the last one a diverged run reached
    task_terms: dict[str, np.ndarray] = field(default_factory=dict)  # "task.measure" -> (K,), NaN at k = 0
    diverged: bool = False  # MuJoCo's step blew up (the run stopped early without a fall)
    task_problems: list[str] = field(default_factory=list)  # what the tasks judged on the whole run, in words
    task_unmendable: list[str] = field(default_factory=list)  # of those, what another simulation cannot mend
    reference_notes: list[str] = field(default_factory=list)  # what in the reference no body can follow
    # (K,) the simulated feet's depth in the soft ground before ``Options.ground_feet`` lifted them
    # (None: not lifted, ``foot_below_ground_m``; see ``sank_m``)
    contact_depth_m: np.ndarray | None = None

    @property
    def sank_m(self) -> np.ndarray:
        """(K,) how deep the simulation's soft ground let the feet sink, before any lift."""
        return self.foot_below_ground_m if self.contact_depth_m is None else self.contact_depth_m

    @property
    def fell(self) -> bool:
        return self.fell_at is not None

    @property
    def root_drift_m(self) -> np.ndarray:
        """(K,) horizontal distance of the simulated root from the reference's (the model is Z-up, in
        metres): a body that slides or tiptoes away stays up, and only this says so."""
        return np.linalg.norm(self.qpos[:, :2] - self.ref_qpos[:, :2], axis=1)

    @property
    def heading_error_deg(self) -> np.ndarray:
        """(K,) how far the base turned about the vertical from the reference's (:func:`heading_errors_deg`)."""
        return heading_errors_deg(self.qpos, self.ref_qpos)


@dataclass
class Shot:
    """What a receding-horizon loop runs on, made once from the reference (``prepare``): the planner's
    body (``plan``: no external force is known to it) and the simulated one (``sim``: pushed), the
    reference at steps of ``h`` (``ref_q``: what the measures compare with, raised as the body starts,
    ``measures.start_lift``), the planner's target
    (``target``: its toes out of the ground, ``tracking.clear_ground``) with its velocities, the
    tracking cost, the tasks, and the target's inverse-dynamics controls (``tail``)."""

    model: BodyModel
    ref_seconds: np.ndarray
    h: float
    plan: MujocoBody
    sim: MujocoBody
    ref_q: np.ndarray
    target: np.ndarray
    ref_v: np.ndarray
    tracking: BodyTracking
    tasks: list
    tail: np.ndarray
    n: int  # steps of a window
    steps: int
    """Steps simulated; the reference (``ref_q``, ``target``) may run on past them, for the planner's
    windows near the shot's end (a shot cut from a longer take)."""

    def pad(self, k: int, lead: int = 0) -> np.ndarray:
        """The control a window ending at step ``k`` appends: ``lead`` zeros (the eye's, in the coupled
        loop), then the target's inverse-dynamics torques (held past the reference's end)."""
        return np.r_[np.zeros(lead), self.tail[min(k, len(self.tail) - 1)]]

    def horizon(self, options: Options, lead: int = 0, carry_max: float | None = None):
        """The receding-horizon solver: ``first_iterations`` on the cold first window, ``iterations``
        after, the regularization restarted after a solve that ended at its ceiling and, with
        ``carry_max`` (the coupled loop's ``MU_CARRY_MAX``), carried to the next window at most that."""
        from usdgaze.planning import ddp

        return ddp.RecedingHorizon(self.n, lead + self.plan.nu, ddp.Options(max_iter=options.iterations),
                                   U_init=np.array([self.pad(i, lead) for i in range(self.n)]),
                                   first=ddp.Options(max_iter=options.first_iterations), restart_at_ceiling=True,
                                   carry_max=carry_max)


def prepare(model: BodyModel, ref_qpos_frames: np.ndarray, ref_seconds: np.ndarray, options: Options,
            pushes: tuple[Push, ...] = (), tasks: Sequence[TaskFactory] = (), lead: Sequence = (),
            ahead: tuple[np.ndarray, np.ndarray] | None = None) -> Shot:
    """The :class:`Shot` of a reference (``qpos`` per frame at ``ref_seconds``), pushes and tasks;
    ``lead``: parts ahead of the body in the planner's state (the coupled loop's eye), stacked with it
    before the costs and tasks are made, so these see the body's slices of that state; ``ahead``:
    the take's frames after the shot (``qpos``, seconds), which only the planner's windows see.

    Without ``ahead`` a window reaching past the shot's end tracks its last pose held, with its
    velocity: mid-stride, a walk asked to stop dead in 0.6 s. Its stones shot (4.0-5.5 s of CMU
    131_01, Stone10 15 cm toward -X, seed 1) fell at 1.48 s of 1.5; tracking the take on, it stands."""
    import mujoco

    from usdgaze.planning.compose import Stacked

    h = options.h
    steps = int(np.ceil((ref_seconds[-1] - ref_seconds[0]) / h - 1e-6))  # as resample covers the shot
    if ahead is not None and len(ahead[1]):
        keep = ahead[1] <= ref_seconds[-1] + options.horizon_s + 2 * h
        ref_qpos_frames = np.concatenate([ref_qpos_frames, ahead[0][keep]])
        ref_seconds = np.concatenate([ref_seconds, ahead[1][keep]])
    plan = MujocoBody(model, h=h, workers=options.workers, stride=options.fd_stride, reuse=options.fd_reuse)
    sim = MujocoBody(model, h=h, forces=_schedule(model, pushes, h, plan.mj.nbody))
    if lead:
        Stacked([*lead, plan])
    ref_q = resample(ref_qpos_frames, ref_seconds, h, plan)
    target = clear_ground(plan, ref_q)  # what the planner tracks; the measures use the reference as is
    # A reference whose first frame is in the floor is tracked raised as it starts: tracked as it is,
    # a body started on one toe 5 cm up pushed itself off the ground (a 0.4 s flight at h 0.03).
    lift = start_lift(plan.mj, mujoco.MjData(plan.mj), target[0])
    target[:, 2] += lift
    # The measures' reference is raised with it: a walk set 2 m below the stage's ground was said to keep its
    # pelvis at 94908900% of the reference's (a height clamped to 1 um), and could never be said to fall.
    ref_q = ref_q.copy()
    ref_q[:, 2] += lift
    target = lift_feet(plan, target)  # then a foot still in the ground is lifted by its leg
    ref_v = velocities(target, h, plan.mj)
    tracking = BodyTracking(plan, target, ref_v, _head_body(model), options.weights)
    n = max(2, int(round(options.horizon_s / h)))
    made = [lookahead.limit(factory(plan, target), n, h) for factory in tasks]  # the stones' 0.6 s
    return Shot(model, ref_seconds, h, plan, sim, ref_q, target, ref_v, tracking, made,
                support.inverse_dynamics(plan, target, ref_v, h), n, steps)


class Controller(Protocol):
    """The planning side of a control step: what ``run`` asks at each step ``k`` of the body state
    ``xb`` (``data``: a ``mujoco.MjData`` at the simulated state, kinematics done)."""

    def sense(self, k: int, xb: np.ndarray, data) -> None:
        """Observe at step ``k`` (also at the last state, after the last control)."""

    def control(self, k: int, xb: np.ndarray, data) -> tuple[np.ndarray, Sequence[float]]:
        """The body's control for step ``k`` and the solve's cost per iteration."""

    def advance(self, k: int) -> None:
        """The body took step ``k`` (parts the controller simulates itself, the eyes, follow)."""


class BodyController:
    """The body alone: tracking plus tasks over the MuJoCo body, one warm-started window a step."""

    def __init__(self, shot: Shot, options: Options) -> None:
        from usdgaze.planning.compose import CostSum

        self.shot, self.solver = shot, shot.horizon(options)
        self.cost = CostSum([shot.tracking, *shot.tasks]) if shot.tasks else shot.tracking

    def sense(self, k: int, xb: np.ndarray, data) -> None:
        return None

    def control(self, k: int, xb: np.ndarray, data):
        self.solver.U[-1] = self.shot.pad(k + self.shot.n - 1)
        u, sol = self.solver.step(self.shot.plan, self.cost, xb, k)
        return u, sol.costs

    def advance(self, k: int) -> None:
        return None


def simulate(model: BodyModel, ref_qpos_frames: np.ndarray, ref_seconds: np.ndarray, options: Options = Options(),
             pushes: tuple[Push, ...] = (), progress=None, tasks: Sequence[TaskFactory] = (),
             ahead: tuple[np.ndarray, np.ndarray] | None = None) -> Result:
    """Track the reference (``qpos`` per frame at ``ref_seconds``) for its whole length, plus tasks
    (``ahead``: see :func:`prepare`)."""
    from usdgaze.planning import ddp  # noqa: F401  (loads the solver's LAPACK before run's thread limit)

    shot = prepare(model, ref_qpos_frames, ref_seconds, options, pushes, tasks, ahead=ahead)
    return run(shot, options, BodyController(shot, options), progress)


def run(shot: Shot, options: Options, controller: Controller, progress=None) -> Result:
    """The receding-horizon loop of both the body-only and the coupled controller: per step, sense,
    plan and apply the first control to the simulated body, measure; stop at a blow-up or
    ``stop_after_fall_s`` after a fall."""
    import mujoco
    from threadpoolctl import threadpool_limits

    from usdgaze.planning import ddp  # noqa: F401  (its LAPACK loaded outside the thread limit)

    plan, sim, h, steps, ref_q = shot.plan, shot.sim, shot.h, shot.steps, shot.ref_q
    qpos = np.zeros((steps + 1, plan.nq))
    qpos[0], qvel = shot.target[0], shot.ref_v[0].copy()
    ctrl, costs, measured = np.zeros((steps, plan.nu)), [], {}
    feet = foot_geoms(plan.mj, shot.model)
    depth = np.zeros(steps + 1)
    d = mujoco.MjData(plan.mj)
    d.qpos[:] = qpos[0]
    mujoco.mj_kinematics(plan.mj, d)
    down, kk = 0, steps + 1
    with threadpool_limits(1):  # small dense matrices: BLAS threads only contend
        for k in range(steps + 1):
            plan.set_anchor(ref_q[k, 3:7])
            sim.set_anchor(ref_q[k, 3:7])
            x = plan.to_state(qpos[k], qvel)
            controller.sense(k, x, d)
            if k == steps:
                break
            u, solve_costs = controller.control(k, x, d)
            costs.append([float(c) for c in solve_costs])
            xn = sim.step_body(x, u, k)
            if not np.all(np.isfinite(xn)):
                kk = k + 1
                break
            q_next, v_next = sim.to_mujoco(xn)
            if blown_up(q_next, v_next, ref_q[k + 1], shot.model.height):
                kk = k + 1
                break
            controller.advance(k)
            qpos[k + 1], qvel = q_next, v_next
            ctrl[k] = u
            down = down + 1 if qpos[k + 1, 2] < FALL_RATIO * ref_q[k + 1, 2] else 0
            d.qpos[:] = qpos[k + 1]
            mujoco.mj_kinematics(plan.mj, d)
            depth[k + 1] = foot_depth(plan.mj, d, feet)
            measure_tasks(shot.tasks, k + 1, d, measured)
            if progress:
                progress(k + 1, steps)
            if down * h >= options.stop_after_fall_s:  # on the ground: nothing left to control
                kk = k + 2
                controller.sense(k + 1, plan.to_state(qpos[k + 1], qvel), d)
                break
    grounded = _grounded(plan, qpos[:kk], depth[:kk], feet) if options.ground_feet else None
    written, depth, sank = grounded or (qpos[:kk], depth, None)
    result = shot_result(shot.model, written, ref_q, shot.ref_seconds, ctrl, depth, costs, measured, steps, h)
    result.contact_depth_m = sank
    result.task_problems, result.task_unmendable = judge_tasks(shot.tasks, result)
    sliding = feasible.sliding_stance(feasible.toe_paths(plan, ref_q[:steps + 1]), h)
    task_notes = [n for t in shot.tasks if hasattr(t, "notes") for n in t.notes(float(result.seconds[0]))]
    result.reference_notes = ([sliding] if sliding else []) + task_notes
    return result


def _grounded(plan: MujocoBody, qpos: np.ndarray, depth: np.ndarray, feet: np.ndarray):
    """The simulated states with each foot the soft ground let sink lifted out by its leg
    (``Options.ground_feet``), their feet's depths, and the simulation's own."""
    lifted = lift_feet(plan, qpos)
    return lifted, foot_depths(plan.mj, lifted, feet), depth.copy()


def shot_result(model: BodyModel, qpos, ref_q, ref_seconds, ctrl, depth, costs, measured, steps: int,
                h: float) -> Result:
    """The :class:`Result` of a simulation that ran ``len(qpos)`` of ``steps + 1`` states: fall,
    pelvis ratio and joint errors against the reference, per-step arrays cut to that length."""
    kk = len(qpos)
    ratio = qpos[:, 2] / np.maximum(ref_q[:kk, 2], 1e-6)
    low = np.flatnonzero(ratio < FALL_RATIO)
    seconds = ref_seconds[0] + h * np.arange(kk)
    diverged = not len(low) and kk < steps + 1
    fell = float(seconds[low[0]]) if len(low) else (float(seconds[-1]) if diverged else None)
    return Result(seconds=seconds, qpos=qpos, ref_qpos=ref_q[:kk], ctrl=ctrl[: kk - 1], pelvis_ratio=ratio,
                  joint_error_deg=joint_errors_deg(model, qpos, ref_q[:kk]), foot_below_ground_m=depth[:kk],
                  solve_costs=costs, fell_at=fell, diverged=bool(diverged),
                  task_terms={key: np.array(v + [np.nan] * (kk - len(v)))[:kk] for key, v in measured.items()})


def _schedule(model: BodyModel, pushes, h: float, nbody: int):
    if not pushes:
        return None

    def forces(k: int) -> np.ndarray:
        out = np.zeros((nbody, 6))
        t = k * h
        for p in pushes:
            if p.start_s <= t + 1e-9 < p.start_s + p.duration_s:
                out[p.body + 1, :3] += p.force
        return out

    return forces


def _head_body(model: BodyModel) -> int:
    heads = [b for b, r in enumerate(model.role) if r == "head" and model.kind[b] != "weld"]
    return (heads[-1] if heads else len(model.bodies) - 1) + 1
