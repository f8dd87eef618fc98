"""Stages for the physics tasks on the CMU walk: the clip cut to a span, task prims (stones, moving
obstacles) authored on it, the test's seeded obstacle crossings, and the contact measure on the written
layer (UsdSkel FK of the bones against USD's own transforms of the spheres).

Used by tests/test_physics_obstacles.py and by benchmarks/bench_physics.py (``--tasks obstacles-coupled``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Gf, Sdf

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"
SKEL, ANIM = "/root/Body/BodySkel", "/root/Body/BodySkel/scaled_131_01"
TASK = "usdgaze:physics:task"
BONE_M = 0.08  # a bone's radius for the contact measure: thicker than the model's limbs (2-9 cm)
RADIUS_M = 0.25  # the crossing spheres'
SPAN = (1.0, 2.2)  # seconds of the walk the obstacle scenes use


def cut(path: Path, start_s: float, end_s: float) -> Path:
    """The CMU stage cut to ``[start_s, end_s]`` seconds of its animation."""
    layer = Sdf.Layer.FindOrOpen(str(CMU))
    tcps = layer.timeCodesPerSecond
    out = Sdf.Layer.CreateNew(str(path))
    out.TransferContent(layer)
    a, b = layer.startTimeCode + start_s * tcps, layer.startTimeCode + end_s * tcps
    for name in ("rotations", "translations", "scales"):
        attr = Sdf.Path(f"{ANIM}.{name}")
        for t in out.ListTimeSamplesForPath(attr):
            if t < a - 1e-6 or t > b + 1e-6:
                out.EraseTimeSample(attr, t)
    times = out.ListTimeSamplesForPath(Sdf.Path(f"{ANIM}.rotations"))
    out.startTimeCode, out.endTimeCode = times[0], times[-1]
    out.Save()
    return path


def add_objects(path: Path, kind: str, name: str, positions: list[np.ndarray], radius: float, times=None,
                seen: bool = True):
    """Task prims; ``seen``: GazeObjectAPI objects (the coupled loop: eyes and belief), else plain
    spheres the body-only controller knows."""
    layer = Sdf.Layer.FindOrOpen(str(path))
    group = Sdf.CreatePrimInLayer(layer, f"/{name}s")
    group.specifier, group.typeName = Sdf.SpecifierDef, "Xform"
    for i, pos in enumerate(positions):
        prim = Sdf.CreatePrimInLayer(layer, f"/{name}s/{name}{i}")
        prim.specifier, prim.typeName = Sdf.SpecifierDef, "Sphere"
        if seen:
            prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
        Sdf.AttributeSpec(prim, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = radius
        Sdf.AttributeSpec(prim, TASK, Sdf.ValueTypeNames.Token).default = kind
        tr = Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double3)
        if times is None:
            tr.default = Gf.Vec3d(*map(float, pos))
        else:
            for t, p in zip(times, pos):
                layer.SetTimeSample(tr.path, float(t), Gf.Vec3d(*map(float, p)))
        Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    layer.Save()


def crossing(ref, tcps: float, seed: int, count: int = 2, toward: bool = False):
    """Spheres (centres at 30 fps time codes) crossing the reference's path: each passes 0.45-0.6 m
    from the hips at a random time, at 0.6-1.4 m/s, 0.4-1.2 m up, from a random direction, or with
    ``toward`` coming at the walker from ahead (within 45 deg of head-on) and passing it no earlier
    than 0.7 s, so that each starts 1.5-2 m away, where the eyes can see it (the paper's "approaching
    obstacles"; from a random direction many come from behind or start beside the walker, out of
    the +-60 deg field of view until they touch)."""
    rng = np.random.default_rng(seed)
    t = ref.times[0] + np.arange(0.0, ref.times[-1] - ref.times[0] + 1e-6, 4.0)
    secs = (t - ref.times[0]) / tcps
    hips = ref.position("Hips")
    up = ref.up
    walk = hips[-1] - hips[0]
    heading = np.arctan2(walk[2], walk[0])  # the stage's ground plane (Y up): x = cos, z = sin
    paths = []
    for _ in range(count):
        tc = rng.uniform(0.7 if toward else 0.4, secs[-1] - 0.2)  # from ahead: seen 1.5-2 m away
        at = hips[int(round(tc * tcps))]
        a = heading + np.pi + rng.uniform(-0.25 * np.pi, 0.25 * np.pi) if toward else rng.uniform(0, 2 * np.pi)
        flat = np.array([np.cos(a), 0.0, np.sin(a)])
        side = np.cross(up, flat)
        centre = at - (at @ up) * up + side * rng.uniform(0.45, 0.6) * rng.choice([-1, 1]) + up * rng.uniform(0.4, 1.2)
        paths.append(centre + np.outer(secs - tc, flat * rng.uniform(0.6, 1.4)))
    return t, paths


def gaps(posed, stage_path: Path, prims: list[str], radius: float) -> np.ndarray:
    """Per frame, the smallest distance between any bone (joint to parent joint, 8 cm thick) and any
    sphere, at the spheres' true positions on the stage (USD's own transforms); < 0 is a contact."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(stage_path))
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(SKEL))
    topo = UsdSkel.Topology(skel.GetJointsAttr().Get())
    parents = np.array([topo.GetParent(i) for i in range(len(posed.joints))])
    bones = [(i, int(p)) for i, p in enumerate(parents) if p >= 0]
    out = []
    for f, t in enumerate(posed.times):
        cache = UsdGeom.XformCache(Usd.TimeCode(float(t)))
        centres = np.array([np.array(cache.GetLocalToWorldTransform(stage.GetPrimAtPath(p)))[3, :3] for p in prims])
        pts = posed.world[f, :, 3, :3]
        a, b = pts[[i for i, _ in bones]], pts[[p for _, p in bones]]
        ab = b - a
        s = np.clip(np.einsum("cbk,bk->cb", centres[:, None] - a[None], ab) / np.maximum(np.sum(ab * ab, 1), 1e-12), 0, 1)
        near = a[None] + s[..., None] * ab[None]
        out.append(float((np.linalg.norm(centres[:, None] - near, axis=-1) - BONE_M - radius).min()))
    return np.array(out)


def obstacle_scene(tmp: Path, seed: int, span: tuple[float, float] = SPAN, toward: bool = False,
                   seen: bool = True) -> tuple[Path, list[str]]:
    """The walk cut to ``span`` with two seeded spheres crossing it (:func:`crossing`), GazeObjectAPI
    objects (the coupled loop) or, ``seen=False``, plain spheres whose paths the body-only controller
    knows; the stage and the spheres' prim paths."""
    from . import measure

    src = cut(tmp / "obstacles.usda", *span)
    tcps = Sdf.Layer.FindOrOpen(str(src)).timeCodesPerSecond
    times, paths = crossing(measure.posed(str(src), SKEL), tcps, seed=seed, toward=toward)
    add_objects(src, "obstacle", "Obstacle", [np.array(p) for p in paths], RADIUS_M, times=times, seen=seen)
    return src, [f"/Obstacles/Obstacle{i}" for i in range(len(paths))]
