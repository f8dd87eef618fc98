"""The one stage opener: a USD stage, or a one-line error naming the file; and the files a stage reads."""

from __future__ import annotations

import contextlib
import os
import re
import sys
import threading

from pxr import Sdf, Usd

from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.files.kinds import not_a_file, require_file


def open_stage(path: str | os.PathLike, where: str | None = None,
               error: type[UsdGazeError] = UsdGazeError) -> Usd.Stage:
    """Open ``path`` as a stage; a missing file, a folder or USD's failure is one ``error`` line.

    ``where`` names the file in messages (default: the path as given).
    """
    path = os.fspath(path)
    where = where or path
    require_file(path, error, where)
    _require_utf8(path, error)
    return _opened(lambda: Usd.Stage.Open(path), where, error)


def _require_utf8(path: str, error: type[UsdGazeError]) -> None:
    """OpenUSD anchors a relative name at the working folder: a folder name that is not UTF-8 failed
    later, reading the layers' real paths (an internal error). Named absolute, as USD sees it."""
    from usdgaze.files.transaction import os_reason

    full = os.path.abspath(path)
    try:
        full.encode("utf-8")
    except UnicodeError as exc:
        raise error(f"{full}: cannot open as a USD stage ({os_reason(exc)})") from None


def open_root(root: Sdf.Layer, where: str, error: type[UsdGazeError] = UsdGazeError) -> Usd.Stage:
    """A stage on an in-memory root layer (``plot``, ``preview``, ``validate --layer``), opened as
    :func:`open_stage` opens a file: a failed composition is our one line, not USD's warnings too."""
    return _opened(lambda: Usd.Stage.Open(root), where, error)


def _opened(open_it, where: str, error: type[UsdGazeError]) -> Usd.Stage:
    """``open_it()``'s stage with USD's own warnings held back, and said only where it opened well."""
    with _usd_warnings() as said:
        try:
            stage = open_it()
        except Exception as exc:  # pxr raises Tf.ErrorException with multi-line text
            raise error(f"{where}: cannot open as a USD stage ({usd_failure(exc)})") from None
        if stage is None:
            raise error(f"{where}: cannot open as a USD stage")
        check_composition(stage, where, error)
        said.keep = True
    return stage


@contextlib.contextmanager
def without_usd_warnings():
    """USD's own warnings dropped while the block runs: for a look at a layer about to be edited, whose
    sublayers may name the output this command has not written yet."""
    with _usd_warnings():
        yield


def check_composition(stage: Usd.Stage, where: str, error: type[UsdGazeError] = UsdGazeError) -> None:
    """A stage whose composition failed (a missing sublayer, reference or payload, a cycle) is one
    ``error`` line: the shot would otherwise be computed on what USD skipped."""
    problems = stage.GetCompositionErrors()
    if not problems:
        return
    first = " ".join(str(problems[0]).split())
    first = re.sub(r",@anon:[^@]*@", "", first).removesuffix("; skipping.")  # and USD's session layer
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    raise error(f"{where}: composition failed: {first[:300]}{more}")


class _Said:
    keep = False


# File descriptor 2 belongs to the process: two threads swapping it at once (a dask worker's shots)
# would leave it on one thread's scratch file. Opens hold the swap one at a time.
_FD2 = threading.Lock()


@contextlib.contextmanager
def _usd_warnings():
    """USD's C++ warnings while a stage opens, held back: dropped when the open turns into our own
    one-line error, passed on to stderr otherwise. Another thread's stderr in that window is held
    back with them."""
    with _FD2:
        with _holding() as said:
            yield said


@contextlib.contextmanager
def _holding():
    said = _Said()
    sys.stderr.flush()
    try:
        held = _scratch()
    except OSError:  # nowhere to hold them: USD prints as it goes
        yield said
        return
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to hold back
        os.close(held)
        yield said
        return
    os.dup2(held, 2)
    try:
        yield said
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        if said.keep:
            os.lseek(held, 0, os.SEEK_SET)
            text = os.read(held, 1 << 20)
            if text:
                os.write(2, text)
        os.close(held)


def _scratch() -> int:
    """A file descriptor of an unnamed scratch file (in memory on Linux: no tempfile import)."""
    if hasattr(os, "memfd_create"):
        return os.memfd_create("usdgaze-usd-warnings")
    import tempfile

    fd, name = tempfile.mkstemp(prefix="usdgaze-")
    os.unlink(name)
    return fd


def layer_stack(layer: Sdf.Layer) -> list[tuple[str, str, Sdf.LayerOffset]]:
    """(identifier, real path, time offset to ``layer``) of every layer of ``layer``'s layer stack,
    strongest first, as Pcp composes it (nested offsets and timeCodesPerSecond ratios included).
    Names, not layers: a layer only the stack's cache held expires with it."""
    from pxr import Pcp

    ident = Pcp.LayerStackIdentifier(layer)
    cache = Pcp.Cache(ident)
    stack, _errors = cache.ComputeLayerStack(ident)
    return [(l.identifier, l.realPath, o) for l, o in zip(stack.layers, stack.layerOffsets)]


def layer_dependencies(path: str | os.PathLike, strict: bool = False, missing: bool = False) -> list[str]:
    """Files a layer on disk brings in (sublayers, references, payloads, clips), without opening a stage.

    Unreadable (it or a layer it brings in): none, for a command that says so in its own words, or
    with ``strict`` a one-line error naming it (a shot with a broken sublayer was said not to compose
    the input at all). With ``missing``, also the absolute paths of the layers it names that are not
    there (yet): another command's output, say."""
    from pxr import UsdUtils

    problem = not_a_file(path)
    if problem and os.path.exists(path):  # USD's open of a named pipe waits for a writer: the command hung
        if strict:
            raise UsdGazeError(f"{path}: {problem}")
        return []
    try:
        layers, assets, unresolved = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(os.fspath(path)))
    except Exception as exc:
        if strict:
            raise UsdGazeError(f"{path}: cannot read the layers it brings in ({usd_failure(exc)})") from None
        return []
    files = [layer.realPath for layer in layers if layer is not None and not layer.anonymous and layer.realPath]
    files += [str(a) for a in assets if a and os.path.isfile(str(a))]
    return files + [str(u) for u in unresolved if u and os.path.isabs(str(u))] if missing else files


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
