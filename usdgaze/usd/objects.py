"""Objects to look at, read from a stage: prims with ``GazeObjectAPI`` or named paths.

An object's true state is the translation of its local-to-world transform, sampled at the planner's
times (for a Boundable whose geometry is not centred on its origin, a mesh baked in world space, the
centre of its world bounds, as ``--look-at`` takes it; for animated geometry, that centre at every time;
for a character, its eyes, ``usdgaze.usd.faces``); positions come back in metres (the stage's metersPerUnit
applied). A transform USD cannot evaluate is refused first (``usdgaze.usd.xformops``).

Positions are read by :mod:`usdgaze.usd.object_positions`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom

from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.usd.faces import HEAD_RADIUS_M, eye_positions
from usdgaze.usd.checks import authored_type
from usdgaze.usd.plugin import has_api
from usdgaze.usd.object_positions import positions, sampled
from usdgaze.usd.targets import drawn_problem, instances_note, prototype_instancer
from usdgaze.usd.xformops import check_transform
from usdgaze.values import MAX_OBSTACLE_RADIUS_M, MAX_TARGET_DISTANCE_M

API_NAME = "GazeObjectAPI"
PHYSICS_TASK = "usdgaze:physics:task"
"""The physics pass's task of a prim (``stone`` or ``obstacle``); read by ``usdgaze.passes.physics``."""
KINDS = ("", "ballistic", "static", "moving")


@dataclass
class StageObject:
    path: str
    positions: np.ndarray  # (K, 3) metres, world
    importance: np.ndarray  # (K,) > 0
    radius: float
    kind: str
    sized: bool = False  # the radius is authored (not the schema's fallback)
    visible: np.ndarray | None = None
    """(K,) whether USD draws it (its and its ancestors' visibility); None: at every time."""
    face: bool = False
    """A character read at its eyes (``usdgaze.usd.faces``): its positions are its face's."""

    @property
    def view_radius(self) -> float:
        """The size the field of view sees: the authored radius; without one a point (0), or for a
        character read at its eyes its head (its face is what is seen, not the body round it)."""
        return self.radius if self.sized else HEAD_RADIUS_M if self.face else 0.0


_TYPES = {"gaze:object:importance": ("float", "double", "half"), "gaze:object:radius": ("float", "double", "half"),
          "gaze:object:kind": ("token", "string")}


def type_problem(attr: Usd.Attribute) -> str | None:
    """Why a GazeObjectAPI attribute's authored type is not the schema's (a number, or a word), or None."""
    wanted = _TYPES.get(attr.GetName())
    spelled = authored_type(attr)
    if wanted is None or spelled in wanted:
        return None
    return f"{attr.GetName()}: is a {spelled or 'value of no type'}, expected a {' or '.join(wanted[:2])}"


def importance_problem(attr: Usd.Attribute) -> str | None:
    """The first authored importance (a time sample, or the default) that is not > 0, or None."""
    samples = attr.GetTimeSamples()
    for t, v in ((t, attr.Get(t)) for t in samples) if samples else [(None, attr.Get())]:
        if v is None or not np.isfinite(float(v)) or float(v) <= 0.0:
            at = "" if t is None else f" at time {t:g}"
            return f"gaze:object:importance: {'no value' if v is None else f'{float(v):g}'}{at}, expected > 0"
    return None


def _attr(prim: Usd.Prim, name: str, default, where: str):
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return default
    problem = type_problem(attr)
    if problem:
        raise UsdGazeError(f"{where}.{problem}")
    if attr.GetResolveInfo().GetSource() in (Usd.ResolveInfoSourceTimeSamples, Usd.ResolveInfoSourceValueClips):
        # Radius and kind are uniform (one value for the shot). Time samples (a DCC export writes a
        # sample per frame) are not what Get() at the default time sees: that is the schema's fallback
        # (0.1 m, no kind), so a sampled "ballistic" or a sampled negative radius went unnoticed.
        times = attr.GetTimeSamples()
        values = [attr.Get(t) for t in times]
        if not values or any(v is None for v in values):
            raise UsdGazeError(f"{where}.{name}: has no value")
        first = values[0]
        for t, v in zip(times, values):
            both_nan = isinstance(v, float) and isinstance(first, float) and np.isnan(v) and np.isnan(first)
            if v != first and not both_nan:
                raise UsdGazeError(f"{where}.{name}: {_shown(first)} at time {times[0]:g} but {_shown(v)} at time "
                                   f"{t:g}; it is one value for the whole shot (uniform): author it once")
        return first
    value = attr.Get()
    if value is None:
        raise UsdGazeError(f"{where}.{name}: has no value")
    return value


def _shown(value) -> str:
    return f"{value:g}" if isinstance(value, float) else f"'{value}'"


def _importance(prim: Usd.Prim, time_codes: np.ndarray, where: str) -> np.ndarray:
    attr = prim.GetAttribute("gaze:object:importance")
    if not attr or not attr.HasAuthoredValue():
        return np.ones(len(time_codes))
    problem = type_problem(attr) or importance_problem(attr)  # the authored samples, as validate checks them
    if problem:
        raise UsdGazeError(f"{where}.{problem}")
    fast = sampled(attr, time_codes)
    if fast is not None:
        return fast.astype(float).reshape(len(time_codes))
    values = [attr.Get(Usd.TimeCode(float(t))) for t in time_codes]
    if any(v is None for v in values):
        raise UsdGazeError(f"{where}.gaze:object:importance: has no value")
    return np.array(values, dtype=float)


def object_prims(stage: Usd.Stage, source: str, paths: list[str] | None) -> list[Usd.Prim]:
    """The prims named by ``paths``, else every prim with GazeObjectAPI; one-line errors otherwise."""
    if paths is not None:
        if not paths:
            raise UsdGazeError(f"{source}: --objects names no prim; give PATH,... or leave it out for every "
                               f"prim with {API_NAME}")
        prims = []
        for p in paths:
            if not Sdf.Path.IsValidPathString(p) or not Sdf.Path(p).IsAbsolutePath():
                raise UsdGazeError(f"{source}: --objects entry '{p}' is not an absolute prim path such as /World/Ball")
            if not Sdf.Path(p).IsPrimPath():  # /Ball.radius: 'no such prim' said nothing of why
                raise UsdGazeError(f"{source}: --objects entry '{p}' names a property; give its prim, "
                                   f"{Sdf.Path(p).GetPrimPath()}")
            if any(q.GetPath() == Sdf.Path(p) for q in prims):  # its belief and cost would count twice
                raise UsdGazeError(f"{source}:{p}: --objects names this prim twice; name each object once")
            prim = stage.GetPrimAtPath(p)
            if not prim or not prim.IsValid():
                raise UsdGazeError(f"{source}:{p}: no such prim")
            if not prim.IsActive():
                raise UsdGazeError(f"{source}:{p}: is inactive (active = false), so it is not in the scene")
            prims.append(prim)
    else:
        prims = [p for p in scene_prims(stage) if has_api(p, API_NAME)]
    if not prims:
        raise UsdGazeError(f"{source}: no objects to look at: apply {API_NAME} to some prims or pass --objects PATH,...")
    for prim in prims:
        require_xformable(prim, source, "an object")
        _require_not_skinned(prim, source)
        instancer = prototype_instancer(prim)
        if instancer is not None:  # it was an object where no instance is drawn
            raise UsdGazeError(f"{source}:{prim.GetPath()}: is a prototype of the PointInstancer {instancer.GetPath()}, "
                               "drawn only where its instances are; make the PointInstancer the object")
        problem = drawn_problem(prim)
        if problem:
            raise UsdGazeError(f"{source}:{prim.GetPath()}: {problem}; make one of those the object")
    return prims


def _require_not_skinned(prim: Usd.Prim, source: str) -> None:
    """One line for a skinned mesh, or a prim holding one below its SkelRoot: its transform stays and its
    bounds are the rest pose, so a walking character's body was an object standing where it started
    (``apply --look-at`` refuses it too)."""
    from pxr import UsdSkel

    from usdgaze.characters import skinned_by

    root = UsdSkel.Root.Find(prim)
    if not root or root.GetPrim() == prim:
        return
    if any(path.HasPrefix(prim.GetPath()) for path, _ in skinned_by(prim.GetStage(), root.GetPrim())):
        raise UsdGazeError(f"{source}:{prim.GetPath()}: is (or holds) a skinned mesh, whose bounds are its rest pose, "
                           f"not where the body is; make the SkelRoot {root.GetPrim().GetPath()} the object (its "
                           "bounds follow the body)")


def scene_prims(stage: Usd.Stage):
    """Every active, loaded, defined prim of the stage, those inside instances included (an instanced
    set of stones or props is still in the scene)."""
    return stage.Traverse(Usd.TraverseInstanceProxies())


def require_xformable(prim: Usd.Prim, source: str, role: str) -> None:
    """One line unless ``prim`` has a transform: without one it would sit at the world's origin."""
    if not prim.IsA(UsdGeom.Xformable):
        kind = prim.GetTypeName() or "typeless prim"
        raise UsdGazeError(f"{source}:{prim.GetPath()}: is a {kind} without a transform; {role} must be Xformable")


def check_apart(prims: list[Usd.Prim], roots: list[Usd.Prim], source: str, role: str = "an object to look at",
                inside: bool = False) -> None:
    """One line for a prim that is a character's SkelRoot or holds it (it moves with the character),
    and with ``inside`` for one within the character too (a stone or an obstacle on the body)."""
    for prim in prims:
        for root in roots:
            problem = _apart_problem(prim, root, role, inside)
            if problem:
                raise UsdGazeError(f"{source}:{prim.GetPath()}: {problem}")


def _holds(prim: Usd.Prim, root: Usd.Prim) -> bool:
    return root.GetPath().HasPrefix(prim.GetPath())


def _apart_problem(prim: Usd.Prim, root: Usd.Prim, role: str, inside: bool) -> str | None:
    if _holds(prim, root):
        return f"is the character {root.GetPath()} or holds it; {role} must be another prim"
    if inside and prim.GetPath().HasPrefix(root.GetPath()):
        return f"lies inside the character {root.GetPath()}; {role} must be another prim"
    return None


def objects_of(prims: list[Usd.Prim], roots: list[Usd.Prim], source: str) -> list[list[Usd.Prim]]:
    """Per planned character (SkelRoot of ``roots``), the objects it looks at: all but one that is it or
    holds it, which the others look at (two characters look at each other; before, any object that was
    or held any planned character was refused). One line for an object inside a planned character (its
    Skeleton, a prop below its SkelRoot: it moves with that body), for one that is or holds every
    planned character, and for a character left nothing to look at."""
    for prim in prims:
        problems = [_apart_problem(prim, root, "an object to look at", True) for root in roots]
        within = [p for p, root in zip(problems, roots) if p and not _holds(prim, root)]
        if within or all(problems):
            raise UsdGazeError(f"{source}:{prim.GetPath()}: {(within or problems)[0]}")
    out = []
    for root in roots:
        own = [p for p in prims if not _holds(p, root)]
        if not own:
            raise UsdGazeError(f"{source}:{root.GetPath()}: has nothing to look at: every object is this character "
                               "or holds it; give it another object, or leave it out with --skel-root")
        out.append(own)
    return out


def is_obstacle(prim: Usd.Prim) -> bool:
    """Whether the physics pass walks round ``prim``: ``usdgaze:physics:task`` is ``obstacle`` (a
    time-sampled task is refused with its own line where the tasks are read)."""
    task = prim.GetAttribute(PHYSICS_TASK)
    return bool(task) and task.HasAuthoredValue() and not task.GetNumTimeSamples() and task.Get() == "obstacle"


def obstacle_radius_problem(prim: Usd.Prim, radius: float | None) -> str | None:
    """Why an obstacle's ``gaze:object:radius`` (``radius`` None: not authored) is no body a person walks
    round, 0 < radius <= 10 m, or None (also for a prim that is no obstacle): ``attend`` refuses it and
    ``validate`` reports it in these words."""
    if not is_obstacle(prim):
        return None
    if radius is None:  # the schema's 0.1 m was taken: a Sphere of radius 0.4 was walked 30 cm into, unsaid
        return (f"gaze:object:radius: not authored; an obstacle's size is this radius, in "
                f"metres (more than 0 and at most {MAX_OBSTACLE_RADIUS_M:g} m): author it")
    if not 0.0 < radius <= MAX_OBSTACLE_RADIUS_M:  # NaN fails it too
        return (f"gaze:object:radius: {radius:g} m for an obstacle; expected more than 0 and "
                f"at most {MAX_OBSTACLE_RADIUS_M:g} m (a body the character walks round)")
    return None


def authored_obstacle_problem(prim: Usd.Prim) -> str | None:
    """What :func:`read_objects` refuses of an obstacle's radius as ``prim`` authors it: its reading (samples
    that differ, a wrong type) or :func:`obstacle_radius_problem`; None for a sound one, or no obstacle."""
    if not is_obstacle(prim):
        return None
    name = "gaze:object:radius"
    try:
        authored = _attr(prim, name, None, "")
    except UsdGazeError as exc:
        # A wrong type on a GazeObjectAPI prim the prim validators visit is GazeObject's Type line already.
        if has_api(prim, API_NAME) and not prim.IsInstanceProxy() and type_problem(prim.GetAttribute(name)):
            return None
        return str(exc).lstrip(".")
    return obstacle_radius_problem(prim, None if authored is None else float(authored))


def read_objects(stage: Usd.Stage, source: str, prims: list[Usd.Prim], time_codes: np.ndarray,
                 meters_per_unit: float, notes: list[str] | None = None, faces: bool = True) -> list[StageObject]:
    """World positions of every object at ``time_codes`` plus its GazeObjectAPI attributes; with ``faces``
    a character at its eyes, ``notes`` getting a line where they cannot be found (else its bounds' centre,
    a body to walk round)."""
    out = []
    caches: list = []  # per-time caches, made only for an object the fast path cannot read
    for prim in prims:
        where = f"{source}:{prim.GetPath()}"
        importance = _importance(prim, time_codes, where)
        authored = _attr(prim, "gaze:object:radius", None, where)
        radius = 0.1 if authored is None else float(authored)
        kind = str(_attr(prim, "gaze:object:kind", "", where))
        if not np.all(np.isfinite(importance)) or np.any(importance <= 0):
            bad = importance[~(np.isfinite(importance) & (importance > 0))][0]
            raise UsdGazeError(f"{where}.gaze:object:importance: {bad:g} must be > 0")
        problem = obstacle_radius_problem(prim, None if authored is None else radius)
        if problem:
            raise UsdGazeError(f"{where}.{problem}")
        if not np.isfinite(radius) or radius < 0:
            raise UsdGazeError(f"{where}.gaze:object:radius: {radius:g}, expected a finite number >= 0 (m)")
        if kind not in KINDS:
            raise UsdGazeError(f"{where}.gaze:object:kind: '{kind}' is not one of {', '.join(repr(k) for k in KINDS)}")
        check_transform(prim, source)
        note = instances_note(prim, source)  # said once, whichever characters read it
        if note and notes is not None and note not in notes:
            notes.append(note)
        try:
            eyes = eye_positions(prim, time_codes, source, notes) if faces else None
            with np.errstate(over="ignore", invalid="ignore"):  # a transform that overflows is said below
                pos = (positions(prim, time_codes, caches, source) if eyes is None else eyes) * meters_per_unit
        except Tf.ErrorException as exc:  # what check_transform cannot see: USD's own word, in one line
            raise UsdGazeError(f"{where}.xformOpOrder: USD cannot evaluate this transform "
                               f"({usd_failure(exc)})") from None
        if not np.all(np.isfinite(pos)):
            raise UsdGazeError(f"{where}: its world transform is not finite at some time")
        if np.abs(pos).max(initial=0.0) > MAX_TARGET_DISTANCE_M:
            raise UsdGazeError(f"{where}: lies over {MAX_TARGET_DISTANCE_M:g} m from the world's origin at some "
                               "time; a point that far is only a direction")
        out.append(StageObject(str(prim.GetPath()), pos, importance, radius, kind, authored is not None,
                               _visibility(prim, time_codes), eyes is not None))
    return out


def _visibility(prim: Usd.Prim, time_codes: np.ndarray) -> np.ndarray | None:
    """Whether the object is drawn at each time code, or None where it always is: an invisible object
    (a prop hidden until it is thrown) was seen and looked at (92% of a shot where it never showed)."""
    above = [p for p in _ancestry(prim) if p.IsA(UsdGeom.Imageable)]
    attrs = [UsdGeom.Imageable(p).GetVisibilityAttr() for p in above]
    image = UsdGeom.Imageable(prim)
    if not any(a and a.ValueMightBeTimeVarying() for a in attrs):
        # At a time code, not the default time: one time sample (USD holds it) is no default value.
        at = Usd.TimeCode(float(time_codes[0])) if len(time_codes) else Usd.TimeCode.Default()
        shown = image.ComputeVisibility(at) != UsdGeom.Tokens.invisible
        return None if shown else np.zeros(len(time_codes), dtype=bool)
    # Animated visibility (rare): evaluated at each step, the object's own and its ancestors'.
    return np.array([image.ComputeVisibility(Usd.TimeCode(float(t))) != UsdGeom.Tokens.invisible
                     for t in time_codes], dtype=bool)


def _ancestry(prim: Usd.Prim) -> list[Usd.Prim]:
    out = []
    while prim and not prim.IsPseudoRoot():
        out.append(prim)
        prim = prim.GetParent()
    return out
