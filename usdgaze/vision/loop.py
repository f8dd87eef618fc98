"""The visuomotor closed loop: sense, update beliefs, plan a window with DDP, act one step, repeat.

Pure numpy. Inputs are the base gaze chain and the objects' true positions on the planner's time
grid (t_k = k h, metres); outputs are the eye pose, the chain offsets, the point of sight and each
object's estimate and uncertainty per step.

Each step k:
1. sense: an object is observed when some part of it (its radius; 0 a point) is inside the +-60 deg
   field of view of the head (``belief.in_view``); z = p + N(0, r I) from a seeded generator, r from the true distance to the point of sight.
   A newly seen object starts a filter; a known one gets the Kalman update (prediction only when
   unseen); one whose sigma_p exceeds ``drop_sigma`` is forgotten until seen again.
2. choose at most ``max_tracked`` known objects for the optimization: highest importance first, then
   nearest to the eyes (every known object keeps being updated).
3. plan: DDP over the window on the stacked [eye, body, belief] dynamics with the expected-mean belief,
   started from the cheapest (by the same cost) of the previous window's solution shifted by one step
   and one look-at proposal per object (saccade to its predicted path, then pursue it). DDP is local,
   and the observation noise r flattens out far from the point of sight, so an object a few metres
   from where the eyes look gives the solver no gradient: the proposals let it consider looking there.
4. act: apply the first control; the eye velocity is clipped to the speed bound of that instant and
   the eye stops at its range (``eye.limit``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.planning import ddp
from usdgaze.planning.compose import Stacked
from usdgaze.planning.kinbody import BaseChain, KinematicBody
from usdgaze.vision import eye as eyemod
from usdgaze.vision.belief import GRAVITY, Belief, VisionParams, in_view, kalman_update, noise
from usdgaze.vision.costs import AttendCost, Weights

MODES = ("uncertainty", "distance", "sequential")
LOCK_AFTER_STEPS = 8
PROPOSE_EVERY = 4  # planner steps between look-at proposals (100 ms), and whenever the slots change
PROPOSAL_MARGIN = np.array([np.radians(2.0), np.radians(2.0), 0.5])  # inside the eye range (rad, rad, mm)
# ... and at the far end of the focal range a twentieth of that: the distance is zeta/17 / (1 - zeta/17)
# metres, so 0.5 mm under the top (16.5 mm, 33 m) stopped proposals at 16 m, and an object 20 m away
# was never looked at (the observation noise grows with the distance from the point of sight to it).
PROPOSAL_MARGIN_HI = np.array([np.radians(2.0), np.radians(2.0), 0.025])
PROPOSAL_SPEED = 0.97  # of the speed bound


@dataclass
class Thing:
    """One object: true positions per planner step (K, 3) in metres, importance (scalar or (K,)), radius
    (m, its size for the field of view; 0: a point), kind."""

    name: str
    positions: np.ndarray
    importance: float | np.ndarray = 1.0
    radius: float = 0.0
    kind: str = ""

    @property
    def accel(self) -> np.ndarray:
        """The brain's process model: gravity for thrown things, none for the rest."""
        return np.array([0.0, 0.0, 0.0]) if self.kind != "ballistic" else -GRAVITY * self.up

    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    visible: np.ndarray | None = None
    """(K,) whether it is drawn at each step (an invisible object is not seen); None: always."""

    def visible_at(self, k: int) -> bool:
        return True if self.visible is None else bool(self.visible[min(k, len(self.visible) - 1)])

    def importance_at(self, k: int) -> float:
        imp = np.atleast_1d(self.importance)
        return float(imp[min(k, len(imp) - 1)])


@dataclass
class LoopOptions:
    alpha: float = 0.2
    alpha_per_second: bool = True  # Q = alpha h I a step; False: the literal alpha I a step
    eta: float = 0.3
    h: float = 0.025
    window_s: float = 0.8
    mode: str = "uncertainty"
    seed: int = 0
    max_tracked: int = 4
    drop_sigma: float = 4.0  # sigma_p above which a track is dropped (unit_m^2: 20 cm standard deviation)
    sigma_v0: float = 100.0  # velocity variance of a new track, in unit_m^2 / s^2 (1 (m/s)^2)
    unit_m: float = 0.1
    iterations: int = 3
    start_distance_m: float = 2.0
    weights: Weights = field(default_factory=Weights)


@dataclass
class LoopResult:
    eye: np.ndarray  # (K, 3) theta, psi (rad), zeta (mm)
    offsets: np.ndarray  # (K, 4) spine yaw/pitch, neck yaw/pitch (rad)
    sight: np.ndarray  # (K, 3) point of sight (m)
    estimate: np.ndarray  # (K, O, 3), NaN while untracked
    sigma_p: np.ndarray  # (K, O), NaN while untracked
    visible: np.ndarray  # (K, O) bool: observed this step
    optimized: np.ndarray  # (K, O) bool: in the planner's slots this step
    eyes: np.ndarray | None = None  # (K, 3) eye midpoint (m)
    solves: list[list[float]] = field(default_factory=list)  # cost per iteration, per step


class Filters:
    """Known objects' beliefs (mu 6, sigma 3), keyed by object index."""

    def __init__(self, things: list[Thing], opts: LoopOptions) -> None:
        self.things, self.opts = things, opts
        self.params = VisionParams(opts.alpha, opts.eta, opts.h, opts.unit_m, opts.alpha_per_second)
        self.mu: dict[int, np.ndarray] = {}
        self.sig: dict[int, np.ndarray] = {}
        self.rng = np.random.default_rng(opts.seed)
        self.age: dict[int, int] = {}

    def sense(self, k: int, eyes: np.ndarray, forward: np.ndarray, pps: np.ndarray) -> np.ndarray:
        """Observe every object in view from ``eyes`` (head ``forward``) looking at ``pps``; which were seen."""
        seen = np.zeros(len(self.things), bool)
        for j, th in enumerate(self.things):
            p = th.positions[min(k, len(th.positions) - 1)]
            seen[j] = th.visible_at(k) and bool(in_view(p, eyes, forward, th.radius))
            z = r = None
            if seen[j]:
                r = float(noise(pps, p, self.opts.eta)[0])
                z = p + self.params.unit_m * np.sqrt(r) * self.rng.standard_normal(3)
            if j in self.mu:
                self.age[j] = self.age.get(j, 0) + 1
                self.mu[j], self.sig[j] = kalman_update(self.mu[j], self.sig[j], z, r or 0.0, th.accel, self.params)
                if self.sig[j][0] > self.opts.drop_sigma:
                    del self.mu[j], self.sig[j], self.age[j]
            elif seen[j]:
                self.mu[j] = np.concatenate([z, np.zeros(3)])
                self.sig[j] = np.array([r, self.opts.sigma_v0, 0.0])
        return seen

    def choose(self, k: int, eyes: np.ndarray, seen: np.ndarray) -> list[int]:
        """Most important first; among equals the ones in view, then the nearest."""
        ranked = sorted(self.mu, key=lambda j: (-self.things[j].importance_at(k), not seen[j],
                                                np.linalg.norm(self.mu[j][:3] - eyes), j))
        return ranked[: self.opts.max_tracked]


def _arrival_order_target(filters: Filters, slots: list[int], eyes: np.ndarray, done: set[int],
                          locked: list[int]) -> int:
    """Sequential tracking: the slot of the object expected to arrive first (closest approach soonest),
    kept until it arrives (``locked`` holds the object being followed)."""
    if locked and locked[0] in slots and locked[0] not in done:
        return slots.index(locked[0])
    settled = [j for j in slots if filters.age.get(j, 0) >= LOCK_AFTER_STEPS]
    best, best_t = 0, np.inf
    ts = np.arange(0.0, 3.0, 0.02)
    for s, j in enumerate(slots):
        if j in done:
            continue
        mu, a = filters.mu[j], filters.things[j].accel
        path = mu[:3] + ts[:, None] * mu[3:] + 0.5 * ts[:, None] ** 2 * a
        t = ts[int(np.argmin(np.linalg.norm(path - eyes, axis=1)))]
        if t < best_t:
            best, best_t = s, t
    if any(slots[best] == j for j in settled):  # lock once its velocity estimate has had time to form
        locked[:] = [slots[best]]
    return best


def _look_at_controls(stack, X: np.ndarray, U: np.ndarray, k0: int, target: np.ndarray) -> np.ndarray:
    """Eye controls that saccade to ``target`` (N+1, 3) along the head motion of X, then pursue it.

    Each step moves the eye straight toward the target's eye angles as fast as the speed bound of
    that instant allows; the focal length follows the target's distance.
    """
    eye = stack["eye"]
    sight = next(p.sight for p in stack.parts if hasattr(p, "sight"))
    p, R = sight._poses(X, k0)
    local = np.einsum("nji,nj->ni", R, target - p)
    want = np.column_stack([eyemod.angles_for(local), eyemod.zeta_for(np.linalg.norm(local, axis=1))])
    # Just inside the range and the speed bound: the cost's soft bounds already charge the edge itself
    # (smax(0) = gamma / 2), which would price a proposal that only touches them above the warm start.
    want = np.clip(want, eyemod.LO + PROPOSAL_MARGIN, eyemod.HI - PROPOSAL_MARGIN_HI)
    h = eye.h
    out = U.copy()
    e = X[0, eye.xs].copy()
    for i in range(len(U)):
        de = (want[i + 1] - e) / h
        bound = PROPOSAL_SPEED * float(eyemod.speed_bound((k0 + i) * h))
        speed = np.hypot(de[0], de[1])
        if speed > bound:
            de[:2] *= bound / speed
        out[i, eye.us] = de
        e = e + h * de
    return out


def seed_controls(stack, cost, x: np.ndarray, U: np.ndarray, k: int, targets: list[np.ndarray]) -> np.ndarray:
    """The cheapest start among the warm start and one look-at proposal per target (same cost)."""
    best_U = U
    X = ddp.rollout(stack, x, U, k)
    best = ddp.total_cost(cost, X, U, k)
    for tgt in targets:
        cand = _look_at_controls(stack, X, U, k, tgt)
        J = ddp.total_cost(cost, ddp.rollout(stack, x, cand, k), cand, k)
        if J < best:
            best, best_U = J, cand
    return best_U


def run(base: BaseChain, things: list[Thing], opts: LoopOptions, n_steps: int, progress=None) -> LoopResult:
    """Simulate ``n_steps`` planner steps of the visuomotor loop."""
    if opts.mode not in MODES:
        raise ValueError(f"cost mode {opts.mode!r}: expected one of {', '.join(MODES)}")
    horizon = int(round(opts.window_s / opts.h))
    h, n_obj = opts.h, len(things)
    body = KinematicBody(base, h)
    eye = eyemod.Eye(h)
    filters = Filters(things, opts)
    mpc = ddp.RecedingHorizon(horizon, eye.nu + body.nu, ddp.Options(max_iter=opts.iterations, tol=1e-3, mu_init=1.0, mu_min=1e-2,
                                                                          alphas=(1.0, 0.3, 0.1, 0.03)))
    e = np.array([0.0, 0.0, float(eyemod.zeta_for(opts.start_distance_m))])
    qb = np.zeros(body.nx)
    out = LoopResult(np.zeros((n_steps, 3)), np.zeros((n_steps, 4)), np.zeros((n_steps, 3)),
                     np.full((n_steps, n_obj, 3), np.nan), np.full((n_steps, n_obj), np.nan),
                     np.zeros((n_steps, n_obj), bool), np.zeros((n_steps, n_obj), bool))
    out.eyes = np.zeros((n_steps, 3))
    done: set[int] = set()
    locked: list[int] = []
    last_slots: list[int] = []
    for k in range(n_steps):
        sight = eyemod.Sight(eye, body)
        Stacked([eye, body])  # bind slices for the sensing pose
        x_pose = np.concatenate([e, qb])
        pps, p_eyes, R = (a[0] for a in sight.points(x_pose[None], k))
        out.visible[k] = filters.sense(k, p_eyes, R[:, 0], pps)
        out.eyes[k] = p_eyes
        for j in filters.mu:
            out.estimate[k, j] = filters.mu[j][:3]
            out.sigma_p[k, j] = filters.sig[j][0]
            if np.linalg.norm(filters.mu[j][:3] - p_eyes) < 0.8:  # arrived (caught)
                done.add(j)
        slots = filters.choose(k, p_eyes, out.visible[k])
        out.optimized[k, slots] = True
        belief = Belief(len(slots), np.array([things[j].accel for j in slots]).reshape(-1, 3), filters.params, sight)
        stack = Stacked([eye, body, belief])
        x = np.concatenate([e, qb] + [np.concatenate([filters.mu[j], filters.sig[j]]) for j in slots])
        target = _arrival_order_target(filters, slots, p_eyes, done, locked) if opts.mode == "sequential" else 0
        imp = np.array([things[j].importance_at(k) for j in slots])
        cost = AttendCost(stack, sight, imp, opts.weights, opts.mode if slots else "uncertainty", target)
        n_h = mpc.horizon + 1
        ts = h * np.arange(n_h)[:, None]
        targets = [filters.mu[j][:3] + ts * filters.mu[j][3:] + 0.5 * ts**2 * things[j].accel for j in slots]
        if k % PROPOSE_EVERY == 0 or slots != last_slots:
            mpc.U = seed_controls(stack, cost, x, mpc.U, k, targets)
        last_slots = slots
        u, sol = mpc.step(stack, cost, x, k)
        out.solves.append(sol.costs)
        out.eye[k], out.offsets[k], out.sight[k] = e, qb[:4], pps
        de = eyemod.limit(e, u[eye.us], float(eyemod.speed_bound(k * h)), h)
        e = e + h * de
        qb = _body_step(qb, u[eye.nu:], h, body)
        if progress:
            progress(k + 1, n_steps)
    return out


def fixations(res: LoopResult, h: float, within_deg: float = 5.0, min_s: float = 0.1) -> list[tuple[float, int]]:
    """(time s, object index or -1) at each change of what the planner fixates.

    An object is fixated when the line of sight passes within ``within_deg`` of its estimate; a
    fixation shorter than ``min_s`` is not a change (a saccade passing over an object).
    """
    v = res.sight - res.eyes
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    w = res.estimate - res.eyes[:, None]
    w /= np.linalg.norm(w, axis=2, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(np.einsum("ki,koi->ko", v, w), -1, 1)))
    ang = np.where(np.isnan(ang), np.inf, ang)
    best = np.argmin(ang, axis=1) if ang.shape[1] else np.zeros(len(v), int)
    on = np.where(ang[np.arange(len(v)), best] <= within_deg, best, -1) if ang.shape[1] else best - 1
    changes: list[tuple[float, int]] = []
    k, n = 0, len(on)
    while k < n:
        j = k
        while j < n and on[j] == on[k]:
            j += 1
        if (j - k) * h >= min_s and (not changes or changes[-1][1] != on[k]):
            changes.append((k * h, int(on[k])))
        k = j
    return changes


def _body_step(qb: np.ndarray, acc: np.ndarray, h: float, body) -> np.ndarray:
    """The simulated chain (a ``KinematicBody``): the model's step, its head speed clipped to
    ``HEAD_SPEED`` (as the eye's is to its bound: the planner sees both as soft costs), stopped at the
    offsets' range."""
    n = len(acc)
    qd = qb[n:] + h * acc
    speed = np.hypot(*body.head_rate(qd))
    if speed > body.HEAD_SPEED:
        qd = qd * (body.HEAD_SPEED / speed)
    q = qb[:n] + h * qd
    clipped = np.clip(q, body.LO, body.HI)
    qd = np.where(clipped != q, 0.0, qd)
    return np.concatenate([clipped, qd])
