"""Resume keys: a shot is redone only when something its result depends on changed.

The key hashes the tool version and a digest of the installed package's own files (a build that
changes what it writes without a new version string still redoes the shots), the versions of USD,
numpy and scipy (and for a physics shot MuJoCo's), the shot's parameters, and the
*contents* of every layer the input composes (root layer, sublayers, references, payloads, value
clips: what ``UsdUtils.ComputeAllDependencies`` finds) and of the map file and its layers. It is
recorded in the override layer's ``customLayerData`` (``usdgaze.batchKey``); a shot whose outputs
exist and whose recorded key matches is skipped.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from pathlib import Path

from usdgaze.batch.manifest import Shot
from usdgaze.errors import UsdGazeError
from usdgaze.files.kinds import require_file

KEY_FIELD = "batchKey"


def _file_digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def composed_files(root: str) -> tuple[list[str], list[str], list]:
    """Real paths of the layers ``root`` composes (itself first; for the layers in a .usdz, the package
    file), its unresolved layer paths, and the opened layers (keep them alive so the stage opened next
    reuses them)."""
    from pxr import Ar, UsdUtils

    from usdgaze.errors import usd_failure
    from usdgaze.files.transaction import os_reason
    from usdgaze.usd.stage import without_usd_warnings

    require_file(root)
    try:
        # An unresolved layer is hashed into the key and said by the shot in one line: USD's own
        # multi-line warning about it here was noise in a farm log.
        with without_usd_warnings():
            layers, _assets, unresolved = UsdUtils.ComputeAllDependencies(root)
    except UnicodeError as exc:  # a name (or the folder it is in) that is not UTF-8
        raise UsdGazeError(f"{root}: cannot read its layers ({os_reason(exc)})") from None
    except Exception as exc:  # pxr raises Tf.ErrorException with multi-line text
        raise UsdGazeError(f"{root}: cannot read its layers ({usd_failure(exc)})") from None
    if not layers:
        raise UsdGazeError(f"{root}: cannot open as a USD layer")
    paths: list[str] = []
    for layer in layers:
        path = layer.realPath
        if path and Ar.IsPackageRelativePath(path):  # 'shot.usdz[notes.usda]': a layer in a package
            path = Ar.SplitPackageRelativePathOuter(path)[0]  # whose file holds it, hashed once
        if path and path not in paths:
            paths.append(path)
    return paths, sorted(str(p) for p in unresolved), layers


def shot_key(shot: Shot) -> tuple[str, list]:
    """The shot's resume key (hex) and the layers opened to compute it."""
    from usdgaze import __version__

    h = hashlib.sha256()
    h.update(f"usdgaze {__version__} {tool_digest()}\n".encode())
    h.update(f"{libraries()}\n".encode())
    h.update(json.dumps(shot.parameters(), sort_keys=True).encode() + b"\n")
    if shot.values.get("physics"):  # another MuJoCo release simulates other bits
        h.update(f"mujoco {_mujoco_version()}\n".encode())
    sources = [("input", shot.values["input"])]
    if "map" in shot.values:
        file, _, prim = shot.values["map"].partition(":/")
        h.update(f"map prim /{prim}\n".encode())
        sources.append(("map", file))
    opened = []
    for role, path in sources:
        files, unresolved, layers = composed_files(path)
        opened.extend(layers)
        for f in files:
            # Contents, not paths: moving a shot tree does not redo it; editing any layer does.
            h.update(f"{role} layer {_file_digest(f)}\n".encode())
        for u in unresolved:
            h.update(f"{role} unresolved {u}\n".encode())
    return h.hexdigest(), opened


@functools.lru_cache(maxsize=1)
def tool_digest() -> str:
    """SHA-256 of the usdgaze package's files as installed (paths and contents; no bytecode): the
    code that writes a shot, once per process."""
    import usdgaze

    root = Path(usdgaze.__file__).resolve().parent
    h = hashlib.sha256()
    files = sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc")
    for path in files:
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def libraries() -> str:
    """The versions of what computes and writes a shot beside usdgaze: USD (its crate writer's bytes),
    numpy and scipy (the model's arithmetic). Another release may write other bytes for the same
    inputs, so an output made with it is not this run's (it was skipped)."""
    from importlib.metadata import PackageNotFoundError, version

    import numpy
    from pxr import Usd

    try:
        scipy = version("scipy")
    except PackageNotFoundError:  # the model's import fails with its own line when it runs
        scipy = "none"
    return f"usd {'.'.join(map(str, Usd.GetVersion()))} numpy {numpy.__version__} scipy {scipy}"


def _mujoco_version() -> str:
    try:
        import mujoco
    except ImportError:  # the shot fails with its own one line when it runs
        return "none"
    return mujoco.__version__


def recorded_key(out: str) -> str | None:
    """The key recorded in an existing override layer, or None (missing, unreadable, no key)."""
    from pxr import Sdf

    if not os.path.isfile(out):
        return None
    try:
        layer = Sdf.Layer.OpenAsAnonymous(out, metadataOnly=True)
    except Exception:  # an unreadable old output is simply redone
        return None
    data = layer.customLayerData.get("usdgaze", {}) if layer else {}
    key = data.get(KEY_FIELD) if hasattr(data, "get") else None
    return str(key) if key else None
