"""Whether an override layer was made from the version of the input it is composed over.

``apply`` and ``attend`` write every joint's arrays of an animation they override, and change only
the joints their gaze chain drives (pelvis to head, the eyes, the leg roots); every other joint's
values are the input's, bit for bit. A layer made from another take, or from the input before it
was edited, holds other values there, and composed over this input it plays them (the old leg, a
"gaze" of 100 deg for a 30 deg request) while ``validate``, ``plot`` and ``preview`` called it clean.
``attend --physics`` moves every joint: its layers are not checked.

Read at the Sdf level, at a handful of time codes: a check on every frame would cost what reading
the whole animation does.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdSkel

FRAMES_CHECKED = 12
"""Time codes compared per array, spread evenly over those the layer and the input both author."""

_ARRAYS = ("rotations", "translations", "scales")


def moves_every_joint(record: dict) -> bool:
    """Whether the layer's pass changes every joint (``attend --physics``), so no joint is the input's."""
    return str(record.get("command", "")).startswith("attend --physics")


def stale_joint(layer, anim: UsdSkel.Animation, driven: set[str]) -> tuple[str, str, float] | None:
    """(array, joint, stage time code) of the first joint ``layer`` writes for ``anim`` but does not
    drive (``driven``: joint tokens) whose value is not the input's below it, or None."""
    joints = _joints(layer, anim)
    if joints is None:
        return None
    ours, theirs = joints
    for name in _ARRAYS:
        specs = _specs(layer, anim.GetPrim().GetAttribute(name))
        if specs is None:
            continue
        column = {j: k for k, j in enumerate(theirs)}
        pairs = [(i, column[j]) for i, j in enumerate(ours) if j in column and j not in driven]
        if not pairs:
            continue
        found = _first_difference(specs, np.array(pairs, dtype=int))
        if found is not None:
            return name, ours[found[0]], found[1]
    return None


def _joints(layer, anim: UsdSkel.Animation) -> tuple[list[str], list[str]] | None:
    """The animation's joints as ``layer`` lists them (its own, where it grew them) and as the layers
    below it do; None where nothing below authors them (an animation the layer defined)."""
    attr = anim.GetJointsAttr()
    specs = [s for s in (attr.GetPropertyStack(Usd.TimeCode.Default()) if attr else []) if s.HasDefaultValue()]
    below = [s for s in specs if s.layer != layer]
    if not below:
        return None
    theirs = [str(j) for j in below[0].default]
    own = next((s for s in specs if s.layer == layer), None)
    return ([str(j) for j in own.default] if own is not None else theirs), theirs


def _specs(layer, attr: Usd.Attribute):
    """((layer's spec, offset), (the input's spec below it, offset)): the layer's time samples and the
    opinion they override (samples, or a default); None where the layer samples no such array."""
    if not attr:
        return None
    stack = attr.GetPropertyStackWithLayerOffsets(Usd.TimeCode.Default())
    at = next((k for k, (s, _) in enumerate(stack) if s.layer == layer and layer.GetNumTimeSamplesForPath(s.path)), None)
    if at is None:
        return None
    below = next(((s, o) for s, o in stack[at + 1:]
                  if s.HasDefaultValue() or s.layer.GetNumTimeSamplesForPath(s.path)), None)
    return None if below is None else (stack[at], below)


def _first_difference(specs, pairs: np.ndarray) -> tuple[int, float] | None:
    """(the layer's joint index, stage time code) of the first pair of columns whose bits differ, at
    up to :data:`FRAMES_CHECKED` time codes both sides author; None where all agree."""
    (ours, ours_offset), (theirs, theirs_offset) = specs
    own = {float(ours_offset * t): t for t in ours.layer.ListTimeSamplesForPath(ours.path)}
    sampled = theirs.layer.GetNumTimeSamplesForPath(theirs.path) > 0
    other = ({float(theirs_offset * t): t for t in theirs.layer.ListTimeSamplesForPath(theirs.path)}
             if sampled else dict.fromkeys(own))
    common = sorted(set(own) & set(other))
    picked = np.unique(np.linspace(0, len(common) - 1, FRAMES_CHECKED).round().astype(int)) if common else []
    need = pairs.max(axis=0)  # the highest column each side must hold
    for code in (common[i] for i in picked):
        a = np.asarray(ours.layer.QueryTimeSample(ours.path, own[code]))
        b = np.asarray(theirs.layer.QueryTimeSample(theirs.path, other[code]) if sampled else theirs.default)
        if a.ndim != 2 or b.ndim != 2 or a.dtype != b.dtype or need[0] >= len(a) or need[1] >= len(b):
            continue  # a malformed sample: AnimationArrays says so
        bits = f"u{a.itemsize}"  # bits, not values: NaN and -0.0 compare as they are
        differ = np.flatnonzero((a[pairs[:, 0]].view(bits) != b[pairs[:, 1]].view(bits)).any(axis=1))
        if len(differ):
            return int(pairs[differ[0], 0]), code
    return None


def driven_joints(skel: UsdSkel.Skeleton, root, record: dict, source: str, layer_name: str) -> set[str] | None:
    """The joint tokens the pass drove on ``skel``: its gaze chain bound as ``plot`` binds it (the
    SkelRoot's map, the --bind and --forward the layer records, names), with the eyes and the leg
    roots; None where no chain binds (the review says why; nothing to compare against)."""
    from usdgaze.characters import chain_of, own_map
    from usdgaze.core.hints import from_record
    from usdgaze.errors import UsdGazeError
    from usdgaze.usd.skelio import joint_parents

    joints = [str(j) for j in (skel.GetJointsAttr().Get() or [])]
    names = skel.GetJointNamesAttr()
    where = f"{source}:{skel.GetPath()}"
    try:
        chain = chain_of(joints, joint_parents(joints, where), list(names.Get()) if names and names.HasAuthoredValue() else None,
                         own_map(root, source), from_record(record, layer_name), where)
    except UsdGazeError:
        return None
    return driven_by(chain, joints)


def driven_by(chain, joints: list[str]) -> set[str]:
    """The joint tokens a pass changes for a bound ``chain``: pelvis to head, every role's joints
    (the eyes), and the leg roots (which counter-rotate the pelvis)."""
    roles = [j for js in chain.roles.values() for j in js]
    return {joints[i] for i in (*chain.path, *chain.leg_roots, *roles)}


def other_version(layer_name: str, animation, found: tuple[str, str, float]) -> str:
    """What validate (an error) and plot and preview (a warning) say of a :func:`stale_joint`."""
    from usdgaze.core.names import leaf

    array, joint, code = found
    return (f"{layer_name}: the layer was made from another version of the input: joint '{leaf(joint)}' of "
            f"{animation} differs at time code {code:g} ({array}; the layer's gaze does not drive it); "
            "run the pass again over this input")


def review_warnings(stage, layer, layer_name: str, record: dict, characters) -> list[str]:
    """:func:`other_version` for each reviewed character (``CharacterReview``s, their chains bound)."""
    from usdgaze.usd.skelio import animation_of

    if moves_every_joint(record):
        return []
    out = []
    for c in characters:
        anim = animation_of(stage.GetPrimAtPath(c.skeleton))
        found = stale_joint(layer, UsdSkel.Animation(anim), driven_by(c.chain, c.joints)) if anim else None
        if found is not None:
            out.append(other_version(layer_name, anim.GetPath(), found))
    return out
