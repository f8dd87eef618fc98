"""Reproduce the comparisons of Eom et al. 2019 (Figure 4 and the alpha study) with ``usdgaze attend``.

    python sample_stages/attend/figure4.py OUT_FOLDER [--window 0.8]

Runs ``usdgaze attend`` on two_balls.usda with the distance-sum, sequential and uncertainty costs,
and on ball_throw.usda with alpha 0, 0.2 and 0.4; reads back each written layer's point of sight
(``gaze:attend:pointOfSight``) and the balls' true positions, prints per run the share of frames the
line of sight is within 5 deg of each ball, the number of switches between balls, and the median
distance of the point of sight from the balls' midpoint; and draws figure4.png (top view of the
point-of-sight paths, as in the paper's figure, plus the angle to each ball over time).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from pxr import Usd, UsdGeom  # noqa: E402

from usdgaze.attend import AttendSettings, attend  # noqa: E402

FIX_DEG = 5.0


def _track(stage: Usd.Stage, prim: str, times) -> np.ndarray:
    xf = UsdGeom.Xformable(stage.GetPrimAtPath(prim))
    return np.array([np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(t)))[3, :3] for t in times])


def _read(out: Path, stage_path: Path, balls: list[str]):
    layer_stage = Usd.Stage.Open(str(out))
    prim = next(p for p in layer_stage.Traverse() if p.GetAttribute("gaze:attend:pointOfSight"))
    attr = prim.GetAttribute("gaze:attend:pointOfSight")
    times = attr.GetTimeSamples()
    pos = np.array([attr.Get(t) for t in times], dtype=float)
    stage = Usd.Stage.Open(str(stage_path))
    tracks = [_track(stage, b, times) for b in balls]
    secs = (np.array(times) - stage.GetStartTimeCode()) / stage.GetTimeCodesPerSecond()
    return secs, pos, tracks


def _angles(pos, track, origin):
    a, b = pos - origin, track - origin
    c = (a * b).sum(1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def _summary(name, secs, pos, tracks, origin):
    on = [(_angles(pos, t, origin) < FIX_DEG) for t in tracks]
    seq = [i + 1 for row in zip(*on) for i, v in enumerate(row) if v]
    switches = sum(a != b for a, b in zip(seq, seq[1:]))
    mid = np.median(np.linalg.norm(pos - np.mean(tracks, axis=0), axis=1)) if len(tracks) > 1 else float("nan")
    shares = ", ".join(f"ball {i + 1} {100 * o.mean():4.0f}%" for i, o in enumerate(on))
    print(f"{name:28s} {shares}; switches {switches}; median distance to the midpoint {mid:5.2f} m")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--window", type=float, default=0.8)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    runs = []
    two = HERE / "two_balls.usda"
    for cost in ("distance", "sequential", "uncertainty"):
        out = args.out / f"two_balls_{cost}.usdc"
        attend(two, out, settings=AttendSettings(cost=cost, window_s=args.window))
        runs.append((f"two balls, {cost}", *_read(out, two, ["/Objects/BallLeft", "/Objects/BallRight"])))
    one = HERE / "ball_throw.usda"
    for alpha in (0.0, 0.2, 0.4):
        out = args.out / f"ball_throw_alpha{alpha:g}.usdc"
        attend(one, out, settings=AttendSettings(alpha=alpha, window_s=args.window))
        runs.append((f"one ball, alpha {alpha:g}", *_read(out, one, ["/Objects/Ball"])))
    origin = _eyes()
    for name, secs, pos, tracks in runs:
        _summary(name, secs, pos, tracks, origin)
    _draw(runs, args.out / "figure4.png")
    print(f"wrote {args.out / 'figure4.png'}")


def _eyes() -> np.ndarray:
    """The standing character's eye midpoint: the stages hold it still, so the first-frame head."""
    stage = Usd.Stage.Open(str(HERE / "ball_throw.usda"))
    from pxr import UsdSkel

    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/root/Body/BodySkel"))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/root/Body")), Usd.PrimDefaultPredicate)
    q = cache.GetSkelQuery(skel)
    t = Usd.TimeCode(stage.GetStartTimeCode())
    world = np.array(q.ComputeJointSkelTransforms(t)) @ np.array(UsdGeom.Xformable(skel.GetPrim()).ComputeLocalToWorldTransform(t))
    names = [str(j).rsplit("/", 1)[-1] for j in q.GetJointOrder()]
    return world[names.index("Head"), 3, :3] + np.array([0.0, 0.08, 0.0])


def _draw(runs, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(runs), figsize=(4 * len(runs), 7))
    origin = _eyes()
    for col, (name, secs, pos, tracks) in enumerate(runs):
        ax = axes[0, col]
        for t in tracks:
            ax.plot(t[:, 0], t[:, 2], "k:", lw=1)
        ax.plot(pos[:, 0], pos[:, 2], "r-", lw=1.5)
        ax.set_title(name, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
        ax2 = axes[1, col]
        for i, t in enumerate(tracks):
            ax2.plot(secs, _angles(pos, t, origin), label=f"ball {i + 1}")
        ax2.axhline(FIX_DEG, color="grey", lw=0.5)
        ax2.set_ylim(0, 60)
        ax2.set_xlabel("s")
        ax2.set_ylabel("angle to ball (deg)")
        ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


if __name__ == "__main__":
    main()
