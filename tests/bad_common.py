"""Helpers for the bad-input catalogue builders (tests/bad_cases_*.py) and its runner.

A builder gets an empty case folder ``d``, writes what the case needs there and returns the argv of
one command: ``usdgaze`` arguments (``["batch", MANIFEST, ...]`` for ``usdgaze batch``).
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import io
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from pxr import Sdf, Vt

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)

from . import measure
from . import synthetic as syn

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "usdgaze"]
BATCH = ROOT / "pipeline" / "batch.py"
SHIFT = ["--shift", "0.5s:30:0"]
_CACHE = Path(tempfile.mkdtemp(prefix="usdgaze-bad-rigs-"))
atexit.register(shutil.rmtree, _CACHE, True)
_RIGS: dict[tuple, syn.Rig] = {}


def rig(d: Path, name: str = "in.usda", **kw) -> syn.Rig:
    """A small synthetic rig at ``d/name``: built once per set of options, then copied."""
    kw.setdefault("frames", 90)
    kw.setdefault("mesh", False)
    key = tuple(sorted(kw.items())) + (Path(name).suffix,)
    if key not in _RIGS:
        _RIGS[key] = syn.make_rig(_CACHE / f"rig{len(_RIGS)}{Path(name).suffix}", **kw)
    base = _RIGS[key]
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(base.path, path)
    return dataclasses.replace(base, path=path)


def apply_argv(d: Path, src: Path, *extra: str, shifts=SHIFT, out: str = "gaze.usdc") -> list[str]:
    return ["apply", str(src), *shifts, "--out", str(d / out), *extra]


def edited(d: Path, fn, name: str = "in.usda", **kw) -> Path:
    """A rig edited at the Sdf level by ``fn(layer, rig)``."""
    r = rig(d, name, **kw)
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    layer.Reload(force=True)  # a copy of a cached rig: never the registry's stale content
    fn(layer, r)
    layer.Save()
    return r.path


def remove(layer: Sdf.Layer, path: str) -> None:
    p = Sdf.Path(path)
    if p.IsPropertyPath():
        owner = layer.GetPrimAtPath(p.GetPrimPath())
        owner.RemoveProperty(owner.properties[p.name])
    else:
        del layer.GetPrimAtPath(p.GetParentPath()).nameChildren[p.name]


def set_sample(layer: Sdf.Layer, r: syn.Rig, attr: str, value, at: int = 5) -> None:
    layer.SetTimeSample(Sdf.Path(f"{r.animation}.{attr}"), float(r.times[at]), value)


def quats(n: int, nan: bool = False):
    q = np.zeros((n, 4), dtype=np.float32)
    q[:, 3] = 1.0
    if nan:
        q[n // 2] = np.nan
    return Vt.QuatfArray.FromNumpy(q)


def retype(layer: Sdf.Layer, attr_path: str, type_name, value) -> None:
    """Re-author an attribute with another type, keeping its name and variability."""
    p = Sdf.Path(attr_path)
    prim = layer.GetPrimAtPath(p.GetPrimPath())
    old = prim.properties[p.name]
    variability = old.variability
    prim.RemoveProperty(old)
    spec = Sdf.AttributeSpec(prim, p.name, type_name, variability)
    if value is not None:
        spec.default = value


def dump_map(path: Path) -> Path:
    from usdgaze.gaze.defaults import default_definition
    from usdgaze.usd.schema import dump_map as dump

    dump(default_definition(), path)
    return path


def map_edit(d: Path, attr: str, value, type_name=None) -> list[str]:
    """An apply with a dumped map whose ``attr`` is set to ``value`` (optionally re-typed)."""
    path = dump_map(d / "map.usda")
    layer = Sdf.Layer.FindOrOpen(str(path))
    layer.Reload(force=True)
    full = f"/GazeMap.{attr}"
    if type_name is not None:
        retype(layer, full, type_name, value)
    else:
        spec = layer.GetAttributeAtPath(full)
        spec.default = value(spec.default) if callable(value) else value
    layer.Save()
    return apply_argv(d, rig(d).path, "--map", str(path))


def manifest(d: Path, body: str, *extra: str, name: str = "manifest.toml") -> list[str]:
    """A batch run of a manifest written to ``d/name`` (an input rig at ``d/in.usda``)."""
    rig(d)
    (d / name).write_text(body)
    return ["batch", str(d / name), *extra]


JOB = 'input = "in.usda"\nout = "gaze.usdc"\nshifts = ["0.5s:30:0"]\n'


def sheet(d: Path, rows: str = "a.c3d,0,0\nb.c3d,30,0\n") -> Path:
    """A CSV trial sheet whose trial files exist (the commands fail before reading them)."""
    for line in rows.splitlines():
        (d / line.split(",")[0]).write_bytes(b"trial")
    path = d / "sheet.csv"
    path.write_text("file,yaw,pitch\n" + rows)
    return path


# -- running -------------------------------------------------------------------------------------

def snapshot(d: Path) -> dict[str, tuple]:
    """Every entry under ``d``: bytes hash (or link target, or 'dir') and mode."""
    out = {}
    for p in sorted(d.rglob("*")):
        st = p.lstat()
        if p.is_symlink():
            kind = ("link", os.readlink(p))
        elif p.is_dir():
            kind = ("dir",)
        elif not stat.S_ISREG(st.st_mode):  # a named pipe: reading it would wait for a writer
            kind = ("special", stat.S_IFMT(st.st_mode))
        else:
            kind = ("file", measure.sha256(p))
        out[str(p.relative_to(d))] = (*kind, st.st_mode & 0o7777)
    return out


def run_inprocess(argv: list[str], cwd: Path) -> tuple[int, str, str]:
    """Run the console entry point in this process; stdout and stderr as text (USD's C++ output too)."""
    from usdgaze.console.main import main

    out, err = io.StringIO(), io.StringIO()
    with tempfile.TemporaryFile() as native:
        saved = os.dup(2)
        old = os.getcwd()
        os.dup2(native.fileno(), 2)
        os.chdir(cwd)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(argv)  # ``batch`` is a usdgaze command like the others
        finally:
            os.chdir(old)
            os.dup2(saved, 2)
            os.close(saved)
        native.seek(0)
        text = native.read().decode(errors="replace")
    return code, out.getvalue(), err.getvalue() + text


def run_subprocess(argv: list[str], cwd: Path) -> tuple[int, str, str]:
    cmd = [*CLI, *argv]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, timeout=300)
    return p.returncode, p.stdout, p.stderr


# -- mounts (root only; elsewhere the callers inject the fault) ------------------------------------

def can_mount() -> bool:
    if os.geteuid() != 0 or not shutil.which("mount"):
        return False
    probe = Path(tempfile.mkdtemp(prefix="usdgaze-mount-probe-"))
    try:
        ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(probe)],
                            capture_output=True).returncode == 0
        if ok:
            subprocess.run(["umount", str(probe)], capture_output=True)
        return ok
    finally:
        probe.rmdir()


MOUNTS: list[Path] = []
_PRIVATE: list[bool] = []


def _private_mount_namespace() -> None:
    """Move this test process into its own mount namespace (once), so that its small tmpfs mounts
    vanish with it even if it is killed, and no other process on the machine sees them."""
    if _PRIVATE:
        return
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    ok = libc.unshare(0x00020000) == 0  # CLONE_NEWNS
    if ok:  # MS_REC | MS_PRIVATE: nothing mounted here propagates back to the machine's namespace
        ok = libc.mount(b"none", b"/", None, 16384 | 262144, None) == 0
    _PRIVATE.append(ok)


def fill(folder: Path) -> None:
    """Leave no space on ``folder``'s file system (a small tmpfs)."""
    with contextlib.suppress(OSError), open(folder / "filler", "wb") as f:
        while True:
            f.write(b"\0" * 4096)
            f.flush()


def tmpfs(path: Path, size: str = "16k", read_only: bool = False) -> Path:
    """A small tmpfs at ``path`` (unmounted at the end of the session)."""
    _private_mount_namespace()
    path.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size},mode=0755", "tmpfs", str(path)], check=True)
    MOUNTS.append(path)
    if read_only:
        subprocess.run(["mount", "-o", "remount,ro", str(path)], check=True)
    return path


def unmount_all() -> None:
    for path in reversed(MOUNTS):
        subprocess.run(["umount", "-l", str(path)], capture_output=True)
    MOUNTS.clear()
