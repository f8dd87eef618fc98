"""Farm job files for a manifest: each scheduler runs one task per shot, and each task calls
``usdgaze batch MANIFEST --task-index I``.

* Deadline: a job-info and a plugin-info file for a CommandLine job (frames 0..N-1, chunk 1), submitted
  with ``deadlinecommand job_info.job plugin_info.job``;
* OpenCue: a job spec (cjsl XML, one layer with range 0-(N-1), chunk 1), submitted with
  ``opencue.api.launchSpec(open(SPEC).read())`` or cuesubmit;
* SLURM: an array-job script, submitted with ``sbatch usdgaze.sbatch`` (over 1001 shots: several
  arrays, ``bash submit.sh``).
"""

from __future__ import annotations

import getpass
import os
import re
import shlex
import shutil
import sys
from pathlib import Path
from typing import NamedTuple, TYPE_CHECKING, Sequence
from xml.sax.saxutils import escape

from usdgaze.errors import UsdGazeError

if TYPE_CHECKING:
    from usdgaze.batch.manifest import Shot

FORMATS = ("deadline", "opencue", "slurm")
_FARMS = {"deadline": "Deadline", "opencue": "OpenCue", "slurm": "SLURM"}


def usdgaze_command() -> list[str]:
    """The argv that runs this usdgaze: its console script when installed, else ``python -m usdgaze``."""
    script = Path(sys.executable).with_name("usdgaze")
    found = str(script) if script.is_file() else shutil.which("usdgaze")
    return [os.path.abspath(found)] if found else [os.path.abspath(sys.executable), "-m", "usdgaze"]


def _token(text: str) -> str:
    """A scheduler-safe name (letters, digits, _ . -)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "usdgaze"


class Request(NamedTuple):
    """What one farm task asks for: an array job makes one request for all its tasks, so the biggest
    shot sets it (:func:`task_request`)."""

    cores: int = 1
    time_limit: str = "00:30:00"  # SLURM's --time


def task_request(shots: Sequence["Shot"]) -> Request:
    """The most ``threads`` any shot sets (1 when none does), and half an hour a task, or four hours
    where a shot simulates physics: the whole 8.3 s stones sample took 33 CPU minutes, and a farm
    kills a task at its limit (30 minutes were asked for every shot)."""
    cores = max((int(s.values.get("threads", 1)) for s in shots), default=1)
    physics = any(s.values.get("command") == "attend" and s.values.get("physics") for s in shots)
    return Request(cores, "04:00:00" if physics else "00:30:00")


def _deadline(manifest: Path, count: int, name: str, extra: Sequence[str], ask: Request) -> dict[str, str]:
    exe, *pre = usdgaze_command()
    args = " ".join([*pre, "batch", f"<QUOTE>{manifest}<QUOTE>", *extra, "--task-index", "<STARTFRAME>"])
    job_info = "\n".join([
        "Plugin=CommandLine",
        f"Name={name}",
        f"Comment=usdgaze batch {manifest.name}: one task per shot ({_count(count)}), "
        f"each up to {_count(ask.cores, 'thread')}",
        f"Frames=0-{count - 1}",
        "ChunkSize=1",
        # Deadline has no per-task core request: one task at a time on a worker leaves the shot that
        # runs the most threads (Comment) every core of the machine.
        "ConcurrentTasks=1",
        "",
    ])
    plugin_info = "\n".join([
        f"Executable={exe}",
        f"Arguments={args}",
        f"StartupDirectory={manifest.parent}",
        "ShellExecute=False",
        "",
    ])
    submit = "#!/bin/sh\n# Submit the usdgaze job to Deadline: sh submit.sh\nexec deadlinecommand \"$(dirname \"$0\")/job_info.job\" \"$(dirname \"$0\")/plugin_info.job\"\n"
    return {"job_info.job": job_info, "plugin_info.job": plugin_info, "submit.sh": submit}


def _opencue(manifest: Path, count: int, name: str, extra: Sequence[str], ask: Request) -> dict[str, str]:
    cmd = " ".join(shlex.quote(a) for a in [*usdgaze_command(), "batch", str(manifest), *extra, "--task-index"]) + " #IFRAME#"
    user = _token(os.environ.get("USER") or getpass.getuser())
    spec = f"""<?xml version="1.0"?>
<!DOCTYPE spec PUBLIC "SPI Cue Specification Language" "http://localhost:8080/spcue/dtd/cjsl-1.14.dtd">
<spec>
  <show>{escape(_token(os.environ.get("SHOW", "usdgaze")))}</show>
  <shot>{escape(_token(manifest.stem))}</shot>
  <user>{escape(user)}</user>
  <job name="{escape(name)}">
    <paused>False</paused>
    <maxretries>1</maxretries>
    <layers>
      <layer name="gaze" type="Render">
        <cmd>{escape(cmd)}</cmd>
        <range>0-{count - 1}</range>
        <chunk>1</chunk>
        <!-- one request for every frame (shot): the most threads any shot of the manifest sets -->
        <cores>{ask.cores}</cores>
        <services>
          <service>shell</service>
        </services>
      </layer>
    </layers>
  </job>
</spec>
"""
    return {f"{name}.xml": spec}


SLURM_ARRAY_MAX = 1001
"""SLURM's default ``MaxArraySize``: an array's indices run 0..1000 at most, and sbatch refuses a larger
``--array`` ("Invalid job array specification"), so more shots go in several arrays (``submit.sh``)."""


def _slurm(manifest: Path, count: int, name: str, extra: Sequence[str], ask: Request) -> dict[str, str]:
    cmd = " ".join(shlex.quote(a) for a in [*usdgaze_command(), "batch", str(manifest), *extra, "--task-index"])
    split = count > SLURM_ARRAY_MAX
    submit = "bash submit.sh (arrays of at most 1001 tasks)" if split else "sbatch usdgaze.sbatch"
    task = '"$((SLURM_ARRAY_TASK_ID + ${1:-0}))"' if split else '"$SLURM_ARRAY_TASK_ID"'
    script = f"""#!/usr/bin/env bash
# usdgaze batch {manifest.name}: one array task per shot ({_count(count)}). Submit: {submit}
# --cpus-per-task: one request for every array task, so the most threads any shot sets ({ask.cores});
# --time: half an hour a shot, four hours where one simulates physics (edit both to your shots).
#SBATCH --job-name={name}
#SBATCH --array=0-{min(count, SLURM_ARRAY_MAX) - 1}
#SBATCH --cpus-per-task={ask.cores}
#SBATCH --mem=2G
#SBATCH --time={ask.time_limit}
#SBATCH --output=usdgaze_%A_%a.log
# Exit codes: 0 done or skipped, 2 bad input (do not retry), 1 internal error (worth a retry).
"""
    if split:
        script += "# The first argument: the shot of array task 0 (submit.sh passes each array's).\n"
    # submit.sh every time: one left by an emit of over 1001 shots submitted that many tasks to the
    # script of a manifest cut down since (re-emitted into the same folder).
    return {"usdgaze.sbatch": script + f"exec {cmd} {task}\n", "submit.sh": _slurm_submit(count)}


def _slurm_submit(count: int) -> str:
    """A script submitting ``count`` shots: the one array of usdgaze.sbatch, or over
    :data:`SLURM_ARRAY_MAX` shots arrays of at most that many tasks, each told the shot its task 0 runs."""
    if count <= SLURM_ARRAY_MAX:
        return f"""#!/usr/bin/env bash
# {_count(count)}: one array (usdgaze.sbatch's --array). Submit: bash submit.sh
set -eu
here=$(cd "$(dirname "$0")" && pwd)
sbatch "$here/usdgaze.sbatch"
"""
    return f"""#!/usr/bin/env bash
# {_count(count)}, more than SLURM's default MaxArraySize ({SLURM_ARRAY_MAX}) lets one array hold: one
# array per {SLURM_ARRAY_MAX} shots. Where the cluster's MaxArraySize differs, set USDGAZE_ARRAY_SIZE to it.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
size=${{USDGAZE_ARRAY_SIZE:-{SLURM_ARRAY_MAX}}}
for ((first = 0; first < {count}; first += size)); do
  n=$(( {count} - first < size ? {count} - first : size ))
  sbatch --array=0-$((n - 1)) "$here/usdgaze.sbatch" "$first"
done
"""


def _count(n: int, what: str = "shot") -> str:
    return f"{n} {what}{'s' * (n != 1)}"


_EMITTERS = {"deadline": _deadline, "opencue": _opencue, "slurm": _slurm}

# The files a shot reads before it runs, by manifest key (the map key may end in ``:/PRIM``).
_READ_KEYS = ("input", "map", "sublayer_into")


def check_inputs(manifest: str | os.PathLike, shots: Sequence["Shot"]) -> None:
    """Every shot's input, map and sublayer target is a file: refused here, not by each farm task.

    Running the batch refuses such a shot when it starts; on a farm that is N tasks queued, started
    and failed one by one, so emitting refuses the first missing file up front instead."""
    for shot in shots:
        for key in _READ_KEYS:
            if key not in shot.values:
                continue
            file = shot.values[key].partition(":/")[0] if key == "map" else shot.values[key]
            if not os.path.isfile(file):
                what = "no such file" if not os.path.lexists(file) else "not a file"
                raise UsdGazeError(f"{manifest}: {shot.label}: {key} = {file}: {what}; "
                                   "its farm task would fail, so no job files were written")


def check_summaries(manifest: str | os.PathLike, summary: Path) -> None:
    """Every emitted task writes its summary beside the manifest (``summary``: task 0's), and refuses to
    run its shot where it cannot: a manifest in a read-only folder was emitted without a word, and
    every farm task then failed (exit 2). Probed as a task claims it (its temporary folder made and
    removed), so a read-only mount, a full quota or a folder at that name are found here."""
    from usdgaze.files.transaction import Outputs

    try:
        with Outputs() as tx:
            tx.claim(summary, "--summary")  # nothing staged: the commit renames nothing
    except UsdGazeError as exc:
        raise UsdGazeError(f"{manifest}: every farm task writes its summary beside the manifest, and {exc}; "
                           "no job files were written") from None


def _check_carried(kind: str, manifest: Path) -> None:
    """One line where the job files cannot carry the manifest's path or this usdgaze's command as they are:
    a control character (a line break in a folder's name ended SLURM's comment line, so the rest of the
    name ran as a command and sbatch ignored the #SBATCH lines after it; it split Deadline's key=value
    lines; XML 1.0 has no other control characters), or for Deadline a double quote, which ends the
    ``<QUOTE>`` around the manifest in its arguments."""
    for what, text in (("the manifest's path", str(manifest)), ("this usdgaze's command", " ".join(usdgaze_command()))):
        bad = next((c for c in text if ord(c) < 32 or ord(c) == 127), None)
        if bad is not None:
            raise UsdGazeError(f"{str(manifest)!r}: {what} holds the control character {bad!r}, which {_FARMS[kind]}'s job files "
                               "cannot carry; rename it, and no job files were written")
        if kind == "deadline" and '"' in text:
            raise UsdGazeError(f"{manifest}: {what} holds a double quote, which ends Deadline's <QUOTE> around the "
                               "manifest in the task's arguments; rename it, and no job files were written")


def jobs_digest(shots: Sequence["Shot"]) -> str:
    """A digest of the manifest's job names in order: what an emitted task checks its manifest still
    lists (``--manifest-jobs``), since it runs its shot by index."""
    import hashlib

    return hashlib.sha256("\n".join(s.name for s in shots).encode()).hexdigest()[:16]


def emit(kind: str, manifest: str | os.PathLike, count: int, folder: str | os.PathLike,
         force: bool = False, ask: Request = Request(), jobs: str | None = None) -> list[Path]:
    """Write the job files for ``count`` shots of ``manifest`` into ``folder`` (all or none); their paths.
    ``force``: every task redoes its shot (``--force``); ``ask``: what each task asks for
    (:func:`task_request`); ``jobs``: the :func:`jobs_digest` every task checks."""
    from usdgaze.files.transaction import Outputs

    if kind not in _EMITTERS:
        raise UsdGazeError(f"--emit {kind}: unknown farm (choose from {', '.join(FORMATS)})")
    # Absolute, links kept: a manifest's paths are relative to its folder as given (a symlinked
    # manifest's: the link's), and resolving the link sent every task to the real file's folder.
    manifest = Path(os.path.abspath(manifest))
    folder = Path(folder)
    _check_carried(kind, manifest)
    if folder.exists() and not folder.is_dir():
        raise UsdGazeError(f"{folder}: --emit needs a folder, and this is a file")
    extra = (["--force"] if force else []) + (["--manifest-jobs", jobs] if jobs else [])
    files = _EMITTERS[kind](manifest, count, _token(f"usdgaze_{manifest.stem}"), extra, ask)
    with Outputs() as tx:
        tx.read(manifest, "manifest")
        tx.make_folder(folder)
        for name, text in files.items():
            tx.claim(folder / name, "--emit")
            tx.stage_text(folder / name, text)
    return [folder / name for name in files]
