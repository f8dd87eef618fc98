"""The gaze pass: layer a schedule of gaze shifts onto a skeletal animation (Heck 5.2.3, extended).

Pure numpy. Input: a :class:`~usdgaze.core.clip.SkelClip`, its bound :class:`~usdgaze.core.rig.Chain`, the
character frame, a :class:`~usdgaze.gaze.gazemap.ParametricGazeMap` and the shifts. Output: new
animation arrays in which only the chain joints, the leg roots under the pelvis and the eyes differ.

How a request is met:

* A request (yaw, pitch) is a change of the line of sight against the base motion's line of sight at
  the same frame (the base's eyes look where its head looks): yaw changes the azimuth about the
  stage up axis (positive toward the character's left), pitch the elevation.
* Shift k blends every segment from the state the previous shift left it in to the map's answer for
  the request (identity for (0, 0)), with the map's timing for the *change* (cascade, overshoot,
  settle). P+ offsets are parent-relative rotations in the character frame; on the rig each one is
  applied in its joint's parent frame as that frame sits in the neutral (bind) pose, spread evenly over the joints
  sharing a role (neck and head share the neck segment). The pelvis turns in its heading frame.
* The leg roots under the pelvis counter-rotate so the legs keep their base world pose.
* The eyes converge on a point of sight at ``fixation_m`` along the wanted line of sight. The wanted
  line of sight follows the map's gaze progress on the canonical chain (so it leads, overshoots and
  settles like the model) and equals the request exactly once the shift settles: the eyes absorb
  the model's residual on this rig and the base motion's bobbing, within the eye range.

The steps live in their own modules: :mod:`~usdgaze.passes.schedule` (shifts -> per-frame offsets),
:mod:`~usdgaze.passes.chain` (rig, chain, legs), :mod:`~usdgaze.passes.aim` (eyes, reach),
:mod:`~usdgaze.passes.assemble` (measure, arrays); the types in :mod:`~usdgaze.passes.options`.
"""

from __future__ import annotations

import numpy as np

from usdgaze.core.clip import SkelClip
from usdgaze.core.rig import CharacterFrame, Chain
from usdgaze.errors import UsdGazeError
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.aim import reach_warnings
from usdgaze.passes.assemble import finish
from usdgaze.passes.chain import move_body, prepare
from usdgaze.passes.schedule import schedule
from usdgaze.passes.sight import direction_from, directions_to_world
from usdgaze.passes.options import EyeRange, PassOptions, PassResult, Shift

__all__ = ["EyeRange", "PassOptions", "PassResult", "Shift", "apply_gaze"]

def apply_gaze(clip: SkelClip, chain: Chain, frame: CharacterFrame, gaze_map: ParametricGazeMap,
               shifts: list[Shift], options: PassOptions = PassOptions()) -> PassResult:
    """Run the gaze pass on one clip; see the module docstring."""
    shifts = sorted(shifts, key=lambda s: s.time_s)
    for a, b in zip(shifts, shifts[1:]):
        if a.time_s == b.time_s:
            raise UsdGazeError(f"{clip.where()}: two shifts at the same time {a.time_s:g} s")
    seconds = clip.seconds
    base = prepare(clip, chain, frame, options)
    rig, skel_to_world, up_w, base_ae = base.rig, base.skel_to_world, base.up, base.ae

    plan = schedule(gaze_map, shifts, seconds)
    body = move_body(base, chain, frame, plan.displacement)

    # The wanted line of sight and, at the fixation distance along it, the point of sight.
    wanted_ae = base_ae + plan.requested
    wanted_ae[:, 1] = np.clip(wanted_ae[:, 1], -89.0, 89.0)
    wanted_s = directions_to_world(np.linalg.inv(skel_to_world), direction_from(wanted_ae, up_w))
    centre = body.eye_centre(rig)
    world_scale = np.cbrt(np.abs(np.linalg.det(skel_to_world)))
    distance = np.broadcast_to(options.fixation_m / clip.meters_per_unit / world_scale, (len(seconds),))
    result = finish(clip, chain, frame, base, body, plan, centre + distance[:, None] * wanted_s, options,
                    requested=plan.requested)
    result.warnings = reach_warnings(clip, shifts, plan, base_ae, result.achieved, result.eye_angles, options)
    return result
