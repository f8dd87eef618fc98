"""The coupled physics pass: body, eyes and belief simulated together (``usdgaze.physics.visuomotor``)
for a clip whose stage has objects to look at, written as the physics pass's body plus the attend
pass's eyes and inspection prims (point of sight, eye pose, per-object estimate and uncertainty).

Read at this edge, then plain arrays: the stage's ``GazeObjectAPI`` prims (as ``usdgaze attend``), in
the model's world; and the balls to catch, named by the SkelRoot's relationship
``usdgaze:physics:catch`` (each target must be one of those objects):

```
over "Body" {
    rel usdgaze:physics:catch = </Objects/Ball>
}
```

A shot with a ball to catch simulates every joint the model has (``weld_still=False``: the standing
reference holds the arms still, the catch must not). Frames after a fall's last simulated one hold it.
"""

from __future__ import annotations

import time

import numpy as np

from usdgaze.passes.catches import CATCH, catch_targets, require_objects  # noqa: F401  (CATCH: the pass's name)
from usdgaze.physics import mpc
from usdgaze.vision import loop

CATCH_TOLERANCE_M = 0.1  # a ball the hand came no nearer than this to is a problem of the shot


def read_scene(root, source: str, roots: list | None = None):
    """(object prims, their paths, catch indices) of the stage for the character ``root``, or ([], [], [])
    where it has none. ``roots``: every character the pass simulates (default: ``root``); each looks at
    the objects but one that is it or holds it, so two characters may look at each other (as ``attend``
    without ``--physics``: ``objects.objects_of``)."""
    from usdgaze.usd.objects import API_NAME, object_prims, objects_of, scene_prims
    from usdgaze.usd.plugin import has_api

    stage = root.GetStage()
    targets = catch_targets(root, source)
    if not any(has_api(p, API_NAME) for p in scene_prims(stage)):
        require_objects(root, source, targets, [], API_NAME)  # a ball on a stage of no objects: one line
        return [], [], []
    roots = list(roots or [root])
    prims = objects_of(object_prims(stage, source, None), roots, source)[roots.index(root)]
    paths = [str(p.GetPath()) for p in prims]
    return prims, paths, require_objects(root, source, targets, paths, API_NAME)


def _things(root, clip, source, prims, model, steps: int, h: float) -> list[loop.Thing]:
    from usdgaze.usd.objects import read_objects

    # The simulation's steps run from the clip's first frame; a clip at 1001 in a stage starting at 1
    # saw its objects 41.7 s early (held at their first samples) when counted from the stage's start.
    codes = clip.start_time + (clip.seconds[0] + h * np.arange(steps)) * clip.time_codes_per_second
    objs = read_objects(root.GetStage(), source, prims, codes, clip.meters_per_unit)
    rot = model.to_model / np.linalg.norm(model.to_model[:, 0])  # stage axes -> model axes (metres kept)
    return [loop.Thing(o.path, o.positions @ rot.T, o.importance, o.view_radius, o.kind, visible=o.visible)
            for o in objs]


def simulate_clip(clip, root, options: mpc.Options, prims, paths, catches, total_mass: float = 75.0,
                  progress=None, seed: int = 0, chain_frame=None, ahead=None, *, task_found: dict[str, list],
                  body=None):
    """Simulate one clip with its eyes; (ShotReport, AnimOverride, per-frame terms, inspection).

    ``chain_frame``: the clip's (Chain, CharacterFrame) from :func:`usdgaze.characters.bind_root`
    (default: bound by names and the SkelRoot's map); ``ahead``: the take's clip after the shot;
    ``task_found``: the stage's stone and obstacle prims (``physics.task_prims``'s); ``body``: its
    ``build.body_model`` (catches weld no still joints), built here if None."""
    from usdgaze.characters import bind_root
    from usdgaze.passes import physics as body_pass
    from usdgaze.physics import build, retarget, visuomotor
    from usdgaze.physics.catch import CatchTask

    source = clip.source
    chain_frame = chain_frame or bind_root(clip, root)
    model, ref = body or build.body_model(clip, total_mass, weld_still=not catches, chain_frame=chain_frame)
    pushes = body_pass.read_pushes(root, clip, model, f"{source}:{root.GetPath()}")
    ref_qpos = retarget.to_qpos(model, ref)
    h = options.h
    steps = int(np.ceil((clip.seconds[-1] - clip.seconds[0]) / h - 1e-6)) + 1
    things = _things(root, clip, source, prims, model, steps, h)
    tasks = [(lambda j: lambda plan, ref_q: CatchTask(plan, j, seed + j, truth=things[j].positions,
                                                                reference=ref_q))(j) for j in catches]
    tasks += body_pass.read_tasks(root.GetStage(), clip, model, source, ref_qpos, paths, task_found=task_found)
    opts = visuomotor.Options(options)
    opts.vision.seed = seed
    start = time.perf_counter()
    res = visuomotor.simulate(model, ref_qpos, clip.seconds, things, opts, pushes, tasks, progress,
                              ahead=body_pass.take_after(model, ahead))
    wall = time.perf_counter() - start
    result = res.body
    qadr, _ = model.layout()
    quats = [3] + [int(qadr[b]) for b, k in enumerate(model.kind) if k == "ball"]
    qpos, n = body_pass._frames_from_steps(result, clip.seconds, quats)
    qpos = np.concatenate([qpos, np.repeat(qpos[-1:], len(clip.seconds) - n, 0)])  # a fall: hold the last
    override, sight, eye_deg, est, uncertainty = _written(clip, chain_frame, model, ref, res, qpos)
    report, terms = body_pass.shot_summary(clip, result, n, len(pushes), wall)  # stones, obstacles said there
    _catch_problems(report, result.task_terms, [paths[j] for j in catches])  # the catch tasks come first
    inspection = (clip.skel_root, clip.times, sight, eye_deg, paths, est, uncertainty)
    return report, override, terms, inspection


def _written(clip, chain_frame, model, ref, res, qpos: np.ndarray):
    """The simulated body at the clip's frames (``qpos``) with its eyes aimed as simulated: the override,
    and per frame the point of sight, the eye pose (degrees, degrees, metres), the belief's estimates
    in stage units and their uncertainty."""
    from usdgaze.passes.assemble import assemble
    from usdgaze.passes.attend import AttendResult, eyes_on
    from usdgaze.passes.chain import with_eyes
    from usdgaze.passes.options import PassOptions
    from usdgaze.physics import retarget
    from usdgaze.usd.layers import AnimOverride

    result = res.body
    rotations, translations = retarget.from_qpos(model, qpos, ref)
    chain, frame = chain_frame
    rig = with_eyes(clip, chain, frame, PassOptions())
    t_rel = clip.seconds - clip.seconds[0]
    t_sim = result.seconds - result.seconds[0]
    eye = _at(t_rel, t_sim, res.vision.eye)
    new_local = lambda j: (translations[:, j], rotations[:, j], ref.scales[:, j])  # noqa: E731
    # The model of a mirrored character is its right-handed mirror image (physics.model), where the
    # eyes' yaw is toward the skeleton's left; eyes_on takes it toward the stage world's left.
    sense = np.broadcast_to(clip.handedness, (len(eye),))
    eye_rot, sight = eyes_on(clip, chain, frame, rig, new_local, eye * np.column_stack([sense, np.ones((len(eye), 2))]))
    new_rot = {j: rotations[:, j] for j in range(len(clip.joints))}
    new_rot.update(eye_rot)
    new_trans = {j: translations[:, j] for j in range(len(clip.joints))}
    anim_joints, rot_a, trans_a, scales_a = assemble(rig, new_rot, new_trans)
    back = np.linalg.inv(model.to_model)  # model -> stage units
    est = np.einsum("ij,foj->foi", back, _at(t_rel, t_sim, res.vision.estimate))
    eye_deg = eye * [180 / np.pi, 180 / np.pi, 1.0]
    written = AttendResult(anim_joints, rot_a, trans_a, scales_a, rig.added, None, None, [], sight, est,
                           _at(t_rel, t_sim, res.vision.sigma_p), eye_deg)
    if rig.added:
        written.added_rest_local = rig.rest_local[-2:]
        written.added_bind_world = clip.bind_world[chain.head] @ rig.rest_local[-2:]
    return AnimOverride.of(clip, written, move_roots=True), sight, eye_deg, est, written.uncertainty


def _catch_problems(report, task_terms: dict, balls: list[str]) -> None:
    """A ball the hand came no nearer than 10 cm to is a problem of the shot. One whose catch never
    reached its proactive phase (no arrival within reach was ever expected in time: thrown from
    behind, or out of reach) is one that another simulation cannot mend, so it is not simulated again."""
    from usdgaze.physics.catch import CatchOptions
    from usdgaze.physics.tasks import task_prefix

    for i, path in enumerate(balls):
        prefix = task_prefix(["catch"] * len(balls), i)
        miss = task_terms.get(f"{prefix}.handToBallM")
        if miss is None or not np.all(np.isnan(miss) | (miss > CATCH_TOLERANCE_M)):
            continue
        near = np.nanmin(miss) if np.any(~np.isnan(miss)) else np.nan
        said = f"catch {path}: the hand came no nearer than {100 * near:.0f} cm to the ball"
        weight = np.nan_to_num(task_terms.get(f"{prefix}.weight", np.zeros(1)))
        if weight.max() < CatchOptions().w_proactive:
            said += " (never reached for: no arrival within reach was expected in time)"
            report.unmendable.append(said)
        report.problems.append(said)


def _at(t_new: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per-step values at frame times (linear; NaN where either neighbour is NaN; held past the end)."""
    flat = v.reshape(len(t), -1)
    i = np.clip(np.searchsorted(t, t_new, side="right") - 1, 0, max(len(t) - 2, 0))
    if len(t) < 2:
        return np.repeat(v[:1], len(t_new), 0)
    a = np.clip((t_new - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)[:, None]
    out = (1 - a) * flat[i] + a * flat[i + 1]
    return out.reshape((len(t_new),) + v.shape[1:])
