"""The ball-catch task of Eom et al. (section 7): the hand to the ball's estimated arrival point.

``c_tsk = |p_hand - p_ball|^2 + |p_lat_ball - p_lat_sp|^2``: ``p_ball`` is where the ball is expected
to arrive, predicted from the character's *belief* (the simulated Kalman estimate, never the true
state) before each solve: where the estimated ballistic path crosses the catching plane, 35 cm in
front of the shoulders' midpoint, if that is within ``reach_m`` of the catching point 20 cm below.
The crossing is the exact root of the path's distance to the plane, and the path is the belief's own
process model (``_crossing``, ``perceive``). The shoulders are the reference's at that step (where
the character means to stand): a plane that followed the simulated body's sway would move a steeply
falling ball's crossing by tens of cm. ``p_sp`` is the midpoint of the feet (the support polygon's
centre), the lateral axis the character's left at the window's start.

Phases as the paper: reactive from a time drawn in 1.5-2 s before the estimated arrival (weight
1e-3), proactive from a time drawn in 0.5-1 s before it (weight 0.1) until the ball arrives (plus
``hold_s``); nothing before, nor while the belief's speed is less sure than 0.5 m/s (a new track's
arrival time is no estimate yet). Distances are in units of 2 cm (``unit_m``): the paper gives no unit.
In metres its 0.1 would price a 50 cm miss at 0.025 a step against the ~1 a step the tracking term
asks for the arm to leave the reference, so the hand would never rise; in centimetres (4 times the
2 cm price) the proactive pull leaned the standing body into falls (2 of the 5 bench throws, once
the arrival estimate was right); in 2 cm units the reactive weight lifts the arm part-way and the
proactive one takes the hand to the ball, as the paper tells, without a fall in those throws.
The lateral term charges only what lies beyond ``lateral_free_m`` (the paper: "if the arrival
position is laterally far from the character"); a plain square would step the character under every
ball. The catching hand is the one on the arrival's side, kept once the proactive phase starts; from
then on an estimate made while the ball is out of view (close below the face) does not move the
target: the hand waits where the ball was last expected.

Derivatives: the gradient is exact, the Hessian Gauss-Newton (``2 w J'J``), with the hand's and feet's
Jacobians from MuJoCo's ``mj_jac`` mapped to the state's minimal coordinates. The cost and its
derivatives are batched over the window (``cost_batch``, ``derivs_batch``: MuJoCo's kinematics per
state, the residuals and products over the steps whose phase weight is not zero at once); the
per-step methods are the same code on one step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from usdgaze.physics.dynamics import MujocoBody, _jr
from usdgaze.physics import segments
from usdgaze.physics.model import BodyModel
from usdgaze.vision.belief import VisionParams

_BELIEF_UNIT_M = VisionParams().unit_m  # the belief's covariances are in this unit squared


@dataclass
class CatchOptions:
    reactive_s: tuple[float, float] = (1.5, 2.0)  # the reactive phase starts this long before arrival
    proactive_s: tuple[float, float] = (0.5, 1.0)
    w_reactive: float = 1e-3
    w_proactive: float = 0.1
    unit_m: float = 0.02  # residuals in units of 2 cm (see the module docstring)
    ahead_m: float = 0.35  # the catching point: in front of the shoulders' midpoint...
    below_m: float = 0.2  # ...and below it
    reach_m: float = 1.2  # an arrival farther than this from the catching point is no catch
    lateral_free_m: float = 0.3
    hold_s: float = 0.1  # the task holds this long after the estimated arrival
    horizon_s: float = 3.0  # how far ahead the estimated path is searched
    max_speed_sd_m_s: float = 0.5  # no arrival (no phase) while the belief's speed is less sure than this


def _hand_sites(model: BodyModel) -> dict[str, tuple[int, np.ndarray]]:
    """'left'/'right' -> (MuJoCo body id, palm point in that body's frame): the first simulated hand
    body below each forearm, the palm halfway to its fingers' bases (children with two joints or more
    below them), else to its first child, else its centre of mass."""
    out = {}
    kids = segments.children_of(model.body_parent)
    for b, role in enumerate(model.role):
        parent = model.body_parent[b]
        if role != "hand" or parent < 0 or model.role[parent] != "forearm":
            continue
        fingers = [c for c in kids[b] if len(segments.subtree_of(kids, c)) >= 3]
        palm = (0.5 * model.offset[fingers].mean(axis=0) if fingers else
                0.5 * model.offset[kids[b][0]] if kids[b] else model.com[b])
        out.setdefault(_side(model, b), (b + 1, palm))
    return out


def can_catch(model: BodyModel) -> bool:
    """Whether the body has a hand below a forearm to catch with."""
    return bool(_hand_sites(model))


def _side(model: BodyModel, b: int) -> str:
    """Which side body ``b`` is on at rest: by the character's left where its forward is known (UE's
    ``hand_r`` does not start with r), else by the name."""
    if model.forward is None:
        return "right" if model.names[b].lower().startswith("r") else "left"
    left = np.cross([0.0, 0.0, 1.0], model.forward)
    return "left" if (model.rest_pos[b] - model.rest_pos[0]) @ left > 0 else "right"


class CatchTask:
    """A ``physics.tasks.Task`` for one ball (object index ``ball`` of the loop's things)."""

    name = "catch"

    def __init__(self, dyn: MujocoBody, ball: int, seed: int = 0, options: CatchOptions = CatchOptions(),
                 truth: np.ndarray | None = None, reference: np.ndarray | None = None) -> None:
        import mujoco

        self.dyn, self.ball, self.o = dyn, ball, options
        self.data = mujoco.MjData(dyn.mj)
        self.reference = reference  # qpos per step: the catching plane stands where the reference does
        self._ref_data = mujoco.MjData(dyn.mj)
        self.hands = _hand_sites(dyn.model)
        if not self.hands:
            raise ValueError("the body model has no hand below a forearm to catch with")
        m = dyn.model
        self.shoulders = [b + 1 for b, r in enumerate(m.role) if r == "upperArm"]
        self.feet = [b + 1 for b in m.feet]
        rng = np.random.default_rng(seed)
        self.t_reactive = float(rng.uniform(*options.reactive_s))
        self.t_proactive = float(rng.uniform(*options.proactive_s))
        self.truth = truth  # true ball positions per step, for the report only
        self.arrival = None  # (time s, point (3,)) from the latest belief
        self.left = np.array([0.0, 1.0, 0.0])
        self.hand = None
        self.locked = False

    # -- the belief: where and when the ball is expected ------------------------------------------
    def perceive(self, percept) -> None:
        """Estimate the arrival from the simulated belief and the simulated body (``percept.data``)."""
        import mujoco

        d, o = percept.data, self.o
        k, h = percept.k, percept.h
        if self.reference is not None:  # where the character means to stand, not where it sways to
            d = self._ref_data
            d.qpos[:] = self.reference[min(k, len(self.reference) - 1)]
            mujoco.mj_kinematics(self.dyn.mj, d)
        fwd = self._forward(d)
        self.left = np.cross([0.0, 0.0, 1.0], fwd)
        if self.ball not in percept.mu:
            self.arrival = None
            return
        if self.locked and percept.seen is not None and not percept.seen[self.ball]:
            return  # out of view in the last moments: catch where it was last expected, not where a guess drifts
        if not self.locked and np.sqrt(percept.sigma[self.ball][1]) * _BELIEF_UNIT_M > o.max_speed_sd_m_s:
            # A new track's speed prior is 10 m/s: the first estimates of the arrival time fall anywhere
            # (measured: 0.85 s ahead at 0.1 s into a 1.1 s throw, 80 cm off), and one inside the drawn
            # proactive lead would start and lock the strong pull on a wrong target. No estimate yet.
            self.arrival = None
            return
        mu, accel = percept.mu[self.ball], percept.things[self.ball].accel
        # The filter steps p += h v, v += h a (vision.belief.kalman_update), so the velocity it learns is
        # the step's mean, h a / 2 ahead of the true one: the continuous path from it would fall short by
        # a h t / 2 (6 cm after 0.6 s at h 0.02, always downward). Its own process model, continuous:
        mu = np.r_[mu[:3], mu[3:] - 0.5 * h * accel]
        mid = d.xpos[self.shoulders].mean(axis=0) if self.shoulders else d.xpos[1]
        point = mid + o.ahead_m * fwd - np.array([0.0, 0.0, o.below_m])
        arrival = _crossing(mu, accel, mid, fwd, o.ahead_m, o.horizon_s, h)
        if arrival is None or np.linalg.norm(arrival[1] - point) > o.reach_m:
            self.arrival = None if not self.locked else self.arrival
            return
        self.arrival = (k * h + arrival[0], arrival[1])
        if not self.locked:
            side = "left" if (arrival[1] - mid) @ self.left >= 0 else "right"
            self.hand = side if side in self.hands else next(iter(self.hands))
            self.locked = self.weight(k, h) >= o.w_proactive

    def _forward(self, d) -> np.ndarray:
        """The character's horizontal forward: the body's left (shoulders or thighs) crossed with up."""
        m = self.dyn.model
        pair = sorted((b for b, r in enumerate(m.role) if r == "thigh"), key=lambda b: _side(m, b) == "right")
        if len(pair) < 2:
            return np.array([1.0, 0.0, 0.0])
        left = d.xpos[pair[0] + 1] - d.xpos[pair[1] + 1]
        left[2] = 0.0
        left /= max(np.linalg.norm(left), 1e-9)
        return np.cross(left, [0.0, 0.0, 1.0])

    def weight(self, k: int, h: float) -> float:
        if self.arrival is None:
            return 0.0
        remaining = self.arrival[0] - k * h
        if -self.o.hold_s <= remaining <= self.t_proactive:
            return self.o.w_proactive
        if self.t_proactive < remaining <= self.t_reactive:
            return self.o.w_reactive
        return 0.0

    # -- the cost -------------------------------------------------------------------------------
    def _residuals(self, Xb: np.ndarray, jac: bool):
        """Residuals ``(n, 4)`` (palm to arrival, lateral excess, in ``unit_m``) of body states ``Xb``
        ``(n, 2 nv)`` and, with ``jac``, their Jacobians ``(n, 4, nv)`` in the state's coordinates.

        MuJoCo's kinematics (and Jacobians) run per state; the rest over the batch at once."""
        import mujoco

        d, dyn, o = self.data, self.dyn, self.o
        body, palm = self.hands[self.hand or next(iter(self.hands))]
        n, nv = len(Xb), dyn.nv
        p_hand, feet, lat = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
        jh, jf, jl = (np.zeros((n, 3, nv)), np.zeros((n, 3, nv)), np.zeros((n, nv))) if jac else (None, None, None)
        j = np.zeros((3, nv))
        for i in range(n):
            d.qpos[:] = dyn.qpos_of(Xb[i])
            mujoco.mj_kinematics(dyn.mj, d)
            p_hand[i] = d.xpos[body] + d.xmat[body].reshape(3, 3) @ palm
            feet[i] = np.add.reduce(d.xpos[self.feet], axis=0) / len(self.feet)  # mean's own sum and division
            lat[i] = float((self.arrival[1] - feet[i]) @ self.left)
            if jac:
                mujoco.mj_comPos(dyn.mj, d)
                mujoco.mj_jac(dyn.mj, d, jh[i], None, p_hand[i], body)
                for f in self.feet:
                    mujoco.mj_jacBody(dyn.mj, d, j, None, f)
                    jf[i] += j / len(self.feet)
                jl[i] = -(self.left @ jf[i])  # per state: BLAS's sums as the per-step term's, bit for bit
        live = np.abs(lat) > o.lateral_free_m
        excess = np.sign(lat) * np.maximum(np.abs(lat) - o.lateral_free_m, 0.0)
        r = np.concatenate([p_hand - self.arrival[1], excess[:, None]], axis=1) / o.unit_m
        if not jac:
            return r, None
        J = np.concatenate([jh, (jl * np.where(live, 1.0, 0.0)[:, None])[:, None]], axis=1) / o.unit_m
        rot = dyn._rot_x  # d(tangent)/dx = Jr(r) per rotation block, as one stack of (4, 3) @ (3, 3)
        maps = _jr(Xb[:, rot].reshape(-1, 3), inverse=False).reshape(n, len(rot), 3, 3)
        blocks = np.ascontiguousarray(J[:, :, rot].transpose(0, 2, 1, 3))
        J[:, :, rot] = np.matmul(blocks, maps).transpose(0, 2, 1, 3)
        return r, J

    def _weights(self, k0: int, n: int) -> np.ndarray:
        return np.array([self.weight(k0 + i, self.dyn.h) for i in range(n)])

    def cost_batch(self, X, U, k0):
        w = self._weights(k0, len(U))
        out = np.zeros(len(U))
        on = np.flatnonzero(w)
        if len(on):
            r, _ = self._residuals(X[on][:, self.dyn.xs], False)
            out[on] = w[on] * np.array([ri @ ri for ri in r])  # BLAS's dot, as the per-step term
        return out

    def derivs_batch(self, X, U, k0):
        """Exact gradient ``2 w J'r`` and Gauss-Newton Hessian ``2 w J'J`` of the window's steps."""
        n, nx, nu = len(U), X.shape[1], U.shape[1]
        w = self._weights(k0, n)
        lx, lxx = np.zeros((n, nx)), np.zeros((n, nx, nx))
        on = np.flatnonzero(w)
        if len(on):
            xs, nv = self.dyn.xs, self.dyn.nv
            r, J = self._residuals(X[on][:, xs], True)
            pos = slice(xs.start, xs.start + nv)
            wJt = (2 * w[on, None, None] * J).transpose(0, 2, 1)
            # per step, the per-step term's BLAS calls on the same layouts: its bits, not another sum order's
            lx[on, pos] = [a @ b for a, b in zip(wJt, r)]
            lxx[on, pos, pos] = [a @ b for a, b in zip(wJt, J)]
        return lx, np.zeros((n, nu)), lxx, np.zeros((n, nu, nu)), np.zeros((n, nu, nx))

    def l(self, x, u, k):
        return float(self.cost_batch(x[None], u[None], k)[0])

    def derivs(self, x, u, k):
        return tuple(a[0] for a in self.derivs_batch(x[None], u[None], k))

    def terminal(self, x, k):
        return self.l(x, np.zeros(0), k)

    def terminal_derivs(self, x, k):
        lx, _, lxx, _, _ = self.derivs(x, np.zeros(0), k)
        return lx, lxx

    # -- the report -----------------------------------------------------------------------------
    def measure(self, k: int, data) -> dict[str, float]:
        """Phase weight, the estimated arrival's time, and the hand's distance to it and to the true ball."""
        body, palm = self.hands[self.hand or next(iter(self.hands))]
        p_hand = data.xpos[body] + data.xmat[body].reshape(3, 3) @ palm
        out = {"weight": self.weight(k, self.dyn.h),
               "arrivalS": np.nan if self.arrival is None else self.arrival[0],
               "handToArrivalM": np.nan if self.arrival is None else float(np.linalg.norm(p_hand - self.arrival[1]))}
        if self.truth is not None:
            out["handToBallM"] = float(np.linalg.norm(p_hand - self.truth[min(k, len(self.truth) - 1)]))
        return out


def _crossing(mu: np.ndarray, accel: np.ndarray, origin: np.ndarray, fwd: np.ndarray, ahead: float,
              horizon_s: float, h: float):
    """(t, position) where the estimated path first comes within ``ahead`` of ``origin`` along ``fwd``
    (the catching plane), within ``horizon_s``; where it is now if it is past the plane and still
    approaching; None otherwise.

    The crossing is the exact root of the path's quadratic distance to the plane, bracketed on a grid
    of ``h``: the first grid point past the plane (as before) lies up to a step's flight beyond it,
    13-16 cm for a 7-8 m/s throw at h 0.02, and alternating between two grid points as the estimate
    wobbles moved the target by as much (measured: 12 vs 30 cm from the ball on one throw)."""
    t = np.arange(0.0, horizon_s + 1e-9, h)
    a = float((mu[:3] - origin) @ fwd) - ahead  # distance to the plane: a + b t + c t^2
    b, c = float(mu[3:] @ fwd), 0.5 * float(accel @ fwd)
    inside = np.flatnonzero(a + b * t + c * t * t <= 0.0)
    if not len(inside):
        return None
    if inside[0] == 0:  # there already: the ball is caught where it is, if it is still coming nearer
        return (0.0, mu[:3].copy()) if b < 0 else None
    lo, hi = t[inside[0] - 1], t[inside[0]]
    if abs(c) > 1e-12:
        roots = np.roots([c, b, a]).real
        roots = roots[(roots >= lo - 1e-9) & (roots <= hi + 1e-9)]
        tc = float(roots.min()) if len(roots) else hi
    else:
        tc = -a / b
    return tc, mu[:3] + tc * mu[3:] + 0.5 * tc * tc * accel
