"""The physics pass: simulate a clip's whole body on MuJoCo under the full-body MPC and write it back
as an override layer (root included), with the per-shot report and per-frame measures.

Tasks authored in the stage (read at this edge, then plain arrays):

* a push: on the SkelRoot, ``usdgaze:physics:pushForce`` (float3, time-sampled, newtons along the
  stage's axes) and ``usdgaze:physics:pushJoint`` (token, the joint whose body is pushed). Each
  sample's force holds until the next sample, so ``{1.0: (0, 0, 150), 1.2: (0, 0, 0)}`` is a 150 N
  push for 0.2 s.
* stepping stones and moving obstacles: prims (GazeObjectAPI objects, so the eyes can see them) with
  ``token usdgaze:physics:task = "stone"`` or ``"obstacle"``. A stone's position is its world
  translation at the clip's start; an obstacle's is its animated world translation, its size the
  object's ``gaze:object:radius`` (``usdgaze.physics.stones``, ``usdgaze.physics.obstacles``). A
  reference contact whose toe ends up on average more than 5 cm from its stone, or whose foot never
  comes down within 0.3 s of it, or a body geom touching an obstacle, is reported as a problem of
  the shot.

Honest failure: when the pelvis drops below 80% of the reference's height the shot is reported as a
fall (time of the first such frame), and a run MuJoCo's step blew up before that as diverged; a
foot more than 2 cm below the ground is a problem too (its depth and when). The
layer still holds what was simulated unless ``keep_failed`` is False, in which case nothing is
written and the command fails. A shot with a problem is first simulated again with more solver
iterations a step, and the report says which simulation was kept (``_simulate_shot``).

The report, its problems and the per-step measures are made in :mod:`usdgaze.passes.physics_report`.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from usdgaze.core.hints import BindHints
from usdgaze.errors import UsdGazeError
from usdgaze.files.kinds import require_file
from usdgaze.passes.physics_report import (  # noqa: F401  (the pass's names)
    FOOT_TOLERANCE_M, HEADING_TOLERANCE_DEG, STONE_TOLERANCE_M, ShotReport, foot_problems, heading_problems,
    shot_summary, task_problems)
from usdgaze.passes.pushes import PUSH_FORCE, PUSH_JOINT, read_pushes  # noqa: F401  (the pass's names)
from usdgaze.passes.physics_options import check_window
from usdgaze.passes.physics_shots import TASKS, Shot, read_shots, task_prims  # noqa: F401  (the pass's names)
from usdgaze.passes.take import through_take
from usdgaze.physics import mpc


def read_tasks(stage, clip, model, source: str, ref_qpos: np.ndarray, objects: list[str] | None = None, *,
               task_found: dict[str, list]) -> list:
    """Task factories for the stones and obstacles authored on ``stage`` (see the module docstring);
    ``ref_qpos`` is the reference at the clip's frames (stone contacts are found there); ``objects``:
    the coupled loop's object paths, whose belief the obstacle task then reads; ``task_found``: the
    stage's task prims, as ``task_prims`` found them (once a shot, ``physics_shots.read_shots``)."""
    from usdgaze.physics import obstacles, stones
    from usdgaze.usd.objects import read_objects

    factories = []
    rot = model.to_model / np.linalg.norm(model.to_model[:, 0])  # metres in, metres out
    for kind, found in task_found.items():
        if not found:
            continue
        objs = read_objects(stage, source, found, clip.times, clip.meters_per_unit, faces=False)  # bodies to walk round
        if kind == "stone":
            frames = (ref_qpos, clip.seconds - clip.seconds[0])
            factories.append(stones.factory(np.array([rot @ o.positions[0] for o in objs]), frames,
                                            names=[str(o.path) for o in objs]))
            continue
        paths = np.stack([o.positions @ rot.T for o in objs], axis=1)  # (F, J, 3)
        secs = clip.seconds - clip.seconds[0]

        def centres_at(t, paths=paths, secs=secs):
            flat = paths.reshape(len(secs), -1)
            return np.stack([np.interp(t, secs, flat[:, i]) for i in range(flat.shape[1])], -1).reshape(len(t), -1, 3)

        seen = None if objects is None else [objects.index(o.path) if o.path in objects else -1 for o in objs]
        factories.append(obstacles.factory(centres_at, np.array([o.radius for o in objs]), seen))
    return factories


def _frames_from_steps(result: mpc.Result, seconds: np.ndarray, dyn_quats: list[int]) -> tuple[np.ndarray, int]:
    """Simulated ``qpos`` at the clip's sample times inside the simulated span (nlerp between steps)."""
    inside = seconds <= result.seconds[-1] + 1e-9
    t = seconds[inside]
    s = result.seconds
    i = np.clip(np.searchsorted(s, t, side="right") - 1, 0, max(len(s) - 2, 0))
    if len(s) < 2:
        return np.repeat(result.qpos[:1], len(t), 0), int(inside.sum())
    a = np.clip((t - s[i]) / (s[i + 1] - s[i]), 0, 1)[:, None]
    q0, q1 = result.qpos[i], result.qpos[i + 1].copy()
    for a4 in dyn_quats:
        flip = np.sum(q0[:, a4:a4 + 4] * q1[:, a4:a4 + 4], axis=1) < 0
        q1[flip, a4:a4 + 4] *= -1
    q = (1 - a) * q0 + a * q1
    for a4 in dyn_quats:
        q[:, a4:a4 + 4] /= np.linalg.norm(q[:, a4:a4 + 4], axis=1, keepdims=True)
    return q, int(inside.sum())


def simulate_clip(clip, root, options: mpc.Options, total_mass: float = 75.0, progress=None, chain_frame=None,
                  ahead=None, *, task_found: dict[str, list], body=None):
    """Simulate one clip; its :class:`ShotReport`, the override and the per-frame measures
    (``chain_frame``: the gaze binding, for rigs whose joint names do not tell the body's segments;
    ``ahead``: the take's clip after the shot, which only the planner sees; ``task_found``: the
    stage's task prims, ``task_prims``'s; ``body``: its ``build.body_model``, built here if None)."""
    from usdgaze.physics import build, retarget

    model, ref = body or build.body_model(clip, total_mass, chain_frame=chain_frame)
    pushes = read_pushes(root, clip, model, f"{clip.source}:{root.GetPath()}")
    ref_qpos = retarget.to_qpos(model, ref)  # on the ground: checked with every shot's tasks (read_shots)
    tasks = read_tasks(root.GetStage(), clip, model, clip.source, ref_qpos, task_found=task_found)
    start = time.perf_counter()
    result = mpc.simulate(model, ref_qpos, clip.seconds, options, pushes, progress, tasks=tasks,
                          ahead=take_after(model, ahead))
    wall = time.perf_counter() - start
    qadr, _ = model.layout()
    quats = [3] + [int(qadr[b]) for b, k in enumerate(model.kind) if k == "ball"]
    qpos, n = _frames_from_steps(result, clip.seconds, quats)
    rotations, translations = retarget.from_qpos(model, qpos, _head(ref, n))
    # A fall stops the simulation early: the frames after it hold its last pose, so the layer samples
    # the frames the input does (validate's OtherTake; a layer over a take ends where the shot does).
    held = np.minimum(np.arange(len(clip.times)), n - 1)
    rotations, translations = rotations[held], translations[held]
    report, terms = shot_summary(clip, result, n, len(pushes), wall)
    return report, _body_override(clip, rotations, translations), terms


def take_after(model, ahead) -> tuple[np.ndarray, np.ndarray] | None:
    """The take's clip after the shot as the model's ``qpos`` per frame and its seconds (None: none)."""
    from usdgaze.physics import retarget

    if ahead is None:
        return None
    return retarget.to_qpos(model, retarget.Reference.from_clip(ahead)), ahead.seconds


def _body_override(clip, rotations: np.ndarray, translations: np.ndarray):
    """Every joint of the simulated body at the clip's frames: the animation's own joints in its order,
    then those it does not list (all of them for a skeleton with no animation), appended with their
    rest scales so every existing index stays valid."""
    from usdgaze.core import rotations as rot
    from usdgaze.usd.layers import AnimOverride

    cols = [int(j) for j in clip.anim_to_skel]
    listed = set(cols)
    extra = [j for j in range(len(clip.joints)) if j not in listed]
    grow = bool(extra) or not clip.animation_bound
    scales = None
    if grow:
        rest_scales = rot.decompose_tr(clip.rest_local[extra])[2].astype(np.float16)
        n = len(clip.times)
        scales = np.concatenate([clip.scales, np.broadcast_to(rest_scales, (n, len(extra), 3))], axis=1)
    idx = np.array(cols + extra, dtype=int)
    out_rot, out_trans = rotations[:, idx].astype(np.float32), translations[:, idx].astype(np.float32)
    lacking = np.flatnonzero(idx < 0)  # the animation's joints the skeleton lacks: written through
    out_rot[:, lacking], out_trans[:, lacking] = clip.rotations[:, lacking], clip.translations[:, lacking]
    return AnimOverride(animation=clip.animation, times=clip.times,
                        joints=list(clip.anim_joints) + [clip.joints[j] for j in extra],
                        rotations=out_rot, translations=out_trans, scales=scales, write_joints=grow,
                        skeleton=None if clip.animation_bound else clip.skeleton, define=not clip.animation_bound)


def _head(ref, n: int):
    from usdgaze.physics.retarget import Reference

    s2w = ref.skel_to_world if len(ref.skel_to_world) == 1 else ref.skel_to_world[:n]
    return Reference(ref.translations[:n], ref.rotations[:n], ref.scales[:n], s2w)


def retry_ladder(options: mpc.Options) -> list[int]:
    """The solver iterations a step of each further simulation of a shot with a problem: ``retry_iterations``,
    then twice that (at most 10); none where ``retry_iterations`` is not more than ``iterations`` (0: none)."""
    if options.retry_iterations <= options.iterations:
        return []
    return sorted({options.retry_iterations, min(2 * options.retry_iterations, 10)})


def _simulate_shot(attempt, options: mpc.Options) -> tuple:
    """``attempt(options)`` (a shot's report, override, per-frame terms, inspection or None); while the kept
    simulation has a problem (a fall, a foot sunk over 2 cm, a stone missed, an obstacle touched, a ball
    not reached; not one that another simulation cannot mend, ``ShotReport.unmendable``) the shot is
    simulated again with the next of ``retry_ladder``'s iterations a step, and that kept unless it is
    worse (it fell where the kept one stood, or it has more problems, or as many with a deeper foot).
    With one iteration 3 of 12 stepping-stone shots fell; the second and third simulations rescue
    different shots of the chaotic loop (docs/physics-log.md, "A third simulation"); each is spent
    only where the one kept before it failed."""
    kept = attempt(options)
    kept[0].iterations, kept[0].window_s, kept[0].timestep_s = options.iterations, options.horizon_s, options.h
    others, wall = [], kept[0].wall_s
    # Ties go by the deepest foot: the whole CMU walk's retry (2 iterations) had one problem as the
    # first did, a foot 3.6 cm deep against 2.2, and was kept.
    rank = lambda r: (r.fell, len(r.problems), r.max_foot_below_ground_m)  # noqa: E731
    for iterations in retry_ladder(options):
        if not set(kept[0].problems) - set(kept[0].unmendable):
            break
        again = attempt(replace(options, iterations=iterations))
        again[0].iterations, again[0].window_s, again[0].timestep_s = iterations, options.horizon_s, options.h
        wall += again[0].wall_s
        kept, other = (again, kept) if rank(again[0]) <= rank(kept[0]) else (kept, again)
        others.append(other[0])
    if others:
        kept[0].other_attempt = [f"with {o.iterations} iteration(s) a step: {p}" for o in others for p in o.problems]
        kept[0].wall_s = wall
    return kept


def _attempt(shot: Shot, options: mpc.Options, total_mass: float, progress, seed: int) -> tuple:
    """One simulation of a shot: its report, override, per-frame terms and the coupled loop's
    inspection (None for the body alone)."""
    from usdgaze.passes import visuomotor

    prims, paths, catches = shot.scene
    if prims:  # something to look at: eyes, belief and body in one loop
        return visuomotor.simulate_clip(shot.clip, shot.root, options, prims, paths, catches, total_mass, progress,
                                        seed, shot.chain_frame, shot.ahead, task_found=shot.tasks, body=shot.body)
    return (*simulate_clip(shot.clip, shot.root, options, total_mass, progress, shot.chain_frame, shot.ahead,
                           task_found=shot.tasks, body=shot.body), None)


def _planner_record(options: mpc.Options) -> dict:
    """The settings that decide the simulated motion, for the layer (threads do not: same bytes), and
    the MuJoCo release that simulated it: another release simulates other bits."""
    import mujoco

    return {"mujoco": mujoco.__version__,
            "timestep": options.h, **({} if options.moving_h is None else {"movingTimestep": options.moving_h}),
            "window": options.horizon_s,
            **({} if options.stones_horizon_s is None else {"stonesWindow": options.stones_horizon_s}),
            "iterations": options.iterations,
            "retryIterations": options.retry_iterations, "firstIterations": options.first_iterations,
            "fdStride": options.fd_stride, "fdReuse": options.fd_reuse, "groundFeet": options.ground_feet}


def run(input_path: str | os.PathLike, out: str | os.PathLike, options: mpc.Options = mpc.Options(),
        skel_root: str | None = None, keep_failed: bool = True, total_mass: float = 75.0,
        progress=None, seed: int = 0, binding: BindHints | None = None, record: dict | None = None,
        no_clobber: bool = False, make_folders: bool = False) -> list[ShotReport]:
    """Simulate every skeleton of ``input_path`` (or under ``skel_root``) and write ``out``.

    ``binding`` (``--bind``/``--forward``) says which joints are the head, neck and eyes where names
    do not, as for ``apply``: the eyes, their inspection and the gaze are placed by it. Every
    skeleton is read and bound before any is simulated, so a bad one costs no simulation.
    ``record``: extra entries for the layer's ``customLayerData["usdgaze"]`` (a batch resume key).
    The output goes through the one writer: it may not be the input or any layer the input
    composes, and nothing is left behind on failure or interruption."""
    from usdgaze.api import _open_input
    from usdgaze.files.transaction import Outputs
    from usdgaze.passes.catches import kind_notes
    from usdgaze.physics.dynamics import require_mujoco
    from usdgaze.usd.layers import check_output_path, composed_override_notes

    require_mujoco()  # before any work: a missing extra is one line, exit 2
    source = str(input_path)
    require_file(source)
    check_window(options, "--window")
    with Outputs(no_clobber=no_clobber) as tx:
        tx.read(source)  # first, so a clash names the input as such
        if make_folders:  # kept only if the command succeeds
            tx.make_folder(Path(out).parent)
        out_path = tx.claim(check_output_path(out), "--out")
        stage = _open_input(tx, source)
        tx.check_replaceable()  # every input recorded: before the work
        headless: list[str] = []
        shots = read_shots(stage, source, skel_root, options, binding, total_mass, headless)
        reports, layer = _simulate_all(stage, source, shots, options, total_mass, progress, seed, keep_failed,
                                       record)
        notes = composed_override_notes(stage, source) + headless
        for shot, r in zip(shots, reports):
            r.warnings = list(notes) + kind_notes(shot.root, shot.scene[0], shot.scene[2], source)
        tx.stage_layer(out_path, layer)
    return reports


def _simulate_all(stage, source, shots, options, total_mass, progress, seed, keep_failed, record):
    """Simulate each shot; (reports, the override layer with per-frame terms and inspection prims)."""
    from usdgaze import __version__
    from usdgaze.usd.attendio import add_inspection
    from usdgaze.usd.layers import build_override, layer_info

    reports, overrides, terms, inspections = [], [], {}, []
    for shot in shots:
        report, override, shot_terms, inspection = _simulate_shot(
            lambda opts: _attempt(shot, opts, total_mass, progress, seed), shot.options)  # noqa: B023 (called here)
        if inspection is not None:
            inspections.append(inspection)
        reports.append(report)
        overrides.append(override if shot.take is None else through_take(override, shot.take, shot.clip))
        # wall_s stays out of the layer: the same inputs and seed must give the same bytes.
        kept = {k: v for k, v in asdict(report).items() if v is not None and k not in ("problems", "wall_s",
                                                                                         "other_attempt", "unmendable", "reference_notes")}
        terms[report.skeleton] = {"report": kept, "problems": report.problems or ["none"], "frames": shot_terms}
        if report.other_attempt:
            terms[report.skeleton]["otherAttempt"] = report.other_attempt
        if report.reference_notes:
            terms[report.skeleton]["referenceNotes"] = report.reference_notes
    failed = [r for r in reports if r.problems]
    if failed and not keep_failed:
        raise UsdGazeError(f"{source}:{failed[0].skeleton}: {failed[0].problems[0]}; nothing written")
    info = layer_info(stage)
    info.custom = {"usdgaze:physics": terms,
                   "usdgaze": {"version": __version__, "input": os.path.basename(source),
                               "command": "attend --physics", "seed": seed, "massKg": float(total_mass),
                               "characters": sorted({str(shot.root.GetPath()) for shot in shots}),
                               "planner": _planner_record(options),
                               **(record or {})}}
    layer = build_override(overrides, info)
    for character, times, sight, eye_pose, paths, estimates, uncertainty in inspections:
        add_inspection(layer, character, times, sight, eye_pose, paths, estimates, uncertainty)
    return reports, layer
