"""Ball-catch stages for the coupled physics loop: the standing CMU character and one thrown ball.

``throw_stage`` writes a self-contained .usda (the standing excerpt's animation cut to the shot, the
CMU skeleton as its sublayer) with a ball already in flight at the first frame, landing at
``arrival`` (stage units, Y up) after ``flight_s`` seconds and held there, and the SkelRoot's
``usdgaze:physics:catch`` relationship naming it. ``seeded_throw`` draws a throw from the front
within reach (the issue's bar); ``behind_throw`` one that comes over the shoulder from behind.
Used by the tests and by benchmarks/bench_physics.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Gf, Sdf

ROOT = Path(__file__).resolve().parents[1]
STANDING = ROOT / "sample_stages" / "attend" / "standing.usdc"
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"
SKEL, ANIM, SKEL_ROOT = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_01", "/root/Body"
BALL = "/Objects/Ball"
G = 9.81
UP = np.array([0.0, 1.0, 0.0])


def character():
    """Head and shoulders' midpoint, forward and left (stage, Y up) of the standing character, by UsdSkel FK."""
    from . import measure

    posed = measure.posed(str(CMU), SKEL)
    head = posed.position("Head")[0]
    shoulders = 0.5 * (posed.position("LeftShoulder")[0] + posed.position("RightShoulder")[0])
    left = posed.position("LeftHip")[0] - posed.position("RightHip")[0]
    left[1] = 0.0
    left /= np.linalg.norm(left)
    return head, shoulders, np.cross(left, UP), left


def flight(start, arrival, flight_s: float, secs: np.ndarray) -> np.ndarray:
    """Ballistic positions from ``start`` (t = 0) to ``arrival`` (t = flight_s), held afterwards."""
    start, arrival = np.asarray(start, float), np.asarray(arrival, float)
    v = (arrival - start) / flight_s + 0.5 * G * flight_s * UP
    t = np.clip(secs, 0.0, flight_s)[:, None]
    return start + v * t - 0.5 * G * UP * t * t


def throw_stage(path: Path, start, arrival, flight_s: float, seconds: float, catch: bool = True) -> Path:
    """Write the stage; returns ``path``."""
    src = Sdf.Layer.FindOrOpen(str(STANDING))
    layer = Sdf.Layer.CreateNew(str(path))
    layer.TransferContent(src)
    layer.subLayerPaths[:] = [str(CMU)]
    tcps = layer.timeCodesPerSecond
    begin = layer.startTimeCode
    end = begin + seconds * tcps
    codes = None
    for name in ("rotations", "translations", "scales"):
        attr = Sdf.Path(f"{ANIM}.{name}")
        times = layer.ListTimeSamplesForPath(attr)
        for t in times:
            if t > end + 1e-6:
                layer.EraseTimeSample(attr, t)
        codes = np.array([t for t in times if t <= end + 1e-6])
    layer.endTimeCode = float(codes[-1])
    pos = flight(start, arrival, flight_s, (codes - begin) / tcps)
    _author_ball(layer, codes, pos, SKEL_ROOT if catch else None)
    layer.Save()
    return path


def _author_ball(layer: Sdf.Layer, codes: np.ndarray, pos: np.ndarray, catcher: str | None) -> None:
    """The ball (/Objects/Ball, a GazeObjectAPI sphere of 11 cm) at ``pos`` per time code; the
    ``catcher`` SkelRoot's ``usdgaze:physics:catch`` names it."""
    group = Sdf.CreatePrimInLayer(layer, "/Objects")
    group.specifier, group.typeName = Sdf.SpecifierDef, "Xform"
    ball = Sdf.CreatePrimInLayer(layer, BALL)
    ball.specifier, ball.typeName = Sdf.SpecifierDef, "Sphere"
    ball.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    Sdf.AttributeSpec(ball, "radius", Sdf.ValueTypeNames.Double).default = 0.11
    Sdf.AttributeSpec(ball, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = 0.11
    Sdf.AttributeSpec(ball, "gaze:object:kind", Sdf.ValueTypeNames.Token).default = "ballistic"
    tr = Sdf.AttributeSpec(ball, "xformOp:translate", Sdf.ValueTypeNames.Double3)
    for c, p in zip(codes, pos):
        layer.SetTimeSample(tr.path, float(c), Gf.Vec3d(*map(float, p)))
    Sdf.AttributeSpec(ball, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    if catcher is not None:
        rel = Sdf.RelationshipSpec(Sdf.CreatePrimInLayer(layer, catcher), "usdgaze:physics:catch", custom=False)
        rel.targetPathList.explicitItems = [Sdf.Path(BALL)]


def seeded_throw(seed: int, flight_s: tuple[float, float] = (1.0, 1.3)):
    """(start, arrival, flight_s) of a throw from the front within reach: launched 5-7 m ahead, landing
    35 cm in front of the shoulders (the catch task's plane: the ball stops there, it is not met
    further along its path), up to 20 cm below them (where the eyes can still see it without
    bending the head), up to 25 cm to either side."""
    rng = np.random.default_rng(seed)
    _, shoulders, fwd, left = character()
    arrival = shoulders + 0.35 * fwd - rng.uniform(0.0, 0.2) * UP + rng.uniform(-0.25, 0.25) * left
    start = shoulders + rng.uniform(5.0, 7.0) * fwd + rng.uniform(-1.5, 1.5) * left + rng.uniform(0.0, 0.6) * UP
    return start, arrival, float(rng.uniform(*flight_s))


def behind_throw():
    """A ball from 4 m behind and 1 m to the left, over the shoulder, landing in front of the chest."""
    _, shoulders, fwd, left = character()
    return shoulders - 4.0 * fwd + 1.0 * left + 0.6 * UP, shoulders + 0.35 * fwd - 0.1 * UP + 0.2 * left, 0.9


def composed(src: Path, out: Path, path: Path) -> Path:
    """A stage with the written layer over the input, for measuring."""
    root = Sdf.Layer.Find(str(path)) or Sdf.Layer.CreateNew(str(path))
    s = Sdf.Layer.FindOrOpen(str(src))
    root.timeCodesPerSecond, root.framesPerSecond = s.timeCodesPerSecond, s.framesPerSecond
    root.startTimeCode, root.endTimeCode = s.startTimeCode, s.endTimeCode
    root.subLayerPaths[:] = list(dict.fromkeys([str(out), str(src)]))  # the input alone: the reference
    root.Save()
    return path


def ball_positions(stage_path: Path, times: np.ndarray) -> np.ndarray:
    """The ball's true world positions at ``times`` (stage units), by USD."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(stage_path))
    prim = stage.GetPrimAtPath(BALL)
    return np.array([np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(float(t))))[3, :3]
                     for t in times])


def catch_measures(src: Path, out: Path, tmp: Path, flight_s: float) -> dict:
    """Measured on the composed stage by UsdSkel FK: the nearer palm's distance to the true ball per
    frame and at its arrival (the first frame at the flight's end); palms are midway between wrist and
    hand joints; how far the palms moved from the reference's."""
    from . import measure

    posed = measure.posed(str(composed(src, out, tmp / f"composed_{Path(out).stem}.usda")), SKEL)
    ball = ball_positions(src, posed.times)
    palms = {side: 0.5 * (posed.position(f"{side.capitalize()}Wrist") + posed.position(f"{side[0]}hand"))
             for side in ("left", "right")}
    dist = np.min([np.linalg.norm(p - ball, axis=1) for p in palms.values()], axis=0)
    layer = Sdf.Layer.FindOrOpen(str(src))
    secs = (posed.times - layer.startTimeCode) / layer.timeCodesPerSecond
    k = min(int(np.searchsorted(secs, flight_s - 1e-6)), len(secs) - 1)  # the first frame the ball is there
    ref = measure.posed(str(src), SKEL)
    ref_palms = {s: 0.5 * (ref.position(f"{s.capitalize()}Wrist") + ref.position(f"{s[0]}hand")) for s in palms}
    moved = np.max([np.linalg.norm(palms[s] - ref_palms[s], axis=1) for s in palms], axis=0)
    return {"posed": posed, "ball": ball, "secs": secs, "distance": dist, "at_arrival": float(dist[k]),
            "hand_moved": moved}


def rig_throw_stage(d: Path, convention: str, side_m: float, flight_s: float = 1.2, tcps: float = 30.0):
    """A synthetic standing rig with fingers (tests/synthetic.py, ``convention``) and a ball thrown
    from 6 m ahead landing 35 cm in front of its shoulders and ``side_m`` toward its left (negative:
    its right), its SkelRoot's ``usdgaze:physics:catch`` naming it. Returns (rig, arrival point)."""
    from . import measure
    from . import synthetic as syn

    rig = syn.make_rig(d / f"{convention}.usda", convention=convention, frames=45, time_codes_per_second=tcps,
                       mesh=False, walk_speed=0.0, joints=70)
    posed = measure.posed(str(rig.path), rig.skeleton)
    at = {j.rsplit("/", 1)[-1]: posed.world[0, i, 3, :3] for i, j in enumerate(posed.joints)}
    shoulders = 0.5 * (at[rig.leaf["arm_l"]] + at[rig.leaf["arm_r"]])
    left = at[rig.leaf["thigh_l"]] - at[rig.leaf["thigh_r"]]
    left[1] = 0.0
    left /= np.linalg.norm(left)
    fwd = np.cross(left, UP)
    arrival = shoulders + 0.35 * fwd - 0.1 * UP + side_m * left
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    codes = np.array(layer.ListTimeSamplesForPath(Sdf.Path(f"{rig.animation}.rotations")))
    pos = flight(shoulders + 6.0 * fwd + 0.3 * left + 0.3 * UP, arrival, flight_s, (codes - codes[0]) / tcps)
    _author_ball(layer, codes, pos, rig.skel_root)
    layer.Save()
    return rig, arrival
