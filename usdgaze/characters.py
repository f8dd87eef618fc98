"""The characters of a stage as ``apply`` sees them: SkelRoots, their gaze map (built once per
process), chain and character frame, and the directives each one's clip is given."""

from __future__ import annotations

import dataclasses

import numpy as np

from usdgaze.core.clip import SkelClip
from usdgaze.core.hints import BindHints
from usdgaze.core.character_frame import body_up
from usdgaze.core.kinematics import UP_SNAP_DEG, snap_up
from usdgaze.core.names import names_not_read, spelled_with_names
from usdgaze.core.rig import Chain, CharacterFrame, bind_chain, character_frame
from usdgaze.errors import NoHeadError, RigError, UsdGazeError
from usdgaze.gaze.definition import GazeMapDefinition
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.directives import Directive
from usdgaze.passes.hidden import held_world
from usdgaze.passes.requests import DirectiveRequest
from usdgaze.usd import schema


def own_map(root, source: str) -> GazeMapDefinition | None:
    """The gaze map authored on a SkelRoot (GazeMapAPI), or None."""
    return schema.root_map(root, source)


def bind_root(clip: SkelClip, root, hints: BindHints | None = None) -> tuple[Chain, CharacterFrame]:
    """:func:`bind` with the map authored on the clip's SkelRoot ``root``: hints, GazeMapAPI, names."""
    return bind(clip, own_map(root, clip.source), hints)


def select_roots(stage, source: str, skel_root: str | None):
    """The SkelRoots to work on: the named one, else every one with a GazeMapAPI, else the only
    one holding a Skeleton."""
    from pxr import Sdf, UsdSkel

    from usdgaze.usd.skelio import no_skel_root, skel_roots, skeletons_under

    if skel_root:
        if not Sdf.Path.IsValidPathString(skel_root) or not (Sdf.Path(skel_root).IsAbsolutePath()
                                                               and Sdf.Path(skel_root).IsPrimPath()):
            raise UsdGazeError(f"{source}: --skel-root '{skel_root}' is not an absolute prim path such as /Character")
        prim = stage.GetPrimAtPath(skel_root)
        if not prim or not prim.IsValid():
            raise UsdGazeError(f"{source}:{skel_root}: no such prim")
        if not prim.IsA(UsdSkel.Root):
            raise UsdGazeError(f"{source}:{skel_root}: is a {prim.GetTypeName() or 'typeless prim'}, not a SkelRoot")
        return [prim]
    roots = skel_roots(stage)
    if not roots:
        raise no_skel_root(stage, source)
    with_map = [r for r in roots if schema.has_map(r)]
    if with_map:
        return with_map
    # A SkelRoot around another (a set or group exported as one) holds no Skeleton of its own: it was
    # listed among those to pick, and a stage of one character needed --skel-root.
    roots = [r for r in roots if skeletons_under(r)] or roots
    if len(roots) > 1:
        listed = ", ".join(str(r.GetPath()) for r in roots[:6])
        raise UsdGazeError(f"{source}: {len(roots)} SkelRoots and none has a GazeMapAPI; pick one with --skel-root ({listed})")
    return roots


def bound_skeletons(root, skels: list, source: str, bind_one) -> tuple[list, list[str]]:
    """``[(skel, bind_one(skel))]`` for the skeletons of ``root`` that bind, and notes: a skeleton with
    no head at all (``NoHeadError``: a face's, a prop's or cloth's skeleton) beside one that binds is
    no character and is left as it is, said in a note (``apply`` refused the SkelRoot, ``attend``
    planned whichever came first); any other error, or no skeleton that binds, is raised."""
    bound, headless = [], []
    for skel in skels:
        try:
            bound.append((skel, bind_one(skel)))
        except NoHeadError as exc:
            headless.append((skel, exc))
    if not bound:  # none binds: the first one's error, with its advice (none at all: nothing)
        if headless:
            raise headless[0][1]
        return [], []
    return bound, _no_character_notes(source, root, headless, bound[0][0])


def first_character(root, skels: list, source: str, bind_one) -> tuple:
    """``(skel, bind_one(skel), notes)`` of the first skeleton of ``root`` that binds, past those with no
    head at all (said in ``notes``, as :func:`bound_skeletons` says them); the skeletons after it are
    not read. Another error, or none that binds, is raised."""
    headless = []
    for skel in skels:
        try:
            value = bind_one(skel)
        except NoHeadError as exc:
            headless.append((skel, exc))
            continue
        return skel, value, _no_character_notes(source, root, headless, skel)
    if headless:  # none binds: the first one's error, with its advice
        raise headless[0][1]
    raise UsdGazeError(f"{source}:{root.GetPath()}: no Skeleton under this SkelRoot")


def _no_character_notes(source: str, root, headless: list, character) -> list[str]:
    """A line for each headless skeleton ``(skel, error)`` left as it is beside ``character``."""
    return [f"{source}:{s.GetPath()}: no head among its joints, so no character: left as it is "
            f"({root.GetPath()}'s character is {character.GetPath()})" for s, _ in headless]


def _map_key(definition: GazeMapDefinition) -> bytes:
    """Content key: characters sharing one map (by composition) build it once."""
    m = definition.motions
    return b"|".join([definition.params.tobytes(), m.offsets.tobytes(), m.timing.tobytes(),
                      repr(definition.settings).encode()])


_MAPS: dict[bytes, ParametricGazeMap] = {}
_MAPS_KEPT = 8


def built_map(definition: GazeMapDefinition) -> ParametricGazeMap:
    """The built map of a definition, built once per process: shots (and characters) sharing a map
    by content reuse it."""
    key = _map_key(definition)
    gaze_map = _MAPS.pop(key, None)
    if gaze_map is None:
        gaze_map = ParametricGazeMap(definition)
    _MAPS[key] = gaze_map  # most recently used last
    while len(_MAPS) > _MAPS_KEPT:
        _MAPS.pop(next(iter(_MAPS)))
    return gaze_map


def _stage_up(clip: SkelClip) -> np.ndarray:
    """The stage's up carried into skeleton space at the first frame the character is not scaled to
    nothing on (unit; a scaled skeleton too): the reader refused a clip without one."""
    up = np.linalg.solve(held_world(clip.skel_to_world)[0, :3, :3], clip.world_up)
    return up / np.linalg.norm(up)


TILT_NOTE_DEG = 1.0
"""A snap of the stage's up onto a skeleton axis larger than this is said in the report."""


def _character_frame(clip: SkelClip, joints: list[str], forward, label: str) -> CharacterFrame:
    stage_up = _stage_up(clip)
    up_s = snap_up(stage_up)  # the character upright in its own space, as on a tilted parent
    neutral = clip.neutral()
    legs = body_up(joints, neutral)
    if legs is not None and np.degrees(np.arccos(np.clip(np.dot(legs, up_s), -1.0, 1.0))) >= UP_SNAP_DEG:
        # Its legs hang along another axis: a character modelled upright leaning or lying in the stage
        # (taking the stage's up missed every look-at target by the lean; flat, by 90 deg).
        up_s = legs
    where = f"{clip.source}:{clip.skeleton}"
    frame = character_frame(joints, neutral, up_s, forward, where=where, forward_label=label,
                            stage_up=stage_up)
    tilt = float(np.degrees(np.arccos(np.clip(np.dot(up_s, stage_up), -1.0, 1.0))))
    if forward is not None:
        return frame
    if tilt < TILT_NOTE_DEG:
        lean = float(np.degrees(np.arccos(np.clip(np.abs(stage_up).max(), 0.0, 1.0))))
        return frame if lean < TILT_NOTE_DEG else dataclasses.replace(frame, note=_lean_note(where, lean))
    return dataclasses.replace(frame, note=_tilt_note(where, frame, up_s, stage_up, tilt))


def _lean_note(where: str, lean: float) -> str:
    """Why a look-at may miss a character leaning or lying in the stage (its skeleton's space turned
    further than ``UP_SNAP_DEG`` from the world's up, its legs saying nothing): its forward is left x
    the stage's up, as tilted as the character, and so is its eyes' modelled axis (a SkelRoot turned
    60 deg about X missed every look-at target by 60 deg by UsdSkel FK, with no word)."""
    return (f"{where}: the stage's up is {lean:.1f} deg off the nearest axis of the skeleton's space (the character "
            "leans or lies in the stage); its forward is taken as left x the stage's up, which is off where its face "
            "points in the bind pose by as much as it leans, and a look-at misses by that much: give the bind pose's "
            "forward with --forward X,Y,Z (skeleton space)")


def _tilt_note(where: str, frame: CharacterFrame, up_s: np.ndarray, stage_up: np.ndarray, tilt: float) -> str:
    """Why the frame is the skeleton's and not the world's, and the forward that would make it the world's:
    a skeleton whose own space is tilted while the character stands upright in the world (its joints
    counter-rotated) cannot be told from a character placed on a slope by anything in the skeleton."""
    axis = "XYZ"[int(np.argmax(np.abs(up_s)))]
    sign = "+" if up_s.max() > 0 else "-"
    left = frame.left - np.dot(frame.left, stage_up) * stage_up
    world_forward = np.cross(left / np.linalg.norm(left), stage_up)
    spelled = ",".join(f"{v:.4g}" for v in np.where(np.abs(world_forward) < 5e-5, 0.0, world_forward))
    return (f"{where}: the stage's up is {tilt:.1f} deg off the skeleton's {sign}{axis} axis in its space (its parent or "
            f"its own transform tilted); the character is taken as upright along {sign}{axis}, as on a tilted parent. "
            f"If it stands upright in the world instead, give --forward {spelled}")


def _by_names_too(joints: list[str], parents, joint_names, fn):
    """``fn(joints)`` on the joint paths, and where their words tell nothing (a RigError) on the
    paths spelled with the skeleton's jointNames (generic tokens such as ``j0/j1`` named Hips and
    Spine); the first error when neither serves."""
    try:
        return fn(joints)
    except RigError as first:
        named = spelled_with_names(joints, parents, joint_names)
        note = names_not_read(joints, joint_names)
        if note:
            raise type(first)(f"{first}{note}") from None
        if named is None:
            raise
        try:
            return fn(named)
        except RigError:
            raise first from None


def _map_bindings(maps: list[tuple[GazeMapDefinition | None, str]]) -> tuple[dict, dict, tuple | None, str]:
    """Roles, their labels, forward and its label from gaze maps, weakest first: a later map's role
    (or forward) replaces an earlier one's; a map's name, where given, goes into its labels."""
    bindings, labels, forward, label = {}, {}, None, "gaze:binding:forward"
    for definition, named in maps:
        if definition is None:
            continue
        of = f" of {named}" if named else ""
        for role, joints in definition.bindings.items():
            bindings[role], labels[role] = joints, f"gaze:binding:{role}{of}"
        if definition.forward is not None:
            forward, label = definition.forward, f"gaze:binding:forward{of}"
    return bindings, labels, forward, label


def bind(clip: SkelClip, definition: GazeMapDefinition | None, hints: BindHints | None = None,
         shared: GazeMapDefinition | None = None, shared_name: str = "") -> tuple[Chain, CharacterFrame]:
    """Chain and character frame of a clip: the user's hints first, then the SkelRoot's map's
    bindings (``definition``), then those of ``shared`` (a ``--map`` file, named ``shared_name`` in
    messages) for roles the SkelRoot leaves unbound, then names."""
    where = f"{clip.source}:{clip.skeleton}"
    bindings, labels, forward, label = _bindings(definition, hints, shared, shared_name)
    chain = _by_names_too(clip.joints, clip.parents, clip.joint_names,
                          lambda joints: bind_chain(joints, clip.parents, bindings, where=where, labels=labels,
                                                    tokens=clip.joints))
    frame = _by_names_too(clip.joints, clip.parents, clip.joint_names,
                          lambda joints: _character_frame(clip, joints, forward, label))
    return chain, frame


def chain_of(joints: list[str], parents, joint_names, definition: GazeMapDefinition | None,
             hints: BindHints | None, where: str) -> Chain:
    """The chain :func:`bind` binds, from the skeleton's joints alone (no samples read): what a review
    of a layer needs to know which joints the pass drove."""
    bindings, labels, _, _ = _bindings(definition, hints, None, "")
    return _by_names_too(joints, parents, joint_names,
                         lambda named: bind_chain(named, parents, bindings, where=where, labels=labels,
                                                  tokens=joints))


def _bindings(definition, hints: BindHints | None, shared, shared_name: str) -> tuple[dict, dict, tuple | None, str]:
    """Roles, labels, forward and its label: the user's hints over the SkelRoot's map over ``shared``'s."""
    hints = hints or BindHints()
    bindings, labels, forward, label = _map_bindings([(shared, shared_name), (definition, "")])
    for role, joints in hints.bindings:
        bindings[role], labels[role] = joints, f"{hints.bind_label} {role}={'+'.join(joints)}"
    if hints.forward is not None:
        forward, label = hints.forward, hints.forward_label
    return bindings, labels, forward, label


def root_directives(root, source: str, requests: list[DirectiveRequest]) -> list[DirectiveRequest]:
    """The command's directives, or without any the SkelRoot's own schedule."""
    from usdgaze.usd import schedule

    if requests:  # in time order, as a schedule holds them: the same directives record the same text
        return sorted(requests, key=lambda r: (r.seconds, r.time))
    if not schedule.has_schedule(root):
        raise UsdGazeError(f"{source}:{root.GetPath()}: no --shift, --look-at or --release given and no "
                           f"{schedule.API_NAME} on this SkelRoot; nothing to do")
    return schedule.read_schedule(root, source)


def skinned_by(stage, skel_root) -> list:
    """(path, Skeleton path) of each prim UsdSkel deforms under the SkelRoot ``skel_root``."""
    from pxr import Usd, UsdSkel

    root = UsdSkel.Root(skel_root)
    cache = UsdSkel.Cache()
    predicate = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    cache.Populate(root, predicate)
    return [(q.GetPrim().GetPath(), str(b.GetSkeleton().GetPrim().GetPath()))
            for b in cache.ComputeSkelBindings(root, predicate) for q in b.GetSkinningTargets()]


def _check_target_prim(stage, target: str, clip: SkelClip) -> None:
    """A look-at target that is the character (its SkelRoot, a prim holding it, its Skeleton, a mesh its
    Skeleton skins or a prim holding one) moves with it and lies in it: its own bounds' centre was looked
    at, down into its body, with a warning that it was behind the character. A skinned mesh of another
    character (or a prim holding one below its SkelRoot) has the bounds of its rest pose, where the body
    is not (a walking character's: 14-18 deg off, silently)."""
    from pxr import Sdf, UsdSkel

    if not Sdf.Path.IsValidPathString(target):  # usd.targets.check_target says so, in one line
        return
    path = Sdf.Path(target)
    if Sdf.Path(clip.skel_root).HasPrefix(path) or path.HasPrefix(Sdf.Path(clip.skeleton)):
        what = ("lies under the character's Skeleton " + clip.skeleton if path.HasPrefix(Sdf.Path(clip.skeleton))
                and path != Sdf.Path(clip.skeleton) else
                f"is the character {clip.skel_root} itself (or holds it, or is its Skeleton)")
        raise UsdGazeError(f"{clip.source}:{target}: {what}; a look-at target must be another prim (on a stage of "
                           "several characters, --skel-root picks the one that looks)")
    prim = stage.GetPrimAtPath(path)
    root = UsdSkel.Root.Find(prim) if prim else None
    if not root or root.GetPrim().GetPath() == path:
        return
    held = [skel for p, skel in skinned_by(stage, root.GetPrim()) if p.HasPrefix(path)]
    if not held:
        return
    if str(root.GetPrim().GetPath()) == clip.skel_root and clip.skeleton in held:
        raise UsdGazeError(f"{clip.source}:{target}: is (or holds) a mesh skinned by {clip.skeleton}, the body of the "
                           f"character {clip.skel_root} itself; a look-at target must be another prim")
    raise UsdGazeError(f"{clip.source}:{target}: is (or holds) a skinned mesh, whose bounds are its rest pose, not "
                       f"where the body is; look at the SkelRoot {root.GetPrim().GetPath()} (its bounds follow "
                       f"the body) or at a point")


def clip_directives(stage, clip: SkelClip, requests: list[DirectiveRequest], notes: list[str] | None = None
                ) -> tuple[list[Directive], list[np.ndarray], list[str]]:
    """Pass directives for one clip, and the world positions per frame of what its looks look at
    (another character's eyes; ``notes`` gets a line where they cannot be found)."""
    from usdgaze.usd.targets import sample_target

    tcps = clip.time_codes_per_second
    first, last = clip.seconds[0], clip.seconds[-1]
    index_of: dict = {}
    targets: list[np.ndarray] = []
    names: list[str] = []
    directives = []
    for r in requests:
        t = r.time_s(clip.start_time, tcps)
        # The ends as this message prints them (6 digits) are inside: a thousandth of a frame, or the
        # rounding of the printed seconds, past an end is that end.
        slack = max(1e-9, 1e-3 / tcps, 5e-6 * max(abs(first), abs(last)))
        if not first - slack <= t <= last + slack:
            said = f"{r.origin} ({r.flag})" if r.origin else f"{clip.where()}: {r.flag}"
            # One sample and no playback range to hold it over (USD holds it at every time): say what to author.
            one = ("; it has one time sample and the stage no playback range longer than a frame: author "
                   "startTimeCode/endTimeCode for the shot to add gaze to the pose it holds") if len(clip.times) == 1 else ""
            raise UsdGazeError(
                f"{said} lies outside the animation{f' {clip.animation}' if r.origin else ''} (time codes "
                f"{clip.times[0]:g} to {clip.times[-1]:g}, {first:g} to {last:g} s){one}")
        t = min(max(t, first), last)
        index = -1
        if r.kind == "look":
            key = r.target if r.target is not None else r.point
            if key not in index_of:
                index_of[key] = len(targets)
                if r.target is not None:
                    _check_target_prim(stage, r.target, clip)
                    targets.append(sample_target(stage, r.target, clip.times, clip.source, notes))
                    names.append(r.target)
                else:
                    targets.append(np.tile(np.asarray(r.point, dtype=float), (len(clip.times), 1)))
                    names.append(",".join(f"{v:g}" for v in r.point))
            index = index_of[key]
        directives.append(Directive(t, r.kind, r.yaw, r.pitch, index, r.weight, r.blend_s(tcps)))
    _check_frames(clip, requests, directives)
    return directives, targets, names


def _check_frames(clip: SkelClip, requests: list[DirectiveRequest], directives: list[Directive]) -> None:
    """Refuse two directives that start on the same frame: the look pass starts each on the first frame
    at or after its time, so the earlier one would never be seen (2 s and time code 241 at 120.48 per
    second, 0.3 ms apart, both started on frame 241 and the first was silently dropped)."""
    order = sorted(range(len(directives)), key=lambda k: directives[k].time_s)  # stable, as the pass sorts
    frames = np.searchsorted(clip.seconds, [directives[k].time_s for k in order])
    for (a, fa), (b, fb) in zip(zip(order, frames), zip(order[1:], frames[1:])):
        if fa != fb:
            continue
        ra, rb = requests[a], requests[b]
        first = ra.said if ra.origin else f"{clip.where()}: {ra.said}"
        second = rb.said
        if ra.origin and rb.origin:  # one schedule: name the second by its entry only
            head, _, entry = rb.origin.rpartition(": ")
            if ra.origin.startswith(head + ": "):
                second = f"{entry} ({rb.flag})"
        f = min(int(fa), len(clip.times) - 1)
        raise UsdGazeError(f"{first} and {second} start on the same frame (time code {clip.times[f]:g}), so "
                           "the first would never be seen; put them at least a frame apart")
