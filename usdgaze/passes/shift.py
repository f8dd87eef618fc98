"""Gaze shifts: how a schedule of shift requests is layered onto a skeletal animation (Heck 5.2.3,
extended), and the pass's option types.

Shifts run through the one pass, :func:`usdgaze.passes.look.apply_look` (a shift is one of its
directives). Only the chain joints, the leg roots under the pelvis and the eyes differ from the input.

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

The steps live in their own modules: :mod:`~usdgaze.passes.look` (directives -> shifts and eye
epochs), :mod:`~usdgaze.passes.schedule` (shifts -> per-frame offsets), :mod:`~usdgaze.passes.chain`
(rig, chain, legs), :mod:`~usdgaze.passes.aim` (eyes, reach), :mod:`~usdgaze.passes.assemble`
(measure, arrays); the types in :mod:`~usdgaze.passes.options`.
"""

from __future__ import annotations

from usdgaze.passes.options import EyeRange, PassOptions, PassResult, Shift

__all__ = ["EyeRange", "PassOptions", "PassResult", "Shift"]
