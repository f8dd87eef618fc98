"""The stepping-stones and moving-obstacle scenes of ``bench_physics.py`` (its ``--tasks stones*`` and
``obstacles*``) and the feet's heights by UsdSkel FK on a written layer; also used by
``_physics_speed.py``. Run ``bench_physics.py``, not this file."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BENCH = Path(__file__).with_name("bench_physics.py")  # the obstacle scenes run one per process through it
sys.path.insert(0, str(ROOT))

from usdgaze.physics import build, mpc, retarget  # noqa: E402

CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"


def _left(model, qpos0):
    import mujoco

    from usdgaze.physics.dynamics import MujocoBody

    body = MujocoBody(model)
    d = mujoco.MjData(body.mj)
    d.qpos[:] = qpos0
    mujoco.mj_kinematics(body.mj, d)
    hips = [b for b, r in enumerate(model.role) if r == "thigh"]
    side = sorted(hips, key=lambda b: model.names[b].lower().startswith("r"))  # left first
    v = d.xpos[side[0] + 1] - d.xpos[side[1] + 1]
    v[2] = 0.0
    return v / np.linalg.norm(v)


def _toes(model, qpos):
    import mujoco

    from usdgaze.physics.dynamics import MujocoBody
    from usdgaze.physics.stones import feet

    body = MujocoBody(model)
    d = mujoco.MjData(body.mj)
    out = []
    for q in qpos:
        d.qpos[:] = q
        mujoco.mj_kinematics(body.mj, d)
        out.append([d.xpos[toe].copy() for _, _, toe in feet(body)])
    return np.array(out), [n for n, _, _ in feet(body)]  # (F, feet, 3)


def _contacts(p: np.ndarray, secs: np.ndarray):
    from usdgaze.physics.stones import contact_mask

    speed = np.linalg.norm(np.gradient(p[:, :2], secs, axis=0), axis=1)
    on = contact_mask(p[:, 2], speed, float(np.diff(secs).mean()))
    edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
    return list(zip(edges[::2], edges[1::2]))


def stone_places(model, qpos: np.ndarray, secs: np.ndarray, shifts: dict, turn: float):
    """Stones at the reference's footfalls (model world, ``(S, 3)``) and which are displaced: those first
    stood on 0.3 s after the start and 0.3 s before the end, by ``shifts[foot]`` toward ``turn`` radians."""
    toes, names = _toes(model, qpos)
    placed, moved = [], []
    for f, name in enumerate(names):
        places = []
        for a, b in _contacts(toes[:, f], secs):
            foot = toes[a:b, f].mean(axis=0) * [1, 1, 0]
            near = [p for p in places if min(np.linalg.norm(foot - x) for x in p[1]) < 0.1]
            near[0][1].append(foot) if near else places.append((secs[a], [foot]))
        for first, feet_at in places:
            size = shifts.get(name, 0.0) if 0.3 <= first <= secs[-1] - 0.3 else 0.0
            placed.append(np.mean(feet_at, axis=0) + size * np.array([np.cos(turn), np.sin(turn), 0.0]))
            moved.append(size > 0)
    return np.array(placed), moved


def run_stones(opts: mpc.Options, shifts: dict, turn: float, span: tuple[float, float] = (1.0, 2.5)) -> dict:
    """One stepping-stone run: stones at the footfalls of 1.0-2.5 s (``stone_places``)."""
    from usdgaze.physics import stones

    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    keep = (clip.seconds >= span[0] - 1e-9) & (clip.seconds <= span[1] + 1e-9)
    qpos, secs = retarget.to_qpos(model, ref)[keep], clip.seconds[keep] - span[0]
    _, names = _toes(model, qpos)
    placed, moved = stone_places(model, qpos, secs, shifts, turn)
    start = time.perf_counter()
    r = mpc.simulate(model, qpos, secs, opts, tasks=[stones.factory(placed, (qpos, secs - secs[0]))])
    wall = time.perf_counter() - start
    sim, _ = _toes(model, r.qpos)
    landings = []
    for f, name in enumerate(names):
        for a, b in _contacts(sim[:, f], r.seconds):
            foot = sim[a:min(b, a + 4), f].mean(axis=0)  # the first ~0.1 s on the ground
            d = np.linalg.norm(placed[:, :2] - foot[:2], axis=1)
            landings.append((name, round(float(r.seconds[a]), 2), bool(moved[d.argmin()]), round(float(d.min()), 3)))
    # per reference contact, the toe's mean distance to its stone (what the shot's report judges)
    from usdgaze.physics.dynamics import MujocoBody
    from usdgaze.physics.tracking import resample

    plan = MujocoBody(model, h=opts.h)
    which = stones.StoneTask(plan, resample(qpos, secs, opts.h, plan), placed, frames=(qpos, secs - secs[0])).stone
    over = []
    for f, name in enumerate(names):
        v = r.task_terms[f"stones.{name}.stoneDistanceM"]
        edges = np.flatnonzero(np.diff(np.r_[0, which[f, :len(v)] >= 0, 0].astype(int)))
        for a, b in zip(edges[::2], edges[1::2]):
            if np.isfinite(v[a:b]).any():
                over.append((name, round(float(r.seconds[a] - r.seconds[0]), 2), bool(moved[which[f, a]]),
                             round(float(np.nanmean(v[a:b])), 3)))
    sim_s = float(r.seconds[-1] - r.seconds[0])
    return {"task": "stones", "turn_deg": round(float(np.degrees(turn))), "fell_at_s": r.fell_at,
            "wall_s": round(wall, 1), "fps_at_30": round(30 * sim_s / wall, 2), "contacts": over,
            "on_moved_m": [x[3] for x in over if x[2]],
            "others_max_m": max([x[3] for x in over if not x[2]], default=None),
            "landings": landings, "max_landing_m": max(x[3] for x in landings),
            "max_on_moved_m": max([x[3] for x in landings if x[2]], default=None),
            "costs_monotone": all(all(b <= a for a, b in zip(c, c[1:])) for c in r.solve_costs)}


def run_stones_fk(opts: mpc.Options, turn_deg: float) -> dict:
    """The stones test's scene (tests/test_physics_tasks.py: 1.0-2.5 s, a stone at each footfall, the
    right swing's displaced 15 cm toward its TOWARD turned ``turn_deg`` about the stage's up) through
    the physics pass; each reference contact's mean ground-plane toe distance to its stone by UsdSkel
    FK on the written layer (the test's measure)."""
    import tempfile

    from pxr import Sdf

    from tests import measure
    from tests import test_physics_tasks as T
    from tests.attend_support import compose
    from usdgaze.passes import physics as physics_pass

    c, s = np.cos(np.radians(turn_deg)), np.sin(np.radians(turn_deg))
    toward = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ T.TOWARD  # about +Y, the stage's up
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = T.cut(tmp / "stones.usda", *T.SPAN)
        ref = measure.posed(str(src), T.SKEL)
        tcps = Sdf.Layer.FindOrOpen(str(src)).timeCodesPerSecond
        placed, moved = [], []
        for toe in T.TOES:
            for a, b in T.contacts(ref, toe, tcps):
                foot = ref.position(toe)[a:b].mean(axis=0)
                foot -= (foot @ ref.up) * ref.up
                size = T.SHIFT[toe] if 0.3 <= a / tcps <= T.SPAN[1] - T.SPAN[0] - 0.3 else 0.0
                placed.append(foot + toward * size)
                moved.append(size > 0)
        T.add_objects(src, "stone", "Stone", placed, 0.15, seen=False)
        cpu0 = time.process_time()
        report = physics_pass.run(src, tmp / "out.usda", opts)[0]
        cpu = time.process_time() - cpu0
        sim = measure.posed(str(compose(tmp, src, tmp / "out.usda")), T.SKEL)
        rows, i = [], 0
        for toe in T.TOES:
            for a, b in T.contacts(ref, toe, tcps):
                off = sim.position(toe)[a:b] - placed[i]
                off -= np.outer(off @ sim.up, sim.up)
                rows.append((toe, round(a / tcps, 2), moved[i], round(float(np.linalg.norm(off, axis=1).mean()), 3)))
                i += 1
    return {"task": "stones-fk", "turn_deg": turn_deg, "toward": toward.round(3).tolist(),
            "fell_at_s": report.fell_at_s,
            "on_moved_m": [r[3] for r in rows if r[2]], "others_max_m": max(r[3] for r in rows if not r[2]),
            "contacts": rows, "min_pelvis_ratio": round(report.min_pelvis_ratio, 3),
            "mean_joint_error_deg": round(report.mean_joint_error_deg, 2), "cpu_s": round(cpu, 1)}


def run_stones_gaze(opts: mpc.Options, span: tuple[float, float], until_lift: bool, task: bool,
                    shift: dict | None = None, seed: int = 0, after_s: float = 0.0) -> dict:
    """The coupled loop (eyes, belief, body) on a crop of sample_stages/attend/stepping_stones.usda
    (stones as GazeObjectAPI objects; ``until_lift``: each important until its foot lifts, else until
    its landing as authored; ``task``: also physics stones), measured on the written layer by UsdSkel
    FK: per stone stepped on, when the written foot that steps on it lifts and whether the line of
    sight reached the stone before then (tests/stone_stages.py); ``shift``: stones displaced (stage
    units), ``seed``: the observation seed; ``after_s``: the take goes on past the shot's range."""
    import tempfile
    from dataclasses import asdict

    from tests import stone_stages
    from usdgaze.passes import physics as physics_pass

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = stone_stages.walk_stage(tmp / "walk.usda", *span, until_lift=until_lift, task=task, shift=shift,
                                      after_s=after_s)
        cpu0, t0 = time.process_time(), time.perf_counter()
        report = physics_pass.run(src, tmp / "out.usda", opts, seed=seed)[0]
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - t0
        rows = [{k: (round(v, 3) if isinstance(v, float) else v) for k, v in asdict(r).items()}
                for r in stone_stages.gaze_before_lift(tmp, src, tmp / "out.usda", shift)]
    checked = [r for r in rows if r["lift_s"] >= 0.4]  # the planner's first 0.4 s left out, as attend's test
    return {"task": "stones-gaze", "span_s": list(span), "take_after_s": after_s, "until_lift": until_lift,
            "stone_task": task,
            "shift": {k: np.round(v, 3).tolist() for k, v in (shift or {}).items()}, "seed": seed,
            "fell_at_s": report.fell_at_s, "problems": report.problems,
            "cpu_s": round(cpu, 1), "fps_at_30_per_cpu_s": round(30 * report.simulated_s / cpu, 2),
            "wall_s": round(wall, 1), "stones": rows,
            "reached_before_lift": f"{sum(r['reached'] for r in checked)} of {len(checked)}"}


def crossing(qpos: np.ndarray, secs: np.ndarray, seed: int):
    """Two spheres (25 cm) crossing the walk, each passing 0.45-0.6 m from the root at a random time,
    direction, speed (0.6-1.4 m/s) and height (0.4-1.2 m): ``(centres at seconds -> (K, 2, 3), radii)``."""
    rng = np.random.default_rng(seed)
    paths = []
    for _ in range(2):
        tc = rng.uniform(0.4, secs[-1] - 0.2)
        at = qpos[np.searchsorted(secs, tc), :3]
        a = rng.uniform(0, 2 * np.pi)
        flat = np.array([np.cos(a), np.sin(a), 0.0])
        centre = at * [1, 1, 0] + np.array([-flat[1], flat[0], 0]) * rng.uniform(0.45, 0.6) * rng.choice([-1, 1])
        centre[2] = rng.uniform(0.4, 1.2)
        paths.append((centre, flat * rng.uniform(0.6, 1.4), tc))
    return (lambda t: np.stack([c + np.outer(t - tc, v) for c, v, tc in paths], axis=1)), np.full(len(paths), 0.25)


def run_obstacles(opts: mpc.Options, seed: int) -> dict:
    """Two spheres crossing 1.0-2.2 s of the walk (``crossing``): overlap with the body's capsules with
    the controller and, for the reference, without."""
    import mujoco

    from usdgaze.physics import obstacles
    from usdgaze.physics.dynamics import MujocoBody

    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    keep = (clip.seconds >= 1.0 - 1e-9) & (clip.seconds <= 2.2 + 1e-9)
    qpos, secs = retarget.to_qpos(model, ref)[keep], clip.seconds[keep] - 1.0
    at, radii = crossing(qpos, secs, seed)
    body = MujocoBody(model)
    d = mujoco.MjData(body.mj)

    def deepest(q, t):
        out = np.inf
        for qq, tt in zip(q, t):
            d.qpos[:] = qq
            mujoco.mj_kinematics(body.mj, d)
            out = min(out, obstacles.clearance(body.mj, d, at(np.array([tt]))[0], radii))
        return out

    start = time.perf_counter()
    r = mpc.simulate(model, qpos, secs, opts, tasks=[obstacles.factory(at, radii)])
    wall = time.perf_counter() - start
    sim_s = float(r.seconds[-1] - r.seconds[0])
    return {"task": "obstacles", "form": obstacles.FORM, "seed": seed, "fell_at_s": r.fell_at, "wall_s": round(wall, 1),
            "fps_at_30": round(30 * sim_s / wall, 2), "reference_gap_m": round(deepest(qpos, secs), 3),
            "simulated_gap_m": round(deepest(r.qpos, r.seconds - r.seconds[0]), 3),
            "mean_joint_error_deg": round(float(r.joint_error_deg.mean()), 2),
            "costs_monotone": all(all(b <= a for a, b in zip(c, c[1:])) for c in r.solve_costs)}


def fk_foot_heights(src: Path, layer: Path, tmp: Path, model) -> tuple[np.ndarray, np.ndarray]:
    """Seconds from the start and, per frame of the written ``layer`` composed over ``src``, the height
    (m) of the lowest point of the model's foot capsules, posed by UsdSkel FK (``tests/measure.py``: no
    usdgaze math)."""
    from pxr import Usd, UsdGeom

    from tests import measure
    from tests.attend_support import compose

    posed = measure.posed(str(compose(tmp, src, layer)), str(_skeleton(src)))
    stage = Usd.Stage.Open(str(src))
    mpu = UsdGeom.GetStageMetersPerUnit(stage)
    seconds = (posed.times - posed.times[0]) / stage.GetTimeCodesPerSecond()
    feet = [b for b, r in enumerate(model.role) if r == "foot"]
    return seconds, np.min([measure.lowest_capsule_point(posed, model.joints[model.bodies[b]].rsplit("/", 1)[-1],
                                                [(v[:3], v[3:]) for k, v in model.geoms[b] if k == "capsule"],
                                                float(model.radius[b]), mpu) for b in feet], axis=0)


def _skeleton(src: Path):
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(src))
    return next(p.GetPath() for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))


def coupled_obstacles_one(seed: int, opts: mpc.Options, toward: bool = False, seen: bool = True) -> dict:
    """One seeded scene of the obstacle test (tests/obstacle_stages.py; ``toward``: the spheres come
    from ahead; ``seen``: objects of the coupled loop, else spheres whose paths the body-only
    controller knows) through the physics pass, measured on the written layer by UsdSkel FK: the
    smallest gap between the bones (8 cm thick) and the spheres, with and without the controller."""
    import tempfile

    from tests import measure
    from tests import obstacle_stages as obs
    from tests.attend_support import compose
    from usdgaze.passes import physics as physics_pass

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src, prims = obs.obstacle_scene(tmp, seed, toward=toward, seen=seen)
        c0 = time.process_time()
        report = physics_pass.run(src, tmp / "out.usda", opts)[0]
        cpu = time.process_time() - c0
        composed = compose(tmp, src, tmp / "out.usda")
        ref = obs.gaps(measure.posed(str(src), obs.SKEL), src, prims, obs.RADIUS_M)
        sim = obs.gaps(measure.posed(str(composed), obs.SKEL), composed, prims, obs.RADIUS_M)
        from usdgaze.physics import obstacles

        return {"task": "obstacles-coupled" if seen else "obstacles-known", "form": obstacles.FORM, "seed": seed,
                "toward": toward, "reference_gap_cm": round(100 * float(ref.min()), 1),
                "simulated_gap_cm": round(100 * float(sim.min()), 1), "fell_at_s": report.fell_at_s,
                "mean_joint_error_deg": round(report.mean_joint_error_deg, 2), "cpu_s": round(cpu, 1),
                "fps_at_30_per_cpu_s": round(30 * report.simulated_s / cpu, 2), "problems": report.problems}


def run_coupled_obstacles(opts: mpc.Options, seeds, toward: bool = False, seen: bool = True,
                          form: str = "body") -> list[dict]:
    """The obstacle test's scenes, each in a fresh process (as the catch throws)."""
    import subprocess

    rows = []
    for seed in seeds:
        cmd = [sys.executable, str(BENCH), "--obstacle-scene", str(seed), "--h", str(opts.h), "--horizon",
               str(opts.horizon_s), "--iterations", str(opts.iterations), "--obstacle-form", form]
        cmd += (["--toward"] if toward else []) + ([] if seen else ["--known"])
        rows.append(json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.splitlines()[-1]))
        print(json.dumps(rows[-1]), flush=True)
    hit = [r for r in rows if r["simulated_gap_cm"] < 0]
    fell = [r for r in rows if r["fell_at_s"] is not None]
    print(f"{rows[0]['task']}: contact in {len(hit)} of {len(rows)} runs, {len(fell)} falls (bar: no contact)", flush=True)
    return rows
