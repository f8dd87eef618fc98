"""Pushes authored on a SkelRoot for the physics pass: ``usdgaze:physics:pushForce`` (a float3 in
newtons along the stage's axes, time-sampled: each sample's force holds until the next) on the body
of ``usdgaze:physics:pushJoint``. Checked here, at the USD edge, so the simulation gets only finite
forces it can take, and a push authored under the SkelRoot (on its Skeleton, say) is refused, not
left to act on nothing."""

from __future__ import annotations

import numpy as np
from pxr import Usd

from usdgaze.errors import UsdGazeError
from usdgaze.passes.catches import CATCH
from usdgaze.physics import mpc
from usdgaze.usd.checks import authored_type

PUSH_FORCE = "usdgaze:physics:pushForce"
PUSH_JOINT = "usdgaze:physics:pushJoint"
MOST_NEWTONS = 1e5  # about 140 times a 75 kg body's weight: more only blows the simulation up
_VECTORS = ("float3", "double3", "half3", "vector3f", "vector3d", "vector3h")


def _forces(force, where: str) -> tuple[list[float], list[np.ndarray]]:
    """The authored samples (or the default) as finite 3-vectors; one line for anything else."""
    spelled = authored_type(force)
    if spelled not in _VECTORS:
        raise UsdGazeError(f"{where}.{PUSH_FORCE}: is a {spelled}, expected a float3 (newtons along the stage's axes)")
    times = list(force.GetTimeSamples())
    values = [force.Get(t) for t in times] if times else [force.Get()]
    out = []
    for t, v in zip(times or [None], values):
        at = "" if t is None else f" at time {t:g}"
        if v is None:
            raise UsdGazeError(f"{where}.{PUSH_FORCE}: has no value{at} (blocked)")
        f = np.array(v, dtype=float)
        if not np.all(np.isfinite(f)):
            raise UsdGazeError(f"{where}.{PUSH_FORCE}: {tuple(float(x) for x in f)}{at} is not finite")
        if np.linalg.norm(f) > MOST_NEWTONS:
            raise UsdGazeError(f"{where}.{PUSH_FORCE}: {np.linalg.norm(f):g} N{at}; at most {MOST_NEWTONS:g} N")
        out.append(f)
    return times, out


ROOT_NAMES = (PUSH_FORCE, PUSH_JOINT, CATCH)
"""The physics attributes read on a SkelRoot (``usdgaze:physics:task`` is a stone's or an obstacle's)."""


def root_property(prim):
    """The first push or catch ``prim`` authors, read on a SkelRoot only, and what it is ("a push", "a
    ball to catch"); None where it authors neither (a push attribute with no value is none)."""
    for name in (PUSH_FORCE, PUSH_JOINT):
        attr = prim.GetAttribute(name)
        if attr and attr.HasAuthoredValue():
            return attr, "a push"
    catch = prim.GetRelationship(CATCH) or prim.GetAttribute(CATCH)
    if catch and catch.IsAuthored():  # on the Skeleton or the SkelRoot's parent it caught nothing, exit 0
        return catch, "a ball to catch"
    return None


def _check_on_the_root(root, source: str) -> None:
    """One line for a push attribute or a catch authored on a prim under the SkelRoot or above it: only the
    SkelRoot's are read (docs/physics.md), and one on the Skeleton or on the SkelRoot's parent was
    ignored without a word; and for a misspelled physics attribute on the SkelRoot itself (a
    ``pushforce`` left the push out, exit 0)."""
    ancestors = []
    parent = root.GetParent()
    while parent and not parent.IsPseudoRoot():
        ancestors.append(parent)
        parent = parent.GetParent()
    for prim in [*Usd.PrimRange(root, Usd.TraverseInstanceProxies()), *ancestors]:
        found = None if prim == root else root_property(prim)
        if found is None:
            continue
        prop, what = found
        names = f"{PUSH_FORCE} and {PUSH_JOINT}" if what == "a push" else CATCH
        raise UsdGazeError(f"{source}:{prop.GetPath()}: {what} is read on the SkelRoot only; author {names} on "
                           f"{root.GetPath()}")
    # a misspelled catch is a relationship: every property, not only the attributes
    check_read(root.GetAuthoredProperties(), ROOT_NAMES, source, f"a SkelRoot's are {', '.join(ROOT_NAMES)}")


def check_read(props, known: tuple[str, ...], source: str, otherwise: str) -> None:
    """One line for the first ``usdgaze:physics:`` property of ``props`` not in ``known`` (a misspelling:
    the pass reads nowhere what it says): the known name it is closest to, else ``otherwise``."""
    import difflib

    for prop in props:
        name = prop.GetName()
        if name.startswith("usdgaze:physics:") and name not in known:
            near = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
            said = f"did you mean {near[0]}?" if near else otherwise
            raise UsdGazeError(f"{source}:{prop.GetPath()}: not an attribute the physics pass reads ({said})")


def read_pushes(root, clip, model, where: str) -> tuple[mpc.Push, ...]:
    """Pushes authored on the SkelRoot prim that act within the clip, in the model's world."""
    _check_on_the_root(root, clip.source)
    force = root.GetAttribute(PUSH_FORCE)
    joint_attr = root.GetAttribute(PUSH_JOINT)
    if not force or not force.HasAuthoredValue():
        if joint_attr and joint_attr.HasAuthoredValue():
            raise UsdGazeError(f"{where}.{PUSH_JOINT}: names a pushed joint, but {PUSH_FORCE} is not authored on "
                               f"the SkelRoot; author the force (a float3 in newtons, time-sampled)")
        return ()
    name = ""
    if joint_attr and joint_attr.HasAuthoredValue():
        if joint_attr.Get() is None or joint_attr.GetNumTimeSamples():
            raise UsdGazeError(f"{where}.{PUSH_JOINT}: is time-sampled or has no value; name the pushed joint "
                               "as one plain value")
        name = str(joint_attr.Get())
    hits = _joint_named(clip, name)
    if not hits or model.body_of(hits[0]) < 0:
        leaf = clip.joints[hits[0]].rsplit("/", 1)[-1] if hits else ""
        why = (f"it is '{leaf}', which has no body of its own in the model" if hits else
               "name it by its token (a leaf such as 'Spine1' or a path), or by its jointNames name")
        raise UsdGazeError(f"{where}.{PUSH_JOINT}: '{name}' is not a simulated joint of {clip.skeleton}; {why}")
    body = model.body_of(hits[0])
    times, values = _forces(force, where)
    times = times or [clip.start_time]
    rot = model.to_model / np.linalg.norm(model.to_model[:, 0])  # directions only: no unit scale
    pushes = []
    for i, (t, f) in enumerate(zip(times, values)):
        end = times[i + 1] if i + 1 < len(times) else clip.end_time
        if not np.any(f) or end <= clip.times[0] or t >= clip.times[-1]:  # no force, or none in the shot
            continue
        # The simulation's clock starts at the clip's first frame, not the stage's start: an animation
        # starting 100 time codes into the stage had its push 1.7 s late (past a 0.3 s shot: none).
        start_s = (t - clip.times[0]) / clip.time_codes_per_second
        pushes.append(mpc.Push(body, rot @ f, start_s, (end - t) / clip.time_codes_per_second))
    return tuple(pushes)


def _joint_named(clip, name: str) -> list[int]:
    """The joints ``name`` names: a token (path or leaf), or a name of the Skeleton's ``jointNames``
    (``mixamorig:Spine1``, which a token cannot spell), as ``--bind`` reads them."""
    leaves = [j.rsplit("/", 1)[-1] for j in clip.joints]
    hits = [i for i, j in enumerate(clip.joints) if name in (j, leaves[i])]
    named = clip.named_joints()
    if not hits and named is not None:
        hits = [i for i, j in enumerate(named) if name in (j, j.rsplit("/", 1)[-1])]
    return hits
