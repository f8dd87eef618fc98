"""Stepping stones (Eom et al. 2019, section 7): the contact foot to the nearest stone at contact frames.

``c_tsk = |p_foot - p_cs|^2 + |W_foot - W_ref|_F^2`` at each step where the reference has that foot
on the ground, ``w_tsk = 10`` (the paper's). ``p_foot`` is the toe joint (the foot body furthest
down the leg: where the stones of ``sample_stages/attend`` were measured), ``W_foot`` the world frame
of the foot's first body (the ankle) and ``W_ref`` the reference's at the same step.

Ours, where the paper leaves room:

* Units: the paper gives none. Distances are in thirds of a metre (the position residual times
  ``POSITION_SCALE = 3``; the rotation matrices' difference is unitless, ``4 (1 - cos angle)``).
  In metres a 10 deg turn of the foot costs as much as a 25 cm miss, and the orientation term
  decided where the foot went: displaced stones were stood on up to 21 cm off, undisplaced ones up
  to 10 cm (the foot crept during its contact). With 3, a 10 deg turn weighs as an 8 cm miss; the
  displaced stone is stood on within 2-3 cm in 7 of 8 directions (docs/physics.md). 2 and 4 fell
  in 1 and 3 of 4 runs, 5 and 10 in all (the standing feet pulled too hard).
* ``p_cs``: the paper takes the stone closest to the contact foot in the last optimal trajectory.
  Re-choosing it inside the optimizer lets a lagging swing foot lock onto the stone the other foot
  just left (seen on the CMU walk, whose feet cross); here each reference contact keeps one stone
  for its whole span: the one closest, in the ground plane, to the reference's footfall (the toe's
  mean position over the contact). With stones displaced less than half their spacing this is
  the paper's choice, and the cost stays smooth. A footfall takes no stone further than ``REACH_M``
  from it: a stone metres from the walk pulled the foot as hard as one 15 cm off (the report then
  said "399 cm from its stone"); such a footfall is left where the reference steps, and the shot's
  notes say so (``notes``).
* A contact under way at the reference's first frame keeps its stone only where the foot stands on
  it (within ``START_ON_M`` of the footfall): that foot is already down and cannot be placed, a stone
  off it only drags it along the ground. On the walk's 4.0 s crop the standing foot's nearest stone
  is 5 cm from it (the sample's stone is the footfall of the whole stance the crop cuts in two), and
  its term pulled the standing foot from the first step; a stone right under the standing foot
  steadies it (its orientation and height residuals: dropped there too, the 1.0-2.5 s bench scene
  fell in 2 of 4 directions and the 4.0-5.5 s walk in 2 of 4).
* Stones are flat marks on the ground (their height is not simulated), so the stone pulls the toe
  in the ground plane and its height target is the reference's toe height at that step, less how
  far the reference's foot floats over the ground at its lowest in that contact (capture floats
  feet: CMU 131_01's right foot stands 3.7-4.4 cm up, and the task held the simulated foot over
  its stone).

* The verdict on a whole run (``StoneTask.problems``): a reference contact on a stone whose foot is
  not down on that stone at any simulated step within ``LANDING_S`` of the contact's start, down
  meaning on the ground (the lowest point of the foot's capsules within ``DOWN_M``) and still, for
  ``CONTACT_MIN_S``; or not by the shot's end where that comes first. The per-step distance
  (``measure``) is taken in the ground plane, so a foot held over its stone would pass it.

Contact frames come from the reference: the toe within 6 cm of its lowest height over the clip and
slower than 0.6 m/s, for at least 50 ms (the rule ``make_stages.py`` found the sample stones with).

Derivatives: the gradient is exact; the Hessian is Gauss-Newton (``2 J'J`` of the residuals), which
is what DDP wants of a least-squares term (positive semi-definite).
"""

from __future__ import annotations

import numpy as np

from usdgaze.physics.dynamics import MujocoBody
from usdgaze.physics.points import Points, frame_jacobian
from usdgaze.physics.measures import lowest_z
from usdgaze.physics.tasks import Problem

W_TSK = 10.0
CONTACT_HEIGHT_M = 0.06
CONTACT_SPEED = 0.6  # m/s
CONTACT_MIN_S = 0.05
POSITION_SCALE = 3.0  # the position residual in thirds of a metre (see the module docstring)
START_ON_M = 0.01  # a contact under way at the first frame keeps a stone only this close to its footfall
# A footfall's stone is at most this far from it in the ground plane: the bar displaces stones by up
# to 15 cm, and half a walking step (CMU 131_01's is 0.6-0.7 m) keeps a foot off its neighbour's stone.
REACH_M = 0.35
LANDING_S = 0.3  # a simulated foot must come down this close in time to the reference's footfall
DOWN_M = 0.02  # a simulated foot is down with the lowest point of its capsules this near the ground
# The task looks this far into the planner's window and no further: costed over a whole 0.8 or 1.0 s
# window, every stones shot tried fell (``physics.lookahead``). A stones shot's window is 1.0 s.
LOOK_AHEAD_S = 0.6


def foot_chains(dyn: MujocoBody) -> list[list[int]]:
    """Per leg, the MuJoCo bodies of its foot from the ankle (the topmost foot body) down to the toe."""
    model = dyn.model
    out = []
    for top in model.feet:
        chain = [top]
        while True:
            kids = [b for b in range(len(model.bodies)) if model.body_parent[b] == chain[-1] and model.role[b] == "foot"]
            if not kids:
                break
            chain.append(kids[0])
        out.append([b + 1 for b in chain])
    return out


def feet(dyn: MujocoBody) -> list[tuple[str, int, int]]:
    """(name, ankle MuJoCo body, toe MuJoCo body) per leg: the foot chain's first and last bodies."""
    return [(dyn.model.names[chain[0] - 1], chain[0], chain[-1]) for chain in foot_chains(dyn)]


def contact_mask(heights: np.ndarray, speeds: np.ndarray, h: float) -> np.ndarray:
    """Steps with the foot on the ground: low and slow for at least ``CONTACT_MIN_S``."""
    low = (heights < heights.min() + CONTACT_HEIGHT_M) & (speeds < CONTACT_SPEED)
    edges = np.flatnonzero(np.diff(np.r_[0, low.astype(int), 0]))
    out = np.zeros(len(low), dtype=bool)
    for a, b in zip(edges[::2], edges[1::2]):
        if (b - a) * h >= CONTACT_MIN_S - 1e-9:
            out[a:b] = True
    return out


class StoneTask:
    """The stepping-stone task term over the planner's state (a ``ddp.Cost`` plus ``measure``)."""

    name = "stones"
    look_ahead_s = LOOK_AHEAD_S  # costed on a longer window's first 0.6 s only (physics.lookahead)

    def __init__(self, dyn: MujocoBody, ref_qpos: np.ndarray, stones: np.ndarray, weight: float = W_TSK,
                 frames: tuple[np.ndarray, np.ndarray] | None = None, names: list[str] | None = None) -> None:
        """``ref_qpos``: the reference at the planner's steps; ``frames``: the reference at its own
        frames and their seconds from the start (contacts are found there: a shuffle's 80 ms lift is
        two steps of the planner), else the steps themselves; ``names``: the stones' names in reports."""
        self.dyn, self.w = dyn, float(weight)
        self.names = list(names) if names is not None else [f"stone {i}" for i in range(len(stones))]
        self.stones = np.asarray(stones, dtype=float).reshape(-1, 3)
        self.points = Points(dyn)
        self.feet = feet(dyn)
        # each foot's capsules: its bodies' from the ankle to the toe
        self._foot_geoms = [np.flatnonzero(np.isin(dyn.mj.geom_bodyid, chain)) for chain in foot_chains(dyn)]
        xpos, xmat = self._poses(ref_qpos)
        fq, fs = frames if frames is not None else (ref_qpos, dyn.h * np.arange(len(ref_qpos)))
        fpos = xpos if frames is None else self._poses(fq)[0]
        # each planner step takes the contact state of the reference frame nearest its time
        step_s = dyn.h * np.arange(len(ref_qpos))
        near = np.clip(np.searchsorted(fs, step_s), 0, len(fs) - 1)
        near = np.where((near > 0) & (np.abs(fs[near - 1] - step_s) < np.abs(fs[near] - step_s)), near - 1, near)
        self.ref_height, self.ref_frame = [], []
        self.stone = np.full((len(self.feet), len(ref_qpos)), -1)  # the stone of each contact step
        self.unreached: list[tuple[str, float, float]] = []  # footfalls with no stone in reach: (foot, s, m)
        taken: set[int] = set()
        for f, (leg, ankle, toe) in enumerate(self.feet):
            p = fpos[:, toe]
            speed = np.linalg.norm(np.gradient(p[:, :2], fs, axis=0), axis=1) if len(p) > 1 else np.zeros(1)
            on = contact_mask(p[:, 2], speed, np.diff(fs).mean() if len(fs) > 1 else dyn.h)
            span = np.zeros(len(fs), dtype=int) - 1
            edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
            for a, b in zip(edges[::2], edges[1::2]):
                if not len(self.stones):
                    continue
                foot = p[a:b].mean(axis=0)
                stone = self.nearest(foot)
                off = float(np.linalg.norm(self.stones[stone, :2] - foot[:2]))
                if off > REACH_M:
                    self.unreached.append((leg, float(fs[a] - fs[0]), off))
                else:
                    taken.add(stone)  # (a foot down at the start stands by it: not placed, but not ignored)
                    if a > 0 or off <= START_ON_M:
                        span[a:b] = stone  # (a foot down at the start off its stone: none, see above)
            self.stone[f] = span[near]
            self.ref_height.append(xpos[:, toe, 2])
            self.ref_frame.append(xmat[:, ankle])
        self.taken = taken  # the stones some footfall of the reference takes
        self._onto_stones(ref_qpos)

    def notes(self, start_s: float = 0.0) -> list[str]:
        """What the reference's footfalls make of the stones, in words, where they miss them: none
        taken at all, or footfalls with no stone within ``REACH_M`` (``start_s``: the shot's first
        time in seconds, which the footfalls' times count from). A stone no footfall of this shot
        takes is not said: a shot cut from a take walks over some of the take's stones only."""
        if not len(self.stones) or not self.unreached:
            return []
        if not self.taken:
            nearest = min(m for _, _, m in self.unreached)
            return [f"no stone within {100 * REACH_M:.0f} cm of any footfall of the reference (the nearest "
                    f"{100 * nearest:.0f} cm): none stepped on"]
        steps = ", ".join(f"{leg} at {start_s + t:.2f} s ({100 * m:.0f} cm)" for leg, t, m in self.unreached)
        return [f"footfalls with no stone within {100 * REACH_M:.0f} cm, left where the reference steps: {steps}"]

    def _onto_stones(self, ref_qpos: np.ndarray) -> None:
        """Each contact's toe height target less how far the reference's foot floats over the ground
        there (its capsules' lowest point at its lowest over the contact): the foot to come down on
        its stone. CMU 131_01's right foot stands 3.7-4.4 cm up through its stances, and the task
        held the simulated foot over Stone10 (docs/physics-log.md, "Floating feet")."""
        sole = self._on_ground(ref_qpos)[0]
        for f in range(len(self.feet)):
            on = self.stone[f] >= 0
            edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
            height = np.array(self.ref_height[f], dtype=float)
            for a, b in zip(edges[::2], edges[1::2]):
                height[a:b] -= max(float(sole[a:b, f].min()), 0.0)
            self.ref_height[f] = height

    def _poses(self, qpos: np.ndarray):
        poses = [self.points.pose(self.dyn.to_state(q)) for q in qpos]
        return np.array([p[0] for p in poses]), np.array([p[1] for p in poses])

    def _k(self, k: int) -> int:
        return min(max(int(k), 0), self.stone.shape[1] - 1)

    def nearest(self, p: np.ndarray) -> int:
        return int(np.argmin(np.sum((self.stones[:, :2] - p[:2]) ** 2, axis=1)))

    def _residuals(self, xb: np.ndarray, k: int, jac: bool):
        """Per foot in contact at ``k``: (residual (12,), its Jacobian (12, nv) or None)."""
        k = self._k(k)
        on = [f for f in range(len(self.feet)) if self.stone[f, k] >= 0]
        if not on:
            return []
        xpos, xmat = self.points.pose(xb)
        out = []
        for f in on:
            _, ankle, toe = self.feet[f]
            s = self.stones[self.stone[f, k]]
            target = np.array([s[0], s[1], self.ref_height[f][k]])
            r = np.concatenate([POSITION_SCALE * (xpos[toe] - target), (xmat[ankle] - self.ref_frame[f][k]).ravel()])
            J = None
            if jac:
                jp, _ = self.points.jacobian(xb, toe, xpos[toe])
                _, jr = self.points.jacobian(xb, ankle, xpos[ankle])
                J = np.vstack([POSITION_SCALE * jp, frame_jacobian(xmat[ankle], jr)])
            out.append((r, J))
        return out

    def _value(self, xb, k):
        return self.w * sum(float(r @ r) for r, _ in self._residuals(xb, k, False))

    def _grad(self, xb, k):
        nv = self.dyn.nv
        g, H = np.zeros(2 * nv), np.zeros((2 * nv, 2 * nv))
        for r, J in self._residuals(xb, k, True):
            g[:nv] += 2 * self.w * J.T @ r
            H[:nv, :nv] += 2 * self.w * J.T @ J
        return g, H

    # -- ddp.Cost --------------------------------------------------------------------------------
    def l(self, x, u, k):
        return self._value(x[self.dyn.xs], k)

    def derivs(self, x, u, k):
        g, H = self._grad(x[self.dyn.xs], k)
        nx, nu = len(x), len(u)
        lx, lxx = np.zeros(nx), np.zeros((nx, nx))
        lx[self.dyn.xs], lxx[self.dyn.xs, self.dyn.xs] = g, H
        return lx, np.zeros(nu), lxx, np.zeros((nu, nu)), np.zeros((nu, nx))

    def terminal(self, x, k):
        return self._value(x[self.dyn.xs], k)

    def terminal_derivs(self, x, k):
        lx, _, lxx, _, _ = self.derivs(x, np.zeros(0), k)
        return lx, lxx

    # -- per-step report -------------------------------------------------------------------------
    def measure(self, k: int, data) -> dict[str, float]:
        """Per foot: the toe's ground-plane distance to the stone of the reference's contact at this
        step (NaN outside contacts)."""
        k = self._k(k)
        out = {}
        for f, (name, _, toe) in enumerate(self.feet):
            p = data.xpos[toe]
            err = np.nan
            if self.stone[f, k] >= 0:
                err = float(np.linalg.norm(self.stones[self.stone[f, k], :2] - p[:2]))
            out[f"{name}.stoneDistanceM"] = err
        return out


    # -- the whole run's verdict -----------------------------------------------------------------
    def problems(self, qpos: np.ndarray, seconds: np.ndarray) -> list[str]:
        """Footfalls on a stone the simulated foot did not make, at the simulated steps ``qpos``: per
        reference contact on a stone, no step within ``LANDING_S`` of its start with the foot down on
        that stone: the lowest point of its capsules within ``DOWN_M`` of the ground, its heel or toe
        slower than ``CONTACT_SPEED`` across it, the stone the nearest to its toe, for
        ``CONTACT_MIN_S``. A contact whose landing time runs past the shot's end is said as not
        down by then. The per-step distance (``measure``) ignores height: a foot held over its
        stone would pass it."""
        h, n = self.dyn.h, len(qpos)
        sole, speed, toe = self._on_ground(qpos)
        reach, lasting = int(round(LANDING_S / h)), int(np.ceil(CONTACT_MIN_S / h - 1e-9))
        out = []
        for f, (name, _, _) in enumerate(self.feet):
            down = (sole[:, f] < DOWN_M) & (speed[:, f] < CONTACT_SPEED)
            nearest = np.argmin(np.sum((toe[:, f, None, :2] - self.stones[None, :, :2]) ** 2, axis=2), axis=1)
            ref = self.stone[f, :n]
            for a in np.flatnonzero(np.diff(np.r_[-1, ref]) != 0):
                if ref[a] < 0 or seconds[a] + CONTACT_MIN_S > seconds[-1] + 1e-9:
                    continue  # no stone, or the shot ends before the reference is down
                if _lasting(down & (nearest == ref[a]), lasting)[max(a - reach, 0): a + reach + 1].any():
                    continue
                if seconds[a] + LANDING_S > seconds[-1] + 1e-9:
                    # Not mendable: the simulated foot may land LANDING_S after the reference's, and no
                    # simulation has more of the shot to land it in (retrying one cost the stones
                    # test's scene a third simulation with the same problem).
                    out.append(Problem(f"{name} not down on {self.names[ref[a]]} by the shot's end at "
                                       f"{seconds[-1]:.2f} s (its sole then {100 * sole[-1, f]:.1f} cm up, moving "
                                       f"{speed[-1, f]:.2f} m/s; the reference's contact from {seconds[a]:.2f} s)",
                                       mendable=False))
                else:
                    out.append(f"{name} not down on {self.names[ref[a]]} within {LANDING_S:.1f} s of "
                               f"{seconds[a]:.2f} s (the reference's contact)")
        return out

    def _on_ground(self, qpos: np.ndarray):
        """Per step and foot: its capsules' lowest point's height ``(K, F)``, the slower of its heel's
        (ankle's) and toe's speed across the ground ``(K, F)`` (the last step's from the one before),
        and the toe's position ``(K, F, 3)``."""
        import mujoco

        mj, h = self.dyn.mj, self.dyn.h
        d = mujoco.MjData(mj)
        sole, ankle, toe = (np.empty((len(qpos), len(self.feet)) + s) for s in ((), (3,), (3,)))
        for k, q in enumerate(qpos):
            d.qpos[:] = q
            mujoco.mj_kinematics(mj, d)
            for f, (_, a, t) in enumerate(self.feet):
                sole[k, f] = lowest_z(mj, d, self._foot_geoms[f])
                ankle[k, f], toe[k, f] = d.xpos[a], d.xpos[t]

        def moving(p):
            step = np.linalg.norm(np.diff(p[:, :, :2], axis=0), axis=2) / h
            return np.concatenate([step, step[-1:]]) if len(step) else np.full(p.shape[:2], np.inf)
        return sole, np.minimum(moving(ankle), moving(toe)), toe


def _lasting(low: np.ndarray, steps: int) -> np.ndarray:
    """``low`` where it holds for at least ``steps`` steps in a row: a toe passing slowly through the
    contact band at the top of a swing (or skidding across the ground) is not a footfall."""
    edges = np.flatnonzero(np.diff(np.r_[0, low.astype(int), 0]))
    out = np.zeros(len(low), bool)
    for a, b in zip(edges[::2], edges[1::2]):
        out[a:b] = b - a >= steps
    return out


def factory(stones: np.ndarray, frames: tuple[np.ndarray, np.ndarray] | None = None, weight: float = W_TSK,
            names: list[str] | None = None):
    """A ``physics.tasks.TaskFactory`` for stones at model-world positions ``(S, 3)``; ``frames`` and ``names``
    as for :class:`StoneTask` (the reference ``qpos`` at its frames, seconds from the start; the
    stones' prim paths, for reports)."""
    return lambda plan, ref_q: StoneTask(plan, ref_q, stones, weight, frames, names)
