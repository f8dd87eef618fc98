"""``--sublayer-into ROOT``: the override as ROOT's strongest sublayer, in step with the input.

ROOT must compose the input at the input's own paths and times (through its sublayers, at any offset,
or through a reference or payload without one); the override goes first at the offset at which ROOT's
layer stack brings the input in. Only ROOT's ``subLayers`` change (its opinions, metadata and encoding are
kept; OpenUSD writes it anew, so the ``#`` comments of a text file are not).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from pxr import Sdf

from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.files.identity import FileId
from usdgaze.files.transaction import Outputs, outputs_of
from usdgaze.usd.layers import USD_FORMATS, relative_asset_path

if TYPE_CHECKING:
    from pxr import Usd


def check_sublayer_target(root: str | os.PathLike, anim_paths: list[str],
                          input_path: str | os.PathLike | None = None, bound: tuple[str, ...] = ()) -> Sdf.Layer:
    """A copy of the layer ``root`` if the override can go in as its strongest sublayer, else a one-line error.

    Refuses when ``root`` itself holds opinions on the animations, since a sublayer is weaker than
    its root layer's own opinions (on ``bound``, skeletons the override binds a new animation to,
    their ``skel:animationSource``), and when ``root`` does not compose ``input_path`` (given). Called
    before anything is written. The copy is anonymous, so a
    failed command leaves the layer registry's ``root`` as it was.
    """
    if Path(root).suffix.lower() not in USD_FORMATS:
        raise UsdGazeError(f"{root}: --sublayer-into must name a .usda, .usdc or .usd layer")
    if not os.path.isfile(root):
        raise UsdGazeError(f"{root}: no such file to insert the sublayer into")
    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(root))
    except Exception as exc:  # pxr raises Tf.ErrorException with multi-line text
        raise UsdGazeError(f"{root}: cannot open the layer to insert the sublayer into ({usd_failure(exc)})") from None
    if layer is None:
        raise UsdGazeError(f"{root}: cannot open the layer to insert the sublayer into")
    if input_path is not None:
        from usdgaze.usd.stage import layer_dependencies, without_usd_warnings

        # The edit goes to the file a symlinked root names, so its sublayers are read from there (one may
        # be this command's output, not written yet: USD's warning about it is not ours to pass on).
        with without_usd_warnings():
            composed = {FileId.of(f) for f in layer_dependencies(os.path.realpath(root), strict=True)}
        if FileId.of(input_path) not in composed:
            raise UsdGazeError(f"{root}: does not compose {input_path} (no sublayer, reference or payload brings "
                               "it in), so the override would change nothing there; use the shot layer that does")
        _check_same_paths(root, input_path, anim_paths)
    for path in anim_paths:
        for name in ("rotations", "translations", "scales"):
            spec = layer.GetAttributeAtPath(Sdf.Path(path).AppendProperty(name))
            if spec is not None and (spec.HasDefaultValue() or layer.GetNumTimeSamplesForPath(spec.path)):
                raise UsdGazeError(
                    f"{root}:{path}.{name}: this layer's own opinion would win over any sublayer; "
                    "use --preview, or insert into a layer that sublayers this one"
                )
    for path in bound:
        if layer.GetRelationshipAtPath(Sdf.Path(path).AppendProperty("skel:animationSource")) is not None:
            raise UsdGazeError(
                f"{root}:{path}.skel:animationSource: this layer's own opinion would win over the sublayer's "
                "binding of the new animation; use --preview, or insert into a layer that sublayers this one"
            )
    return layer


def _check_same_paths(root: str | os.PathLike, input_path: str | os.PathLike, anim_paths: list[str]) -> None:
    """``root`` composes the input's animations at the input's own paths: a shot that references the
    character at another path (/World/Hero for the asset's /Character) is untouched by opinions at
    /Character (it was said to be 'inserted', and the shot played the input unchanged)."""
    real_input = os.path.realpath(input_path)
    if _offset_in_stack(Sdf.Layer.FindOrOpen(os.path.realpath(root)), real_input) is not None:
        return  # sublayered: the same paths
    from pxr import Usd

    from usdgaze.usd.stage import without_usd_warnings

    with without_usd_warnings():  # its sublayers may name this command's output, not written yet
        # Only the animations' prims are composed: a shot's other assets and payloads stay unread.
        stage = Usd.Stage.OpenMasked(os.path.realpath(root), Usd.StagePopulationMask([Sdf.Path(p) for p in anim_paths]))
    for path in anim_paths:
        prim = stage.GetPrimAtPath(path)
        if not prim or not any(_same_file(s.layer.realPath, real_input) for s in prim.GetPrimStack()):
            raise UsdGazeError(f"{root}: brings {input_path} in, but not at {path} (a reference or payload puts it "
                               "elsewhere), so the override, made at the input's paths, would change nothing there; "
                               "run apply on this layer itself (--skel-root the shot's character) and sublayer that")
        offset = _arc_offset(prim, real_input)
        plain = _scaling(stage.GetRootLayer(), real_input)
        if offset is not None and not (abs(offset.offset - plain.offset) < 1e-9 and abs(offset.scale - plain.scale) < 1e-12):
            raise UsdGazeError(f"{root}: brings {input_path} in at {path} with a time offset (a reference or payload's "
                               f"offset {offset.offset:g}, scale {offset.scale / plain.scale:g}), which a sublayer "
                               "cannot follow; run apply on this layer itself and sublayer that")


def _arc_offset(prim: Usd.Prim, real_input: str) -> Sdf.LayerOffset | None:
    """The time mapping from ``real_input`` (in a reference or payload's layer stack) to the stage's root."""
    nodes = [prim.GetPrimIndex().rootNode]
    while nodes:
        node = nodes.pop()
        nodes.extend(node.children)
        for layer, offset in zip(node.layerStack.layers, node.layerStack.layerOffsets):
            if _same_file(layer.realPath, real_input):
                return node.mapToRoot.timeOffset * offset
    return None


def _stack_offsets(layer: Sdf.Layer) -> list[tuple[str, Sdf.LayerOffset]]:
    """(real path, offset to the root) of every layer in ``layer``'s layer stack, as Pcp composes it."""
    from usdgaze.usd.stage import layer_stack

    return [(real, o) for _, real, o in layer_stack(layer)]


def override_offset(root: str | os.PathLike, input_path: str | os.PathLike | None) -> Sdf.LayerOffset:
    """The offset to author on the override as ``root``'s first sublayer so that it plays in step with
    the input: the offset at which ``root``'s layer stack brings the input in (its sublayer offsets
    composed), less the timeCodesPerSecond scaling Pcp gives the override as it gives the input.
    Identity when the input is not in ``root``'s layer stack (a reference or payload brings it in)."""
    if input_path is None:
        return Sdf.LayerOffset()
    target = os.path.realpath(input_path)
    layer = Sdf.Layer.FindOrOpen(os.path.realpath(root))
    found = _offset_in_stack(layer, target) if layer else None
    if found is None:
        return Sdf.LayerOffset()
    return found * _scaling(layer, target).GetInverse()


def _offset_in_stack(layer: Sdf.Layer, real_target: str) -> Sdf.LayerOffset | None:
    """The offset at which ``layer``'s layer stack brings in the file ``real_target``; None if it does not."""
    return next((o for p, o in _stack_offsets(layer) if _same_file(p, real_target)), None)


def _scaling(layer: Sdf.Layer, target: str) -> Sdf.LayerOffset:
    """The timeCodesPerSecond scaling alone that ``layer`` gives ``target`` brought in without an offset."""
    probe = Sdf.Layer.CreateAnonymous("usdgaze_offset.usda")  # the input as the sublayer of a like root
    if layer.HasTimeCodesPerSecond():
        probe.timeCodesPerSecond = layer.timeCodesPerSecond
    if layer.HasFramesPerSecond():
        probe.framesPerSecond = layer.framesPerSecond
    probe.subLayerPaths.append(target)
    return _stack_offsets(probe)[1][1]


def _listed(layer: Sdf.Layer, real_root: str, override: str | os.PathLike) -> list[int]:
    """Indices of ``layer``'s subLayers that name ``override`` (any spelling, symlinks and hard links followed)."""
    folder = os.path.dirname(real_root)
    return [i for i, p in enumerate(layer.subLayerPaths) if _same_file(os.path.join(folder, p), override)]


def _same_file(a: str | None, b: str | os.PathLike) -> bool:
    """Whether two paths name one file on disk (by identity: a hard link of the input is the input)."""
    return bool(a) and FileId.of(a) == FileId.of(b)


def sublayered(root: str | os.PathLike, override: str | os.PathLike, input_path=None) -> bool:
    """``override`` is in ``root``'s subLayers at the offset that keeps it in step with the input, and only
    usdgaze overrides of other prims (another character's gaze) are listed above it.

    Not only first: two manifests inserting into one shot layer each left the other's override second,
    and each rerun redid its shot to put its own first again, so neither ever skipped."""
    real = os.path.realpath(root)
    layer = Sdf.Layer.OpenAsAnonymous(real, metadataOnly=True)
    listed = _listed(layer, real, override) if layer is not None else []
    if not listed or layer.subLayerOffsets[listed[0]] != override_offset(real, input_path):
        return False
    folder = os.path.dirname(real)
    return _unmasked(override, [os.path.join(folder, p) for p in layer.subLayerPaths[:listed[0]]])


def _unmasked(override: str | os.PathLike, above: list[str]) -> bool:
    """Every layer of ``above`` is a usdgaze override authoring none of the properties ``override``
    authors: stronger, they change nothing of its result (an earlier take of the same character does)."""
    from usdgaze.usd.layers import is_override

    if not above:
        return True
    own = _property_paths(override)
    for path in above:
        if not is_override(path):
            return False
        theirs = _property_paths(path)
        if own is None or theirs is None or own & theirs:
            return False
    return True


def _property_paths(path: str | os.PathLike) -> set[Sdf.Path] | None:
    """The property paths the layer at ``path`` authors; None where it cannot be read."""
    try:
        layer = Sdf.Layer.OpenAsAnonymous(os.fspath(path))
    except Exception:  # pxr raises Tf.ErrorException: an unreadable layer masks what it may
        return None
    if layer is None:
        return None
    found: set[Sdf.Path] = set()
    layer.Traverse(Sdf.Path.absoluteRootPath, lambda p: found.add(p) if p.IsPropertyPath() else None)
    return found


def masked_overrides(root: str | os.PathLike, override: str | os.PathLike, anim_paths: list[str],
                     input_path: str | os.PathLike | None = None) -> list[str]:
    """A warning for each other usdgaze override ``root``'s layer stack holds over the same animations
    (an earlier take of this gaze, another name for ``--out``): the new override, strongest, hides its
    animation, but whatever else it authors still shows (its guides drew the old lines of sight over
    the new gaze, and ``validate`` found nothing). Layers the input composes are left out: a pass on
    the input adds to those, and says so (:func:`usdgaze.usd.layers.composed_override_notes`)."""
    from usdgaze.usd.layers import is_override
    from usdgaze.usd.stage import layer_dependencies, without_usd_warnings

    real = os.path.realpath(root)
    with without_usd_warnings():
        composed = {FileId.of(f) for f in layer_dependencies(os.path.realpath(input_path))} if input_path else set()
    notes = []
    for path, _ in _stack_offsets(Sdf.Layer.FindOrOpen(real))[1:]:
        if not path or _same_file(path, override) or FileId.of(path) in composed or not is_override(path):
            continue  # (a layer of another kind is not opened whole)
        layer = Sdf.Layer.FindOrOpen(path)
        held = [a for a in anim_paths if layer is not None and layer.GetPrimAtPath(a)]
        if held:
            notes.append(f"{root}: also sublayers {path}, an override usdgaze wrote for {', '.join(held)}: the new "
                         "override hides its animation, but its guides and whatever else it adds still show; remove it "
                         f"from the subLayers if it is an earlier take")
    return notes


def insert_sublayer(root: str | os.PathLike, override: str | os.PathLike, anim_paths: list[str],
                    outputs: Outputs | None = None, input_path: str | os.PathLike | None = None) -> bool:
    """Make ``override`` the strongest sublayer of ``root``, changing nothing but its subLayers.

    Returns False if it already was there. An entry naming it lower down (weaker than the input, so
    it would change nothing) is moved to the front. It gets the offset at which ``root`` brings in
    ``input_path`` (given), so that it plays in step with the input. Refuses (see
    :func:`check_sublayer_target`) when ``root`` itself holds opinions on the animations. A symlinked
    ``root`` is edited at its target, which keeps its mode; a read-only one is refused.
    """
    real = os.path.realpath(root)
    with outputs_of(outputs) as tx:
        # Read under a lock held until the edit is renamed into place: another command inserting into
        # the same root meanwhile (a farm task of another manifest) had its sublayer dropped by ours.
        tx.lock(os.path.dirname(real))
        layer = check_sublayer_target(root, anim_paths)
        offset = override_offset(real, input_path)
        listed = _listed(layer, real, override)
        if listed[:1] == [0] and layer.subLayerOffsets[0] == offset:
            return False
        if not tx.claimed(root):
            tx.claim(root, "--sublayer-into", edit=True)
        for i in reversed(listed):
            del layer.subLayerPaths[i]
        layer.subLayerPaths.insert(0, relative_asset_path(override, real))
        layer.subLayerOffsets[0] = offset
        tx.stage_layer(root, layer)
    return True
