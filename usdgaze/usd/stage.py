"""The one stage opener: a USD stage, or a one-line error naming the file; and the files a stage reads."""

from __future__ import annotations

import os

from pxr import Sdf, Usd

from usdgaze.errors import UsdGazeError, usd_failure


def open_stage(path: str | os.PathLike, where: str | None = None,
               error: type[UsdGazeError] = UsdGazeError) -> Usd.Stage:
    """Open ``path`` as a stage; a missing file, a folder or USD's failure is one ``error`` line.

    ``where`` names the file in messages (default: the path as given).
    """
    path = os.fspath(path)
    where = where or path
    if os.path.isdir(path):
        raise error(f"{where}: is a folder, expected a USD file")
    if not os.path.isfile(path):
        raise error(f"{where}: no such file")
    try:
        stage = Usd.Stage.Open(path)
    except Exception as exc:  # pxr raises Tf.ErrorException with multi-line text
        raise error(f"{where}: cannot open as a USD stage ({usd_failure(exc)})") from None
    if stage is None:
        raise error(f"{where}: cannot open as a USD stage")
    return stage


def layer_dependencies(path: str | os.PathLike) -> list[str]:
    """Files a layer on disk brings in (sublayers, references, payloads, clips), without opening a stage."""
    from pxr import UsdUtils

    try:
        layers, assets, _unresolved = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(os.fspath(path)))
    except Exception:  # unreadable: the command that reads it says so in its own words
        return []
    files = [layer.realPath for layer in layers if layer is not None and not layer.anonymous and layer.realPath]
    return files + [str(a) for a in assets if a and os.path.isfile(str(a))]


def composed_files(stage: Usd.Stage) -> list[str]:
    """Every file on disk the stage composes: root layer, sublayers, references, payloads, value clips."""
    from pxr import UsdUtils

    files: list[str] = []
    layers = list(stage.GetUsedLayers())
    root = stage.GetRootLayer()
    try:
        dep_layers, assets, _unresolved = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(root.realPath or root.identifier))
    except Exception:  # an unreadable dependency is USD's warning, not ours to fail on
        dep_layers, assets = [], []
    layers.extend(dep_layers)
    for layer in layers:
        if layer is not None and not layer.anonymous and layer.realPath:
            files.append(layer.realPath)
    files.extend(str(a) for a in assets if a and os.path.isfile(str(a)))
    seen, out = set(), []
    for f in files:
        if f not in seen:
            seen.add(f)
            out.append(f)
    return out
