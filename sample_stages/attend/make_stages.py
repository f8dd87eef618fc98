"""Write the attend sample stages next to this script (deterministic: re-running changes no byte).

``python sample_stages/attend/make_stages.py``. Every stage sublayers the CMU capture in
../cmu/ (see its README for the acknowledgement) and adds GazeObjectAPI prims:

* ``standing.usdc``: an override holding the first frame of cmu_131_01 for 2 s at 30 fps (a
  standing character), sublayered by the two ball stages;
* ``ball_throw.usda``: one ball flying at the standing character from the first frame (from 8 m),
  arriving at chest height at 1.4 s (the SkelRoot's ``usdgaze:physics:catch`` names it:
  ``attend --physics`` catches it);
* ``two_balls.usda``: two balls flying together from the front-left and front-right (from 7 m),
  arriving at 1.3 and 1.4 s (Figure 4's balls: no task, they arrive at the chest);
* ``two_balls_catch.usda``: the same throws to be caught: arriving 0.5 m in front of the head and 0.27 m
  below it (within the hands' reach), each ball's importance rising as its time to arrival shrinks
  (the task: see docs/attend.md, "A dwell on the nearer ball");
* ``stepping_stones.usda``: the cmu_131_01 walk, a stone at each footfall (found from the toes'
  height and speed in the capture; each stone records ``userProperties:landing``, ``lift`` and
  ``swingStart``, the time code the foot stepping onto it leaves its previous contact); a stone's
  importance rises to 1 at the swing start before its own (the other foot leaving, in a walk) and
  falls back to 0.05 when its foot lands (the task: see docs/attend.md); each stone is also a
  stepping stone for the physics body (``usdgaze:physics:task = "stone"``);
* ``stepping_stones_shot.usda``: a shot over it, 4.0-5.5 s of the walk, the right foot's stone there
  (Stone10) displaced 15 cm: the stones bar's scene for ``attend --physics``;
* ``obstacles.usda``: the cmu_131_02 walk among eight spheres crossing its path (``usdgaze:physics:task
  = "obstacle"`` for the physics body).

Object motion is authored as time-sampled translations at 30 fps.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel

HERE = Path(__file__).resolve().parent
CMU = HERE.parent / "cmu"
ANIM = "/root/Body/BodySkel/scaled_131_01"
ANIM2 = "/root/Body/BodySkel/scaled_131_02"
STEP = 4.0  # time codes between object samples (~30 fps at 120 tcps)
G = 9.81


def _posed(path: Path):
    """Times, joint names and world matrices (row-vector) of the capture, by UsdSkel."""
    stage = Usd.Stage.Open(str(path))
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/root/Body/BodySkel"))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/root/Body")), Usd.PrimDefaultPredicate)
    q = cache.GetSkelQuery(skel)
    xf = UsdGeom.Xformable(skel.GetPrim())
    times = np.array(q.GetAnimQuery().GetJointTransformTimeSamples())
    world = np.stack([np.array(q.ComputeJointSkelTransforms(Usd.TimeCode(t)))
                      @ np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(t))) for t in times])
    names = [str(j).rsplit("/", 1)[-1] for j in q.GetJointOrder()]
    return stage, times, names, world


def _new_layer(path: Path, sublayers: list[str], start: float, end: float, tcps: float) -> Sdf.Layer:
    layer = Sdf.Layer.CreateNew(str(path)) if not path.exists() else Sdf.Layer.FindOrOpen(str(path))
    layer.Clear()
    layer.subLayerPaths[:] = sublayers
    layer.startTimeCode, layer.endTimeCode = start, end
    layer.timeCodesPerSecond = layer.framesPerSecond = tcps
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    layer.defaultPrim = "root"
    return layer


def _ball(layer: Sdf.Layer, path: str, times: np.ndarray, pos: np.ndarray, radius: float, kind: str,
          importance=None, task: str = "") -> None:
    group = Sdf.CreatePrimInLayer(layer, path.rsplit("/", 1)[0])
    group.specifier, group.typeName = Sdf.SpecifierDef, "Xform"
    prim = Sdf.CreatePrimInLayer(layer, path)
    prim.specifier = Sdf.SpecifierDef
    prim.typeName = "Sphere" if kind != "static" else "Cylinder"
    prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    r = Sdf.AttributeSpec(prim, "radius", Sdf.ValueTypeNames.Double)
    r.default = float(radius)
    if kind == "static":
        Sdf.AttributeSpec(prim, "height", Sdf.ValueTypeNames.Double).default = 0.05
        Sdf.AttributeSpec(prim, "axis", Sdf.ValueTypeNames.Token).default = "Y"
    Sdf.AttributeSpec(prim, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = float(radius)
    Sdf.AttributeSpec(prim, "gaze:object:kind", Sdf.ValueTypeNames.Token).default = kind
    if task:  # what the physics body does with it (`usdgaze attend --physics`, docs/physics.md)
        Sdf.AttributeSpec(prim, "usdgaze:physics:task", Sdf.ValueTypeNames.Token).default = task
    imp = Sdf.AttributeSpec(prim, "gaze:object:importance", Sdf.ValueTypeNames.Float)
    if importance is None:
        imp.default = 1.0
    else:
        for t, v in zip(times, importance):
            layer.SetTimeSample(imp.path, float(t), float(v))
    tr = Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3)
    if len(pos) == 1:
        tr.default = Gf.Vec3d(*map(float, pos[0]))
    else:
        for t, p in zip(times, pos):
            layer.SetTimeSample(tr.path, float(t), Gf.Vec3d(*map(float, p)))
    Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, variability=Sdf.VariabilityUniform
                      ).default = ["xformOp:translate"]


def _throw(start, end, t_fly, t0, secs) -> np.ndarray:
    """A ballistic flight from ``start`` to ``end`` in ``t_fly`` s starting at ``t0`` (Y up); held at both ends."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    v = (end - start) / t_fly + np.array([0, 0.5 * G * t_fly, 0])
    t = np.clip(secs - t0, 0, t_fly)[:, None]
    return start + v * t - 0.5 * G * np.array([0, 1.0, 0]) * t * t


def catch_importance(secs: np.ndarray, arrival: float, tau: float = 0.5) -> np.ndarray:
    """A ball to catch: importance 1 until it is ``tau`` s from arriving, then tau / (time to arrival),
    up to 5 (at 0.1 s); 0.05 once caught. Ours: the paper's importance "depending on the task"."""
    tta = arrival - secs
    return np.where(tta > 0, np.maximum(1.0, tau / np.maximum(tta, 0.1)), 0.05)


def standing(stage_times, world, names, tcps) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Write standing.usdc; return the head position, forward and left at the first frame."""
    src = Sdf.Layer.FindOrOpen(str(CMU / "cmu_131_01.usdc"))
    anim = src.GetPrimAtPath(ANIM)
    t_first = stage_times[0]
    codes = t_first + np.arange(0, 2.0 * tcps + 1e-6, STEP)
    path = HERE / "standing.usdc"
    layer = _new_layer(path, [], float(codes[0]), float(codes[-1]), tcps)
    with Sdf.ChangeBlock():
        prim = Sdf.CreatePrimInLayer(layer, ANIM)
        prim.specifier = Sdf.SpecifierOver
        for name in ("rotations", "translations", "scales"):
            a = anim.attributes[name]
            v = src.QueryTimeSample(a.path, t_first) if src.GetNumTimeSamplesForPath(a.path) else a.default
            spec = Sdf.AttributeSpec(prim, name, a.typeName)
            for c in codes:
                layer.SetTimeSample(spec.path, float(c), v)
    layer.Save()
    i = {n: k for k, n in enumerate(names)}
    w = world[0]
    head = w[i["Head"], 3, :3]
    left = w[i["LeftHip"], 3, :3] - w[i["RightHip"], 3, :3]
    left[1] = 0
    left /= np.linalg.norm(left)
    fwd = np.cross(left, [0, 1.0, 0])
    return head, fwd, left, codes


def footfalls(times, world, names, tcps):
    """(landing, lift, swing start, position) of each toe contact, in landing order; the swing start is
    when the same foot left its previous contact (the foot that steps onto this stone lifts)."""
    out = []
    for toe in ("LeftToe", "RightToe"):
        prev_lift = float(times[0])
        p = world[:, names.index(toe), 3, :3]
        h = p[:, 1]
        speed = np.linalg.norm(np.gradient(p, axis=0), axis=1) * tcps
        contact = (h < h.min() + 0.06) & (speed < 0.6)
        edges = np.flatnonzero(np.diff(np.r_[0, contact.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= 6:  # at least 50 ms on the ground
                q = p[a:b].mean(0)
                out.append((float(times[a]), float(times[b - 1]), prev_lift, np.array([q[0], 0.0, q[2]])))
                prev_lift = float(times[b - 1])
    return sorted(out, key=lambda c: c[0])


def _stones_shot(first: float, tcps: float) -> None:
    """``stepping_stones_shot.usda``: a shot's root layer over ``stepping_stones.usda``, 4.0-5.5 s of the
    walk (the take goes on past it, for the planner), Stone10 (the right foot's footfall at 5.32 s)
    displaced 15 cm along the stage's +X: the stones bar's scene (docs/physics.md) for ``attend
    --physics``, which the whole walk from its first frame is not (it falls at its start)."""
    layer = _new_layer(HERE / "stepping_stones_shot.usda", ["stepping_stones.usda"], first + 480.0, first + 660.0,
                       tcps)
    over = Sdf.CreatePrimInLayer(layer, "/Stones/Stone10")
    over.specifier = Sdf.SpecifierOver
    at = Sdf.Layer.FindOrOpen(str(HERE / "stepping_stones.usda")).GetPrimAtPath("/Stones/Stone10")
    x, y, z = at.attributes["xformOp:translate"].default
    Sdf.AttributeSpec(over, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(x + 0.15, y, z)
    layer.Save()


def main() -> None:
    stage, times, names, world = _posed(CMU / "cmu_131_01.usdc")
    tcps = stage.GetTimeCodesPerSecond()
    head, fwd, left, codes = standing(times, world, names, tcps)
    secs = (codes - codes[0]) / tcps
    subs = ["./standing.usdc", "../cmu/cmu_131_01.usdc"]
    up = np.array([0, 1.0, 0])
    chest = head - 0.45 * up + 0.35 * fwd

    layer = _new_layer(HERE / "ball_throw.usda", subs, codes[0], codes[-1], tcps)
    # In flight from the first frame: the vision system's process model is a ballistic flight, and a
    # ball held still and then launched is not one (a filter with the paper's small process noise
    # would lag the launch).
    _ball(layer, "/Objects/Ball", codes, _throw(head + 8 * fwd + 1.5 * left - 0.2 * up, chest, 1.4, 0.0, secs), 0.11, "ballistic")
    body = Sdf.CreatePrimInLayer(layer, "/root/Body")  # the ball to catch under `attend --physics`
    rel = Sdf.RelationshipSpec(body, "usdgaze:physics:catch", custom=False)
    rel.targetPathList.explicitItems = [Sdf.Path("/Objects/Ball")]
    layer.Save()

    layer = _new_layer(HERE / "two_balls.usda", subs, codes[0], codes[-1], tcps)
    _ball(layer, "/Objects/BallLeft", codes,
          _throw(head + 7 * fwd + 1.5 * left - 0.2 * up, chest + 0.25 * left, 1.3, 0.0, secs), 0.11, "ballistic")
    _ball(layer, "/Objects/BallRight", codes,
          _throw(head + 7 * fwd - 1.5 * left - 0.2 * up, chest - 0.25 * left, 1.4, 0.0, secs), 0.11, "ballistic")
    layer.Save()

    layer = _new_layer(HERE / "two_balls_catch.usda", subs, codes[0], codes[-1], tcps)
    catch = head + 0.5 * fwd - 0.27 * up
    for name, side, t_fly in (("BallLeft", 1, 1.3), ("BallRight", -1, 1.4)):
        _ball(layer, f"/Objects/{name}", codes,
              _throw(head + 7 * fwd + side * 1.5 * left - 0.2 * up, catch + side * 0.25 * left, t_fly, 0.0, secs),
              0.11, "ballistic", catch_importance(secs, t_fly))
    layer.Save()

    steps = footfalls(times, world, names, tcps)
    layer = _new_layer(HERE / "stepping_stones.usda", ["../cmu/cmu_131_01.usdc"], times[0], times[-1], tcps)
    imp_codes = np.arange(times[0], times[-1] + 1e-6, STEP)
    swings = sorted(st[2] for st in steps)
    for i, (land, lift, swing, pos) in enumerate(steps):
        # the previous swing start (of the other foot, in a walk): the stone becomes the next target
        earlier = [w for w in swings if w < swing]
        rise = earlier[-1] if earlier else times[0]
        imp = np.where((imp_codes >= rise) & (imp_codes < land), 1.0, 0.05)
        _ball(layer, f"/Stones/Stone{i:02d}", imp_codes, pos[None], 0.15, "static", imp, task="stone")
        prim = layer.GetPrimAtPath(f"/Stones/Stone{i:02d}")
        for key, value in (("landing", land), ("lift", lift), ("swingStart", swing)):
            Sdf.AttributeSpec(prim, f"userProperties:{key}", Sdf.ValueTypeNames.Double).default = value
    layer.Save()
    _stones_shot(times[0], tcps)

    stage2, times2, names2, world2 = _posed(CMU / "cmu_131_02.usdc")
    hips = world2[:, names2.index("Hips"), 3, :3]
    layer = _new_layer(HERE / "obstacles.usda", ["../cmu/cmu_131_02.usdc"], times2[0], times2[-1], tcps)
    oc = np.arange(times2[0], times2[-1] + 1e-6, STEP)
    s2 = (oc - oc[0]) / tcps
    rng = np.random.default_rng(131)
    path_dir = hips[-1] - hips[0]
    path_dir[1] = 0
    span = np.linalg.norm(path_dir)
    path_dir /= span
    side = np.cross([0, 1.0, 0], path_dir)
    for i in range(8):
        along = hips[0] + path_dir * span * (0.15 + 0.1 * i)
        t_cross = s2[-1] * (0.15 + 0.1 * i)
        speed = rng.uniform(0.6, 1.4) * (1 if i % 2 else -1)
        p = along + side[None] * (speed * (s2 - t_cross))[:, None]
        p[:, 1] = rng.uniform(0.4, 1.2)
        _ball(layer, f"/Obstacles/Obstacle{i}", oc, p, 0.25, "moving", task="obstacle")
    layer.Save()


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parents[1]))
    main()
