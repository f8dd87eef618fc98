"""The paths the one writer (:mod:`.transaction`) works with: its temporary folders' names and the
sweep of dead runs' leftovers, and what a claimed output path is (its real folder, the name limit
there, a device or pipe, a USD layer usdgaze did not write, a ``.usd`` file in the text encoding).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import socket
import time
from pathlib import Path

from usdgaze.files.kinds import special_kind

TMP_PREFIX = ".usdgaze-tmp-"
_STALE_FOREIGN_S = 24 * 3600.0  # another host's leftovers: we cannot ask whether its process lives


def _host() -> str:
    """This host in temporaries' names: at most 32 characters, and a longer name's tail as a digest
    (cut short, farm nodes named alike up to their number were one host to ``sweep``)."""
    name = "".join(c if c.isalnum() else "_" for c in socket.gethostname()) or "host"
    if len(name) <= 32:
        return name
    return f"{name[:23]}_{hashlib.sha256(name.encode()).hexdigest()[:8]}"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def sweep(folder: str | os.PathLike) -> list[str]:
    """Remove leftovers of dead usdgaze runs from ``folder``; returns their names."""
    removed = []
    host = _host()
    with contextlib.suppress(OSError), os.scandir(folder) as entries:
        for entry in entries:
            if not entry.name.startswith(TMP_PREFIX):
                continue
            owner, _, rest = entry.name[len(TMP_PREFIX):].rpartition("-")  # host-pid, token
            owner_host, _, pid = owner.rpartition("-")
            try:
                if owner_host == host and pid.isdigit():
                    stale = not _alive(int(pid))
                else:
                    stale = time.time() - entry.stat(follow_symlinks=False).st_mtime > _STALE_FOREIGN_S
                if stale:
                    if entry.is_dir(follow_symlinks=False):
                        shutil.rmtree(entry.path)
                    else:
                        os.unlink(entry.path)
                    removed.append(entry.name)
            except OSError:
                continue
    return removed


def _text_usd(path: str | os.PathLike) -> bool:
    """Whether ``path`` is an existing ``.usd`` file in the text encoding (``.usd`` holds either)."""
    if Path(path).suffix.lower() != ".usd":
        return False
    try:
        with open(path, "rb") as f:
            return f.read(8) != b"PXR-USDC"
    except OSError:  # a new file: USD's default encoding
        return False


def _special_kind(path: Path) -> str | None:
    """What ``path`` is when it exists and is a device, pipe or socket (not followed)."""
    try:
        return special_kind(path.lstat().st_mode)
    except OSError:
        return None


_USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


def _foreign_layer(path: Path) -> str | None:
    """What an existing USD layer that usdgaze did not write holds (its first root prim, else its first
    sublayer, else its metadata), else None: ours, a truly empty layer (a placeholder), or a file not
    readable as USD (replaced as any file is). Ours: a ``usdgaze`` or ``usdgaze:...`` entry in its
    customLayerData; for a preview, whose entry says so, only while it holds no prims (an animator may
    save edits into it).

    A layer of sublayers and no prims is a shot's root (lighting, layout): it was replaced silently.
    Previews written before they carried the entry are not told apart from one: a root sublayering
    [override, input] is also what an artist writes by hand, and the cost of refusing an old preview
    (remove it once) is small beside that of losing a shot's root."""
    if path.suffix.lower() not in _USD_SUFFIXES:
        return None
    from pxr import Sdf

    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(path), metadataOnly=True)
        if layer is None:
            return None
        marks = {k: v for k, v in layer.customLayerData.items() if k == "usdgaze" or k.startswith("usdgaze:")}
        preview = isinstance(marks.get("usdgaze"), dict) and bool(marks["usdgaze"].get("preview"))
        if marks and not preview:
            return None
        layer = Sdf.Layer.OpenAsAnonymous(str(path))
    except Exception:  # pxr raises Tf.ErrorException for a file that is no layer
        return None
    if layer is None:
        return None
    if layer.rootPrims:
        return str(layer.rootPrims[0].path)
    if preview:
        return None
    if layer.subLayerPaths:
        return f"sublayer @{layer.subLayerPaths[0]}@"
    keys = [k for k in layer.pseudoRoot.ListInfoKeys() if k != "subLayerOffsets"]
    return f"layer metadata {', '.join(keys)}" if keys else None


def _unfollowed(path: str | os.PathLike) -> Path:
    """The real folder and the name as given: a symlink there is the file itself."""
    parent, name = os.path.split(os.path.abspath(os.fspath(path)))
    return Path(os.path.realpath(parent)) / name


def _name_max(folder: Path) -> int:
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255
