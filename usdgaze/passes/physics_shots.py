"""The shots of ``attend --physics``: each skeleton read, bound, cut to the stage's playback range and
given its body model and planner options (by task) before any is simulated; and ``physics-model``,
which writes the MJCF of that same body at that same step."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, NamedTuple

from usdgaze.errors import UsdGazeError
from usdgaze.passes.physics_options import shot_options
from usdgaze.passes.take import cut_to_range
from usdgaze.physics import mpc
from usdgaze.usd.objects import PHYSICS_TASK as TASK

TASKS = ("stone", "obstacle")


class Shot(NamedTuple):
    """One skeleton to simulate, read and checked before any is simulated (:func:`read_shots`)."""

    root: Any  # the Usd.Prim of its SkelRoot
    clip: Any  # the usdgaze.core.clip.Clip, cut to the stage's playback range
    scene: tuple  # the coupled loop's (object prims, their paths, the balls to catch)
    chain_frame: tuple  # the gaze binding: (Chain, CharacterFrame)
    ahead: Any  # the take's clip after the shot (None: none)
    take: Any  # the whole take the clip was cut from (None: the clip is the take)
    body: tuple  # its body model and the reference on it (build.body_model), built once for every attempt
    tasks: dict[str, list]  # the stage's stone and obstacle prims (task_prims)
    options: mpc.Options  # its options: a shot with stones has their window


def task_prims(stage, source: str, skel_root: str) -> dict[str, list]:
    """The stage's stone and obstacle prims (``usdgaze:physics:task``), checked: one plain value each,
    a transformable prim, none under the SkelRoot ``skel_root``."""
    from usdgaze.usd.objects import check_apart, require_xformable, scene_prims

    prims = {kind: [] for kind in TASKS}
    root = stage.GetPrimAtPath(skel_root)
    for prim in scene_prims(stage):
        _check_spelling(prim, source)
        _check_no_root_property(prim, root, source)
        attr = prim.GetAttribute(TASK)
        if not attr or not attr.HasAuthoredValue():
            continue
        kind = attr.Get()
        if kind is None or attr.GetNumTimeSamples():
            raise UsdGazeError(f"{source}:{prim.GetPath()}.{TASK}: is time-sampled or has no value; a task is "
                               "one plain value, 'stone' or 'obstacle'")
        if str(kind) not in TASKS:
            raise UsdGazeError(f"{source}:{prim.GetPath()}.{TASK}: '{kind}' is not one of 'stone', 'obstacle'")
        require_xformable(prim, source, f"a{'n' if kind == 'obstacle' else ''} {kind}")
        prims[str(kind)].append(prim)
    check_apart([p for found in prims.values() for p in found], [stage.GetPrimAtPath(skel_root)], source,
                "a stone or an obstacle", inside=True)
    return prims



def _check_no_root_property(prim, root, source: str) -> None:
    """One line for a push or a catch authored on a prim that is no SkelRoot, away from the character:
    on a prop or the world's Xform it acted on nothing, exit 0. (Under the character's SkelRoot or
    above it, ``pushes.read_pushes`` says where to author it instead.)"""
    from pxr import UsdSkel

    from usdgaze.passes.pushes import root_property

    path, here = root.GetPath(), prim.GetPath()
    if prim.IsA(UsdSkel.Root) or here.HasPrefix(path) or path.HasPrefix(here):
        return
    found = root_property(prim)
    if found is not None:
        prop, what = found
        raise UsdGazeError(f"{source}:{prop.GetPath()}: {what} is read on a character's SkelRoot only, and "
                           f"{here} is none; author it on {path}")


def _check_spelling(prim, source: str) -> None:
    """One line for a ``usdgaze:physics:`` property the pass reads nowhere: a stone tagged
    ``usdgaze:physics:tasks`` (or ``Task``) was no stone, and the shot ran without it, exit 0."""
    from usdgaze.passes.pushes import ROOT_NAMES, check_read

    known = (TASK, *ROOT_NAMES)
    check_read(prim.GetAuthoredPropertiesInNamespace("usdgaze:physics"), known, source, f"it reads {', '.join(known)}")


def read_shot(stage, source: str, root, roots: list, skel, options: mpc.Options, bind: Callable,
              total_mass: float = 75.0) -> Shot:
    """One skeleton's :class:`Shot`: ``bind(clip, root)`` gives its gaze binding (Chain, CharacterFrame)."""
    from usdgaze.passes import visuomotor
    from usdgaze.physics.build import body_model
    from usdgaze.usd.skelio import read_clip

    tasks = task_prims(stage, source, str(root.GetPath()))
    scene = visuomotor.read_scene(root, source, roots)
    opts = shot_options(options, tasks, bool(scene[2]))
    ahead_s = opts.horizon_s + 2 * opts.h  # the planner's last window, past the shot
    clip, ahead, take = cut_to_range(read_clip(stage, skel, root, source), stage, ahead_s)
    chain_frame = bind(clip, root)
    # A ball to catch simulates every joint: a joint the reference holds still may be needed to reach.
    body = body_model(clip, total_mass, weld_still=not scene[2], chain_frame=chain_frame)
    return Shot(root, clip, scene, chain_frame, ahead, take, body, tasks, opts)


def read_shots(stage, source: str, skel_root: str | None, options: mpc.Options, binding,
               total_mass: float = 75.0, notes: list | None = None) -> list[Shot]:
    """Every character skeleton's :class:`Shot`: all read, checked, bound and built before any work (a
    skeleton the model refuses, lying, without feet, squashed, was found only after the characters
    before it had been simulated); ``notes`` gets a line for each skeleton left as no character."""
    from usdgaze.characters import bind_root, bound_skeletons, select_roots
    from usdgaze.usd.skelio import animations_elsewhere, check_not_shared, skeletons_under

    shots = []
    roots = select_roots(stage, source, skel_root)
    others = animations_elsewhere(stage, roots)
    for root in roots:
        bound, headless = bound_skeletons(root, skeletons_under(root), source, lambda skel: read_shot(
            stage, source, root, roots, skel, options, lambda clip, r: bind_root(clip, r, binding), total_mass))
        if notes is not None:  # a face's or a prop's skeleton beside the body's: no character, not simulated
            notes.extend(headless)
        for _, shot in bound:
            check_not_shared(others, shot.clip.animation, source)
            _check_tasks(shot, source)
            shots.append(shot)
    if not shots:
        raise UsdGazeError(f"{source}: no Skeleton to simulate")
    return shots


def _check_tasks(shot: Shot, source: str) -> None:
    """What the simulation of ``shot`` would refuse, said before any shot is simulated: a second
    character's bad push, or its reference off the ground, stopped the command only after the first
    had been simulated (minutes), and the coupled loop (objects in the stage) never checked the ground."""
    from usdgaze.passes import visuomotor
    from usdgaze.passes.pushes import read_pushes
    from usdgaze.physics import retarget
    from usdgaze.physics.build import check_on_ground
    from usdgaze.physics.catch import can_catch

    root, (model, ref) = shot.root, shot.body
    if shot.scene[2] and not can_catch(model):  # it stopped with an internal error, exit 1
        raise UsdGazeError(f"{source}:{root.GetPath()}.{visuomotor.CATCH}: names a ball to catch, but "
                           f"{shot.clip.skeleton} has no hand (a hand joint below a forearm) to catch it with")
    read_pushes(root, shot.clip, model, f"{source}:{root.GetPath()}")
    check_on_ground(model, retarget.to_qpos(model, ref), shot.clip)


def write_model(input_path, out, total_mass: float = 75.0, timestep: float | None = None,
                skel_root: str | None = None) -> dict:
    """Write the MJCF of the body ``attend --physics`` simulates for ``input_path``'s one character (or the
    one under ``skel_root``; its first Skeleton that binds), at its step (``timestep`` None: the step by
    task, as the pass takes it); a summary for the console."""
    from functools import partial

    from usdgaze.api import _open_input
    from usdgaze.characters import first_character
    from usdgaze.files.kinds import require_file
    from usdgaze.files.transaction import Outputs
    from usdgaze.physics import mjcf
    from usdgaze.physics.build import binding, one_skeleton
    from usdgaze.usd.skelio import skeletons_under

    out = Path(out)
    if out.suffix.lower() != ".xml":
        raise UsdGazeError(f"{out}: the model is MJCF; --out must end in .xml")
    if timestep is not None and not 0.001 <= timestep <= 0.05:
        raise UsdGazeError(f"--timestep {timestep}: expected 0.001 to 0.05 s")
    source = str(input_path)
    require_file(source)
    with Outputs() as tx:
        tx.read(source)
        tx.claim(out, "--out")
        stage = _open_input(tx, source)
        root, _ = one_skeleton(stage, source, skel_root)
        skels = skeletons_under(root)
        # The SkelRoot's first character: a face's or a prop's skeleton listed before the body's is none
        # (alone, a skeleton without a gaze chain is built by its shape, as before).
        bind = binding if len(skels) == 1 else partial(binding, headless=False)
        _, shot, _ = first_character(root, skels, source, lambda skel: read_shot(
            stage, source, root, [root], skel, mpc.Options(), bind, total_mass))
        model, h = shot.body[0], timestep or shot.options.h
        tx.stage_text(out, mjcf.write(model, timestep=h))
    return {"bodies": len(model.bodies), "joints": {k: model.kind.count(k) for k in ("free", "ball", "hinge", "weld")},
            "mass": model.total_mass, "skeleton": shot.clip.skeleton, "timestep": h}
