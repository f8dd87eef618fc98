"""Full-body MPC on MuJoCo (``usdgaze.physics``): output frames per second for each task, 1 and 2 cores.

Tasks: ``track`` follows the CMU 131_01 walk (``--seconds``, default its whole 8.3 s), ``push``
stands through a 150 N, 0.2 s push at the chest from the character's left (the first 1.5 s of the
clip, push at 0.5 s); ``stones`` walks 1.0-2.5 s of it with a stone at each footfall, the right
foot's swing stone displaced 15 cm in four directions (and, as ``stones10``, the left foot's shuffle
stone 10 cm: four runs each), printing each reference contact's mean toe distance to its stone and each
toe landing's; ``stones-fk`` runs the stones test's own scene (the displacement turned 0/90/180/270
deg about up) through the physics pass and measures by UsdSkel FK on the written layer; ``stones-walk``
runs the walk itself (4.0-5.5 s, at ``--h``), the left foot's landing displaced 15 cm in four directions;
``stones-bar`` the whole bar in one coupled shot (the test's: 4.0-5.5 s, ``--stones-end``, at ``--h``, eyes, belief, body and
the stones' task, Stone10 displaced 15 cm toward the stage's +X/+Z/-X/-Z, ``--seeds`` observation seeds);
``stones-gaze`` runs the coupled loop (eyes, belief, body) on 4.0-6.0 s of the walk
with stepping_stones.usda's stones as objects (each important until its foot lifts, or until it
lands as authored; with and without the stones' physics task) and prints, by UsdSkel FK on the
written layer, whether the gaze reached each stone before the written foot stepping on it lifted; ``obstacles`` walks
1.0-2.2 s among two spheres crossing its path (``--seeds``, five by default), printing the deepest
overlap of body and spheres with and without the controller; ``obstacles-coupled`` runs the obstacle
test's scenes (tests/obstacle_stages.py: seeds 0,2,4,7,8, each touched by the reference; with
``--toward`` the spheres come from ahead, seeds 0,2,5,6,7) through ``attend --physics`` with the eyes
and belief coupled, ``obstacles-known`` the same scenes body-only (the planner knows the paths), each
measured on the written layer by UsdSkel FK (``--obstacle-form root``: the paper's root cost). Each runs pinned to 1 core and to 2 cores (finite differences of the window
split over 2 threads), one BLAS thread. Printed per run: wall time, simulated seconds per wall second,
output frames per second at 30 fps and at the planner's 1/h, and the shot's measures (fall, lowest
pelvis height against the reference, mean joint-angle error, deepest foot below the ground), against
the paper's 1-6 frames/s on six cores and the goal of >= 6 frames/s on two. "Foot below the ground"
is the deepest point of the model's foot geoms (the capsules of the ankle, sole and toe bodies: the
lower end of each, minus its radius) on the simulated steps; with ``--fk`` the track task runs
through the physics pass (``usdgaze attend --physics``) instead and also measures it on the WRITTEN
layer at every frame of the clip, by UsdSkel FK: the same capsules fixed to the written joints.

``catch``: the coupled loop (eyes, belief and body, ``usdgaze attend --physics``) on five seeded
throws from the front within reach and one from behind (tests/catch_stages.py), each measured on the
written layer by UsdSkel FK: the nearer palm's distance to the true ball at its arrival (bar: within
10 cm in at least 4 of 5), and for the throw from behind the gaze and hand before the ball enters
the field of view.

    python benchmarks/bench_physics.py [--tasks track,push] [--seconds S] [--cores 1,2] [--h H]
        [--horizon S] [--iterations 1] [--stride 1] [--reuse 1] [--speed] [--fk]

``--speed``: every task once per core count, timed alone, with frames/s per wall second, per CPU
second and the idle bound (``benchmarks/_physics_speed.py``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from usdgaze.physics import build, mpc, retarget  # noqa: E402

CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"

from _physics_tasks import (_left, coupled_obstacles_one, fk_foot_heights, run_coupled_obstacles,  # noqa: E402
                            run_obstacles, run_stones, run_stones_fk, run_stones_gaze)


def _track_through_pass(opts: mpc.Options, model) -> tuple:
    """The whole walk through the physics pass: its report and the feet's heights by UsdSkel FK."""
    import tempfile

    from usdgaze.passes import physics as physics_pass

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "walk.usda"
        report = physics_pass.run(CMU, out, opts)[0]
        seconds, low = fk_foot_heights(CMU, out, Path(tmp), model)
    return report, seconds, low


def run_task(task: str, seconds: float, opts: mpc.Options, fk: bool = False) -> dict:
    clip = build.load_clip(CMU)
    model, ref = build.body_model(clip)
    qpos = retarget.to_qpos(model, ref)
    end = seconds if task == "track" else 1.5
    keep = clip.seconds <= end + 1e-9
    pushes = ()
    if task == "push":
        chest = next(b for b, n in enumerate(model.names) if n.lower() in ("chest2", "spine2", "chest", "spine1"))
        pushes = (mpc.Push(chest, 150.0 * _left(model, qpos[0]), 0.5, 0.2),)
    start = time.perf_counter()
    cpu0 = time.process_time()
    if fk and task == "track":
        report, fk_s, low = _track_through_pass(opts, model)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
        sim_s = report.simulated_s
        return {"task": task, "simulated_s": round(sim_s, 3), "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                "fps_at_30": round(30 * sim_s / wall, 2), "cpu_fps_at_30": round(30 * sim_s / cpu, 2),
                "fell": report.fell, "min_pelvis_ratio": round(report.min_pelvis_ratio, 3),
                "mean_joint_error_deg": round(report.mean_joint_error_deg, 2),
                "max_foot_below_ground_m": round(report.max_foot_below_ground_m, 4),
                "contact_depth_m": round(report.contact_depth_m, 4),
                "fk_max_foot_below_ground_m": round(float(-low.min()), 4), "fk_frames": len(low),
                "fk_frames_below_2cm": int((low < -0.02).sum()), "fk_deepest_at_s": round(float(fk_s[low.argmin()]), 3)}
    r = mpc.simulate(model, qpos[keep], clip.seconds[keep], opts, pushes)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
    sim_s = float(r.seconds[-1] - r.seconds[0])
    upto = r.seconds < r.fell_at if r.fell else np.ones(len(r.seconds), bool)  # measures until a fall
    return {"task": task, "simulated_s": round(sim_s, 3), "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
            "sim_s_per_wall_s": round(sim_s / wall, 4), "fps_at_30": round(30 * sim_s / wall, 2),
            "fps_at_1_over_h": round(sim_s / opts.h / wall, 2),
            # CPU seconds of all threads: on a shared machine the 1-core figure a free core would give
            # (with 2 threads it sums both, so it understates a free 2-core machine's rate).
            "cpu_fps_at_30": round(30 * sim_s / cpu, 2), "load": round(os.getloadavg()[0], 1), "fell_at_s": r.fell_at,
            "min_pelvis_ratio": round(float(r.pelvis_ratio[upto].min()), 3),
            "mean_joint_error_deg": round(float(r.joint_error_deg[upto].mean()), 2),
            "max_joint_error_deg": round(float(r.joint_error_deg[upto].max()), 2),
            "max_foot_below_ground_m": round(float(r.foot_below_ground_m[upto].max()), 4),
            "contact_depth_m": round(float(r.sank_m[upto].max()), 4),
            "costs_monotone": all(all(b <= a for a, b in zip(c, c[1:])) for c in r.solve_costs)}


def catch_one(seed: str, opts: mpc.Options) -> dict:
    """One throw ("behind" or a seed) through the physics pass (as the CLI runs it), measured."""
    import tempfile

    from pxr import Sdf

    from tests import catch_stages as cs
    from usdgaze.passes import physics as physics_pass

    start, arrival, flight = cs.behind_throw() if seed == "behind" else cs.seeded_throw(int(seed))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = cs.throw_stage(tmp / "throw.usda", start, arrival, flight, flight + 0.2)
        t0 = time.perf_counter()
        reports = physics_pass.run(src, tmp / "out.usda", opts, seed=0 if seed == "behind" else int(seed))
        wall = time.perf_counter() - t0
        m = cs.catch_measures(src, tmp / "out.usda", tmp, flight)
        sim_s = reports[0].simulated_s
        frames = Sdf.Layer.FindOrOpen(str(tmp / "out.usda")).customLayerData["usdgaze:physics"][cs.SKEL]["frames"]
        t = np.array(frames["seconds"]) - frames["seconds"][0]
        k = min(int(np.searchsorted(t, flight - 1e-6)), len(t) - 1)
        own = frames["catch.handToArrivalM"][k]  # the planner's own: the hand to its estimated arrival point
        return {"task": "catch", "throw": seed, "flight_s": round(flight, 3),
                "hand_to_ball_at_arrival_cm": round(100 * m["at_arrival"], 1),
                "hand_to_estimate_at_arrival_cm": round(100 * own, 1) if own == own else None,
                "nearest_cm": round(100 * float(m["distance"].min()), 1), "fell": reports[0].fell,
                "wall_s": round(wall, 1), "fps_at_30": round(30 * sim_s / wall, 2)}


def run_catch(opts: mpc.Options, seeds=range(5)) -> list[dict]:
    """The five seeded throws and the one from behind, each in a fresh process: a closed loop this
    sensitive gives other bits after other work in the same process (measured: 1 vs 28 cm)."""
    import subprocess

    rows = []
    for seed in [*map(str, seeds), "behind"]:
        cmd = [sys.executable, __file__, "--throw", seed, "--h", str(opts.h), "--horizon", str(opts.horizon_s),
               "--iterations", str(opts.iterations), "--stride", str(opts.fd_stride), "--reuse", str(opts.fd_reuse)]
        rows.append(json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.splitlines()[-1]))
        print(json.dumps(rows[-1]), flush=True)
    near = [r for r in rows if r["throw"] != "behind" and r["hand_to_ball_at_arrival_cm"] <= 10.0]
    print(f"catch: {len(near)} of {len(rows) - 1} front throws within 10 cm at arrival (bar: >= 4 of 5)", flush=True)
    return rows


def _options(a, **kw) -> mpc.Options:
    """The bench's options: ``--stride`` and ``--reuse`` for every task, ``--horizon`` for every shot
    where given, else the command's windows by task."""
    from usdgaze.passes.physics_options import with_window

    return with_window(mpc.Options(**{"fd_stride": a.stride, "fd_reuse": a.reuse, **kw}), a.horizon)


def _step(a, task: str) -> float:
    """``--h``, else the command's step for the task: the catch's (a ball to catch) or the default."""
    return a.h if a.h is not None else (mpc.Options.moving_h if task == "catch" else mpc.Options.h)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tasks", default="track,push")
    ap.add_argument("--seconds", type=float, default=8.3)
    ap.add_argument("--cores", default="1,2")
    ap.add_argument("--h", type=float, default=None,
                    help="the step of track, push, catch, stones-bar, stones-walk (default: the command's by task, "
                    "0.03 s for the catch, 0.02 s for the others)")
    ap.add_argument("--horizon", type=float, default=None,
                    help="the window of every shot (default: the command's, 0.6 s and 1.0 s with stepping stones)")
    ap.add_argument("--iterations", type=int, default=1)
    ap.add_argument("--take-after", type=float, default=0.0,
                    help="stones-bar: the walk's take goes on this many seconds past the shot's range")
    ap.add_argument("--stones-end", type=float, default=5.5,
                    help="stones-bar: the shot's last second of the walk (5.5: the test's, 0.2 s after the "
                    "reference lands on Stone10; 5.8 leaves the landing 0.5 s)")
    ap.add_argument("--seeds", default=None, help="obstacles: 0,1,2,3,4; obstacles-coupled: 0,2,4,7,8 (--toward: 0,2,5,6,7)")
    ap.add_argument("--stride", type=int, default=1, help="finite differences every STRIDE steps, interpolated")
    ap.add_argument("--reuse", type=int, default=1, help="finite differences kept up to REUSE solves (mpc.Options.fd_reuse)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--speed", action="store_true", help="frames/s of each task (--tasks, default all) on each of "
                    "--cores, timed alone (benchmarks/_physics_speed.py)")
    ap.add_argument("--fk", action="store_true", help="track: through the physics pass, feet measured on the layer")
    ap.add_argument("--throw", default=None, help=argparse.SUPPRESS)  # one catch throw (run_catch's worker)
    ap.add_argument("--obstacle-scene", type=int, default=None, help=argparse.SUPPRESS)  # one coupled scene
    ap.add_argument("--toward", action="store_true", help="obstacles-coupled/-known: the spheres come from ahead")
    ap.add_argument("--known", action="store_true", help=argparse.SUPPRESS)  # one scene, body-only
    ap.add_argument("--obstacle-form", default="body", help="obstacles*: the cost's form, body (ours) or root (the paper's)")
    a = ap.parse_args()
    from usdgaze.physics import obstacles

    obstacles.FORM = a.obstacle_form
    if a.throw is not None:
        print(json.dumps(catch_one(a.throw, _options(a, h=_step(a, "catch"), iterations=a.iterations))))
        return
    if a.obstacle_scene is not None:
        opts = _options(a, h=0.03, iterations=a.iterations)
        print(json.dumps(coupled_obstacles_one(a.obstacle_scene, opts, a.toward, not a.known)))
        return
    from threadpoolctl import threadpool_limits

    cpus = sorted(os.sched_getaffinity(0))
    if a.speed:
        speed_table(a, cpus)
        return
    rows = []
    for task in a.tasks.split(","):
        if task == "catch":
            run_catch(_options(a, h=_step(a, task), iterations=a.iterations))
            continue
        if task == "stones-fk":
            opts = _options(a, h=0.03, iterations=a.iterations)
            for turn in (0.0, 90.0, 180.0, 270.0):
                print(json.dumps(run_stones_fk(opts, turn)), flush=True)
            continue
        if task == "stones-gaze":
            opts = _options(a, h=0.03, iterations=a.iterations)
            for until_lift, task_on in ((True, False), (False, False), (True, True)):
                print(json.dumps(run_stones_gaze(opts, (4.0, 6.0), until_lift, task_on)), flush=True)
            continue
        if task == "stones-bar":  # the whole bar in one coupled shot (the test's scene, four directions)
            opts = _options(a, h=_step(a, task), iterations=a.iterations)
            for seed in [int(s_) for s_ in (a.seeds or "0").split(",")]:
                for turn in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):  # the stage's +X, +Z, -X, -Z
                    shift = {"Stone10": 0.15 * np.array([np.cos(turn), 0.0, np.sin(turn)])}
                    print(json.dumps(run_stones_gaze(opts, (4.0, a.stones_end), True, True, shift, seed, a.take_after)),
                          flush=True)
            continue
        if task == "stones-walk":  # the walk itself, 4.0-5.5 s: the left foot's 0.67 s landing displaced
            opts = _options(a, h=_step(a, task), iterations=a.iterations)
            for turn in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
                print(json.dumps(run_stones(opts, {"LeftAnkle": 0.15}, turn, (4.0, 5.5))), flush=True)
            continue
        if task in ("obstacles-coupled", "obstacles-known"):
            default = "0,2,5,6,7" if a.toward else "0,2,4,7,8"  # the first five the reference touches
            run_coupled_obstacles(_options(a, h=0.03, iterations=a.iterations),
                                  [int(s_) for s_ in (a.seeds or default).split(",")], a.toward,
                                  task == "obstacles-coupled", a.obstacle_form)
            continue
        if task in ("stones", "stones10", "obstacles"):
            opts = _options(a, h=0.03, iterations=a.iterations)
            shifts = {"RightAnkle": 0.15} | ({"LeftAnkle": 0.10} if task == "stones10" else {})
            runs = ([run_obstacles(opts, int(s_)) for s_ in (a.seeds or "0,1,2,3,4").split(",")] if task == "obstacles" else
                    [run_stones(opts, shifts, turn) for turn in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi)])
            for row in runs:
                print(json.dumps(row), flush=True)
            continue
        for cores in (int(c) for c in a.cores.split(",")):
            os.sched_setaffinity(0, cpus[:cores])
            opts = _options(a, h=_step(a, task), iterations=a.iterations, workers=cores)
            with threadpool_limits(1):
                row = run_task(task, a.seconds, opts, a.fk) | {"cores": cores}
            rows.append(row)
            print(json.dumps(row) if a.json or "fk_frames" in row else
                  f"{task:6s} {cores} core(s): {row['simulated_s']:.2f} s simulated in {row['wall_s']:.1f} s wall "
                  f"-> {row['fps_at_30']:.2f} frames/s at 30 fps ({row['fps_at_1_over_h']:.2f} at 1/h; "
                  f"{row['cpu_fps_at_30']:.2f} per CPU second; load {row['load']}) "
                  f"vs paper 1-6 on 6 cores, goal >= 6 on 2 | fell {row['fell_at_s']} | (until then) pelvis >= "
                  f"{row['min_pelvis_ratio']:.2f} of ref | joint err {row['mean_joint_error_deg']:.1f} deg | "
                  f"foot below ground {100 * row['max_foot_below_ground_m']:.1f} cm", flush=True)
    os.sched_setaffinity(0, cpus)


def speed_table(a, cpus: list[int]) -> None:
    """``--speed``: each task once per core count (its threads as many), then the summary table."""
    from threadpoolctl import threadpool_limits

    import _physics_speed as speed  # benchmarks/ is on sys.path when run as a script

    tasks = speed.TASKS if a.tasks == "track,push" else tuple(a.tasks.split(","))
    rows = []
    for task in tasks:
        for cores in (int(c) for c in a.cores.split(",")):
            os.sched_setaffinity(0, cpus[:cores])
            h = 0.03 if task.startswith(("stones", "obstacles")) else _step(a, task)  # as the task runs above
            opts = _options(a, h=h, iterations=a.iterations, workers=cores)
            with threadpool_limits(1):
                rows.append(speed.run(task, cores, opts, a.seconds, sys.modules[__name__]))
            print(json.dumps(rows[-1]), flush=True)
    os.sched_setaffinity(0, cpus)
    print(speed.table(rows), flush=True)


if __name__ == "__main__":
    main()
