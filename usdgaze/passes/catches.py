"""The balls a character is to catch: the SkelRoot's ``usdgaze:physics:catch`` relationship, read and
checked at the USD edge (docs/physics.md, "The ball catch"). Each way of authoring it that USD or the
pass would quietly read as no catch (an attribute of that name, a target outside the reference that
brings the character in, a ball on a stage with no objects) is one line: the shot ran without its
catch, exit 0, before."""

from __future__ import annotations

from pxr import Sdf, Usd

from usdgaze.errors import UsdGazeError
from usdgaze.usd.checks import authored_type

CATCH = "usdgaze:physics:catch"


def catch_targets(root: Usd.Prim, source: str) -> list[Sdf.Path]:
    """The targets of ``root``'s ``usdgaze:physics:catch`` relationship, as USD composes them."""
    attr = root.GetAttribute(CATCH)
    if attr:
        raise UsdGazeError(f"{source}:{attr.GetPath()}: is an attribute (a {authored_type(attr)}), expected a "
                           f"relationship to the balls to catch: rel {CATCH} = </Objects/Ball>")
    rel = root.GetRelationship(CATCH)
    if not rel:
        return []
    dropped = _dropped_targets(rel)
    if dropped:
        target, layer = dropped[0]
        raise UsdGazeError(f"{source}:{rel.GetPath()}: its target <{target}> (in {layer}) lies outside the reference "
                           f"or payload that brings {root.GetPath()} in, so USD drops it and the shot would run "
                           f"without that catch; author it on {root.GetPath()} in the shot's own layer, as a list "
                           f"that replaces the asset's (rel {CATCH} = <...>)")
    return list(rel.GetTargets())


def require_objects(root: Usd.Prim, source: str, targets: list[Sdf.Path], paths: list[str], api: str) -> list[int]:
    """The indices in ``paths`` (the character's objects) of the balls ``targets`` names."""
    missing = [t for t in targets if str(t) not in paths]
    if missing:
        raise UsdGazeError(f"{source}:{root.GetPath()}.{CATCH}: <{missing[0]}> is not an object "
                           f"(a prim with {api}) of the stage")
    return [paths.index(str(t)) for t in targets]


def _dropped_targets(rel: Usd.Relationship) -> list[tuple[Sdf.Path, str]]:
    """(target, layer) of each authored target that USD's composition cannot map into the stage's
    namespace (it warns and ignores it): a reference's target outside the referenced prim. Read
    from the strongest opinion down to the first explicit list, which hides the weaker ones."""
    nodes = list(_nodes(rel.GetPrim().GetPrimIndex().rootNode))
    out = []
    for spec in rel.GetPropertyStack():
        ops = spec.targetPathList
        authored = [*ops.explicitItems, *ops.prependedItems, *ops.appendedItems, *ops.addedItems]
        node = next((n for n in nodes if n.path == spec.path.GetPrimPath() and spec.layer in n.layerStack.layers),
                    None)
        if node is not None:
            mapped = node.mapToRoot.Evaluate()
            out += [(t, spec.layer.identifier) for t in authored if mapped.MapSourceToTarget(t).isEmpty]
        if ops.isExplicit:
            break
    return out


def _nodes(node):
    yield node
    for child in node.children:
        yield from _nodes(child)


def kind_notes(root: Usd.Prim, prims: list, catches: list[int], source: str) -> list[str]:
    """A warning per ball to catch that the eyes' belief does not take for thrown: its path is then
    predicted without gravity, a straight line, and the hand reaches where the ball does not come (a
    seeded throw at the catch's step: 30 cm from the palm at its nearest, against 4.5 cm as "ballistic")."""
    notes = []
    for j in catches:
        attr = prims[j].GetAttribute("gaze:object:kind")
        kind = str(attr.Get() or "") if attr else ""
        if kind != "ballistic":
            notes.append(f"{source}:{prims[j].GetPath()}.gaze:object:kind: '{kind}' on a ball {root.GetPath()} is to "
                         "catch: its path is predicted without gravity, in a straight line; author 'ballistic' "
                         "for a thrown ball")
    return notes
