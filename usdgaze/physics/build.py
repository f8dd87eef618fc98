"""Stage -> body model: read a skeleton, build its :class:`BodyModel` and MJCF (USD at this edge only)."""

from __future__ import annotations

import os

import numpy as np

from usdgaze.errors import NoHeadError, RigError, UsdGazeError


def load_clip(input_path: str | os.PathLike, skel_root: str | None = None):
    """The clip of ``input_path``'s one skeleton (:func:`one_skeleton`)."""
    from usdgaze.usd.skelio import read_clip
    from usdgaze.usd.stage import open_stage

    source = str(input_path)
    stage = open_stage(source)
    root, skel = one_skeleton(stage, source, skel_root)
    return read_clip(stage, skel, root, source)


def one_skeleton(stage, source: str, skel_root: str | None):
    """(SkelRoot, Skeleton): the stage's one SkelRoot (or ``skel_root``) and its first Skeleton; one line
    where there are several SkelRoots and none is named, or the SkelRoot has no Skeleton."""
    from usdgaze.characters import select_roots
    from usdgaze.usd.skelio import skeletons_under

    roots = select_roots(stage, source, skel_root)
    if len(roots) > 1:
        raise UsdGazeError(f"{source}: {len(roots)} SkelRoots; pick one with --skel-root")
    skels = skeletons_under(roots[0])
    if not skels:
        raise UsdGazeError(f"{source}:{roots[0].GetPath()}: no Skeleton under the SkelRoot")
    return roots[0], skels[0]


MIN_MASS_KG, MAX_MASS_KG = 1.0, 500.0


def body_model(clip, total_mass: float = 75.0, weld_still: bool = True, chain_frame=None):
    """The body model of a clip's skeleton, hinge axes and ranges fitted to its animation (``weld_still``:
    see :func:`usdgaze.physics.model.build`); ``chain_frame``, the gaze binding's (Chain, CharacterFrame),
    tells the head, eyes and forward where the joint names do not."""
    from usdgaze.physics.model import Hints, build
    from usdgaze.physics.retarget import Reference

    if not MIN_MASS_KG <= total_mass <= MAX_MASS_KG:  # NaN included
        raise UsdGazeError(f"--mass {total_mass:g}: expected {MIN_MASS_KG:g} to {MAX_MASS_KG:g} kg")
    hints = None
    if chain_frame is not None:
        chain, frame = chain_frame
        hints = Hints(head=chain.head, eyes=tuple(chain.eyes or ()), forward=frame.forward)
    ref = Reference.from_clip(clip)
    if len(ref.rotations) and np.array_equal(ref.rotations, np.broadcast_to(ref.rotations[:1], ref.rotations.shape)):
        # One held pose (a still character, or the rest pose) tells nothing about which joints are
        # rigid: welding those at rest would leave nothing to balance with.
        weld_still = False
    model = build(clip.joints, clip.parents, clip.rest_local, clip.skel_to_world, clip.up_axis,
                  clip.meters_per_unit, total_mass=total_mass, reference=ref.rotations, where=clip.where(),
                  weld_still=weld_still, hints=hints)
    return model, ref


def binding(clip, root, headless: bool = True):
    """The gaze binding ``attend --physics`` builds its body with (the SkelRoot's GazeMapAPI, else names),
    so that both build one model: without it, the head, eyes and forward a GazeMapAPI binds on a rig whose
    names say nothing were not read here (its eyes were 1.7 kg bodies of the head). None where no chain
    is found (the skeleton's shape tells, as before); with ``headless`` False a skeleton with no head at
    all raises NoHeadError (no character: a face's beside the body's)."""
    from usdgaze.characters import bind_root

    try:
        return bind_root(clip, root)
    except NoHeadError:
        if not headless:
            raise
        return None
    except RigError:
        return None


def check_on_ground(model, ref_qpos: np.ndarray, clip) -> None:
    """One line, before minutes of simulation, for a reference no simulated ground can carry
    (:func:`usdgaze.physics.feasible.never_on_ground`)."""
    import mujoco

    from usdgaze.physics import feasible, mjcf

    mj = mujoco.MjModel.from_xml_string(mjcf.write(model))
    why = feasible.never_on_ground(mj, model, ref_qpos, clip.seconds)
    if why:
        raise UsdGazeError(f"{clip.where()}: {why}")
