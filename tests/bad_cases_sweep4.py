"""Catalogue builders for what an outside-in audit of ``attend --physics``'s task inputs found
(2026-12-07): catches USD or the pass read as none, an obstacle of no authored size, and checks the
coupled loop (objects in the stage) skipped or a second character reached only after the first was
simulated."""

from __future__ import annotations

from pxr import Sdf

from .bad_common import rig
from .bad_cases_sweep import _obstacle, _physics, _translated

BALL = "/Objects/Ball"


def _ball(layer: Sdf.Layer, api: bool = True, path: str = BALL) -> None:
    """A sphere 2 m before the character; ``api``: a GazeObjectAPI object."""
    prim = Sdf.CreatePrimInLayer(layer, path)
    prim.specifier, prim.typeName = Sdf.SpecifierDef, "Sphere"
    group = prim.nameParent
    group.specifier, group.typeName = Sdf.SpecifierDef, "Xform"
    if api:
        prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
        Sdf.AttributeSpec(prim, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = 0.11
    _translated(prim, (0.0, 1.3, 2.0))


def _catch(layer: Sdf.Layer, owner: str, target: str = BALL) -> None:
    rel = Sdf.RelationshipSpec(layer.GetPrimAtPath(owner), "usdgaze:physics:catch", custom=False)
    rel.targetPathList.explicitItems = [Sdf.Path(target)]


def b_physics_catch_no_objects(d):
    """A ball to catch on a stage with no GazeObjectAPI prim at all: the shot ran body-only, exit 0
    (with another object on the stage the same target was refused)."""
    def author(layer, r):
        _ball(layer, api=False)
        _catch(layer, r.skel_root)
    return _physics(d, author)


def b_physics_catch_on_the_skeleton(d):
    """The catch authored on the Skeleton, not the SkelRoot: ignored, no catch, exit 0."""
    def author(layer, r):
        _ball(layer)
        _catch(layer, r.skeleton)
    return _physics(d, author)


def b_physics_catch_an_attribute(d):
    """``string usdgaze:physics:catch = "/Objects/Ball"``: not a relationship, so no catch, exit 0."""
    def author(layer, r):
        _ball(layer)
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "usdgaze:physics:catch", Sdf.ValueTypeNames.String).default = BALL
    return _physics(d, author)


def b_physics_catch_outside_the_reference(d):
    """A character asset whose SkelRoot's catch targets a ball beside it in the asset, referenced into a
    shot that has its own ball: USD drops the target with a warning, and the shot ran without a catch."""
    r = rig(d, "char.usda")
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    layer.Reload(force=True)
    _ball(layer)
    _catch(layer, r.skel_root)
    layer.Save()
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    for key, value in {"upAxis": "Y", "metersPerUnit": 1.0}.items():
        shot.pseudoRoot.SetInfo(key, value)
    prim = Sdf.CreatePrimInLayer(shot, r.skel_root)
    prim.specifier = Sdf.SpecifierDef
    prim.referenceList.prependedItems = [Sdf.Reference("./char.usda", r.skel_root)]
    _ball(shot)
    shot.Save()
    return ["attend", str(d / "shot.usda"), "--physics", "--out", str(d / "gaze.usdc")]


def b_physics_obstacle_radius_not_authored(d):
    """An obstacle Sphere of radius 0.4 with no ``gaze:object:radius``: simulated as the schema's 0.1 m."""
    def author(layer, r):
        _obstacle(0.0)(layer, r)
        prim = layer.GetPrimAtPath("/Obstacles/A")
        prim.RemoveProperty(prim.properties["gaze:object:radius"])
        Sdf.AttributeSpec(prim, "radius", Sdf.ValueTypeNames.Double).default = 0.4
    return _physics(d, author)


def b_physics_on_a_platform_with_objects(d):
    """A character 1 m up, as ``physics-on-a-platform``, on a stage with an object to look at: the
    coupled loop never checked the ground, and the body dropped onto it (pelvis 90% at 0.2 s), exit 0."""
    def author(layer, r):
        _ball(layer)
        _translated(layer.GetPrimAtPath(r.skel_root), (0.0, 1.0, 0.0))
    return _physics(d, author)


def two_characters(d, bad_push: str = "NoSuchJoint"):
    """``shot.usda``: the rig referenced twice (/A, /B, each with the built-in map's GazeMapAPI, so both
    are simulated), /B with a push on ``bad_push``; the path of the shot."""
    from usdgaze.gaze.defaults import default_definition
    from usdgaze.usd.schema import dump_map

    r = rig(d, "char.usda")
    dump_map(default_definition(), d / "map.usda")
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    for key, value in {"upAxis": "Y", "metersPerUnit": 1.0}.items():
        shot.pseudoRoot.SetInfo(key, value)
    for name, x in (("A", 0.0), ("B", 3.0)):
        prim = Sdf.CreatePrimInLayer(shot, f"/{name}")
        prim.specifier = Sdf.SpecifierDef
        prim.referenceList.prependedItems = [Sdf.Reference("./char.usda", r.skel_root),
                                             Sdf.Reference("./map.usda", "/GazeMap")]
        _translated(prim, (x, 0.0, 0.0))
    b = shot.GetPrimAtPath("/B")
    Sdf.AttributeSpec(b, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = bad_push
    Sdf.AttributeSpec(b, "usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3).default = (100.0, 0.0, 0.0)
    shot.Save()
    return d / "shot.usda"


def b_physics_second_character_bad_push(d):
    """Two characters, the second's push on a joint it lacks: said only after the first had been
    simulated (seconds here, minutes on a real shot)."""
    return ["attend", str(two_characters(d)), "--physics", "--out", str(d / "gaze.usdc")]



def b_physics_task_misspelled(d):
    """A stone tagged ``usdgaze:physics:tasks``: no stone, and the shot ran without it, exit 0."""
    def author(layer, r):
        _ball(layer, api=False, path="/Stones/A")
        Sdf.AttributeSpec(layer.GetPrimAtPath("/Stones/A"), "usdgaze:physics:tasks",
                          Sdf.ValueTypeNames.Token).default = "stone"
    return _physics(d, author)


def b_push_on_a_prop(d):
    """``pushForce`` and ``pushJoint`` on the ball beside the character, no SkelRoot: acted on nothing, exit 0."""
    def author(layer, r):
        _ball(layer)
        prop = layer.GetPrimAtPath(BALL)
        Sdf.AttributeSpec(prop, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
        Sdf.AttributeSpec(prop, "usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3).default = (150.0, 0.0, 0.0)
    return _physics(d, author)


def b_physics_catch_on_a_prop(d):
    """The catch authored on the stage's ``/Objects`` group, not the SkelRoot: no catch, exit 0."""
    def author(layer, r):
        _ball(layer)
        _catch(layer, "/Objects")
    return _physics(d, author)


def _preview_root(d) -> tuple[str, str]:
    """The rig (input) and the --preview root apply wrote beside its override gaze.usdc."""
    from usdgaze import api

    r = rig(d)
    api.apply(str(r.path), ["0.5s:30:0"], d / "gaze.usdc", preview=d / "p.usda")
    return str(r.path), str(d / "p.usda")


def b_plot_layer_is_the_preview_root(d):
    """``plot INPUT --layer`` the --preview root (a stage holding no prims: it said 'overrides no
    SkelAnimation', naming neither what it was nor what to pass)."""
    source, root = _preview_root(d)
    return ["plot", source, "--layer", root, "--out", str(d / "plots")]


def b_validate_layer_is_the_preview_root(d):
    """``validate INPUT --layer`` the --preview root: it composed the input twice and said clean (exit
    0) where plot and preview refuse that layer."""
    source, root = _preview_root(d)
    return ["validate", source, "--layer", root]
