"""Where the stones-bar shot's line searches fail: the constraint onsets its rollouts straddle.

Runs the coupled stones-bar shot (``bench_physics.py --tasks stones-bar``'s scene: the walk 4.0-5.5 s,
Stone10 displaced 15 cm toward the stage's +X/+Z/-X/-Z by ``--turn`` 0/1/2/3) and watches every
line-search rollout of the solver (``ddp._forward``, wrapped here only: the shot is bit-identical to the
bench's). A try *blows up* when its window cost exceeds 1e6 (the tracking term's torques on a feedback
``K (x - X)`` that a sudden deviation made huge). For each, it finds the first window step where some
state component jumps by more than 5 (rad/s, m/s) over its deviation so far, replays the step before
it from the nominal and the trial state, and lists the constraint rows (a body geom's ground contact,
a joint limit) that carry more than 50 N in one and are absent in the other: a contact or limit at
its onset, whose force MuJoCo applies in full from the first violation (impedance ``solimp[0]``).

    python benchmarks/stones_edges.py [--turn 0] [--seed 0] [--h 0.02]

Prints one JSON line: the shot's fall and Stone10 placement, tries, blown tries, blown tries at an
onset, the onset rows by count, the share of solves whose full step (alpha 1) was accepted and the
largest regularization a solve ended with.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BLOWN = 1e6  # window cost of a blown try
JUMP = 5.0  # a state component's jump in one step over its deviation so far
FORCE_N = 50.0  # a constraint row counts when it carries more than this


def rows(body, x: np.ndarray, u: np.ndarray, k: int) -> dict[str, float]:
    """Constraint rows after one step from ``x``: ground contacts by body geom, joint limits, with force (N)."""
    import mujoco

    m, d = body.mj, body.data
    body._load(x, u, k)
    mujoco.mj_step(m, d)
    out: dict[str, float] = {}
    f = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        g = c.geom2 if c.geom1 == 0 else c.geom1
        mujoco.mj_contactForce(m, d, i, f)
        key = f"contact:{m.geom(g).name}"
        out[key] = max(out.get(key, 0.0), float(f[0]))
    for r in np.flatnonzero(d.efc_type == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT):
        out[f"limit:{m.joint(int(d.efc_id[r])).name}"] = abs(float(d.efc_force[r]))
    return out


def onset(body, X, U, Xn, Un, k0: int) -> list[str] | None:
    """The rows present in only one of the two rollouts at the step before their first jump (None: no jump)."""
    dX = np.abs(Xn[:, body.xs] - X[:, body.xs])
    for t in range(1, len(dX)):
        if (dX[t] - dX[:t].max(axis=0)).max() > JUMP:
            a = rows(body, X[t - 1, body.xs], U[t - 1, body.us], k0 + t - 1)
            b = rows(body, Xn[t - 1, body.xs], Un[t - 1, body.us], k0 + t - 1)
            return sorted(key for key in set(a) ^ set(b) if max(a.get(key, 0.0), b.get(key, 0.0)) > FORCE_N)
    return None


class Watch:
    """Wraps the solver's forward pass and solve to count tries, blow-ups and their onsets."""

    def __init__(self) -> None:
        self.tries = self.blown = self.at_onset = 0
        self.onsets: collections.Counter = collections.Counter()
        self.full_steps, self.solves, self.mu_max, self.alpha = 0, 0, 0.0, 0.0

    def install(self) -> None:
        from usdgaze.planning import ddp

        forward, solve = ddp._forward, ddp.solve

        def watched_forward(dyn, cost, X, U, kff, K, alpha, k0):
            out = forward(dyn, cost, X, U, kff, K, alpha, k0)
            self.tries, self.alpha = self.tries + 1, alpha
            if not out[2] <= BLOWN:
                self.blown += 1
                body = next(p for p in dyn.parts if p.name == "body")
                found = onset(body, X, U, out[0], out[1], k0)
                if found:
                    self.at_onset += 1
                    self.onsets.update(found)
            return out

        def watched_solve(dyn, cost, x0, U0, k0=0, options=None):
            sol = solve(dyn, cost, x0, U0, k0, options)
            self.solves += 1
            self.mu_max = max(self.mu_max, float(sol.mu))
            # one iteration a step: a solve that moved accepted its last try
            self.full_steps += int(len(sol.costs) > 1 and self.alpha == 1.0)
            return sol

        ddp._forward, ddp.solve = watched_forward, watched_solve


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--turn", type=int, default=0, help="Stone10 displaced toward +X/+Z/-X/-Z: 0/1/2/3")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--h", type=float, default=0.02)
    a = p.parse_args(argv)
    from tests import stone_stages
    from usdgaze.passes import physics as physics_pass
    from usdgaze.physics import mpc

    watch = Watch()
    watch.install()
    turn = 0.5 * np.pi * a.turn
    shift = {"Stone10": 0.15 * np.array([np.cos(turn), 0.0, np.sin(turn)])}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = stone_stages.walk_stage(tmp / "walk.usda", 4.0, 5.5, until_lift=True, task=True, shift=shift)
        report = physics_pass.run(src, tmp / "out.usda", mpc.Options(h=a.h), seed=a.seed)[0]
        stones = {r.stone: round(100 * r.ref_miss_m, 1) for r in stone_stages.gaze_before_lift(tmp, src, tmp / "out.usda", shift)}
    print(json.dumps({"turn": a.turn, "seed": a.seed, "h": a.h, "fell_at_s": report.fell_at_s, "stones_cm": stones,
                      "tries": watch.tries, "blown": watch.blown, "blown_at_onset": watch.at_onset,
                      "onsets": dict(watch.onsets.most_common(12)),
                      "full_step_share": round(watch.full_steps / max(watch.solves, 1), 3), "mu_max": watch.mu_max}))


if __name__ == "__main__":
    main()
