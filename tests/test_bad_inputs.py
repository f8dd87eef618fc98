"""Bad inputs: exit code 2, exactly one line on stderr naming what is wrong, nothing half-written.

The catalogue lives in docs/bad-inputs.md (one table row per case: id, input, message); the
builders are here and in tests/bad_cases_*.py (``b_<id>``), every row has one and every builder a row.
A row's message is a pattern: ``{dir}`` stands for the case's folder, ``…`` for any text.

How the commands run, honestly: spawning ~220 Python processes that each import pxr costs minutes
on two cores, so most cases call the console entry point (``usdgaze.console.main.main``, or
``pipeline/batch.py``'s ``main``) inside this process, with stdout, stderr and file descriptor 2
(USD's C++ diagnostics) captured. The ``SUBPROCESS`` subset, at least one case of each class, runs
as a real ``python -m usdgaze`` / ``pipeline/batch.py`` process in parallel with those. After each
case the whole case folder (bytes, modes, symlinks) must be as it was before the command ran.

Also here: an ``apply`` killed in the middle of writing leaves no file at ``--out`` (and an older
output there untouched); tests/test_files.py has the real SIGTERM/SIGKILL tests.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import subprocess
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from pxr import Sdf, Vt

from . import (bad_cases_batch, bad_cases_files, bad_cases_look, bad_cases_stage, bad_cases_sweep, bad_cases_sweep2,
               bad_cases_sweep3, bad_cases_sweep4, bad_cases_values, measure)
from .bad_common import (apply_argv, dump_map, edited, quats, remove, rig, run_inprocess, run_subprocess, set_sample,
                         snapshot, unmount_all)

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "bad-inputs.md"
CROWD = ROOT / "sample_stages" / "shared_map" / "crowd.usda"
CLI = [sys.executable, "-m", "usdgaze"]
SHIFT = ["--shift", "0.5s:30:0"]


_rig = rig
_apply = apply_argv
_edited = edited
_remove = remove
_set_sample = set_sample
_quats = quats


# -- builders: id -> (case dir) -> argv -----------------------------------------------------------

def b_missing_input(d):
    return _apply(d, d / "nothere.usda")


def b_text_garbage(d):
    (d / "in.usda").write_text("this is not\na USD layer {\n")
    return _apply(d, d / "in.usda")


def b_zero_bytes_usda(d):
    (d / "in.usda").write_bytes(b"")
    return _apply(d, d / "in.usda")


def b_zero_bytes_usdc(d):
    (d / "in.usdc").write_bytes(b"")
    return _apply(d, d / "in.usdc")


def b_not_a_usd_extension(d):
    rig = _rig(d)
    txt = d / "in.txt"
    txt.write_bytes(rig.path.read_bytes())
    rig.path.unlink()
    return _apply(d, txt)


def b_input_is_a_folder(d):
    (d / "in.usda").mkdir()
    return _apply(d, d / "in.usda")


def b_no_skelroot(d):
    src = _edited(d, lambda layer, rig: setattr(layer.GetPrimAtPath(rig.skel_root), "typeName", "Xform"))
    return _apply(d, src)


def b_several_skelroots(d):
    def two(layer, rig):
        Sdf.CopySpec(layer, rig.skel_root, layer, "/Character2")
        rel = layer.GetRelationshipAtPath("/Character2/Skel.skel:animationSource")
        rel.targetPathList.explicitItems = [Sdf.Path("/Character2/Anim")]
    return _apply(d, _edited(d, two))


def b_skel_root_missing(d):
    return _apply(d, _rig(d).path, "--skel-root", "/Nobody")


def b_skel_root_not_a_skelroot(d):
    return _apply(d, _rig(d).path, "--skel-root", "/Character/Skel")


def b_skel_root_not_a_path(d):
    return _apply(d, _rig(d).path, "--skel-root", "Character")


def b_skel_root_ill_formed(d):
    return _apply(d, _rig(d).path, "--skel-root", "/Character/")


def b_skelroot_without_skeleton(d):
    return _apply(d, _edited(d, lambda layer, rig: _remove(layer, rig.skeleton)))


def b_skeleton_without_animation_source(d):
    def unbound_without_range(layer, rig):
        _remove(layer, rig.skeleton + ".skel:animationSource")
        layer.ClearStartTimeCode()
        layer.ClearEndTimeCode()
    return _apply(d, _edited(d, unbound_without_range))


def b_animation_source_not_an_animation(d):
    def retarget(layer, rig):
        layer.GetRelationshipAtPath(rig.skeleton + ".skel:animationSource").targetPathList.explicitItems = [
            Sdf.Path(rig.skel_root)]
    return _apply(d, _edited(d, retarget))


def b_two_skeletons_one_animation(d):
    return _apply(d, _edited(d, lambda layer, rig: Sdf.CopySpec(layer, rig.skeleton, layer, rig.skel_root + "/Skel2")))


def _still(layer, rig):
    """The animation's first pose as defaults: no time samples left."""
    for name in ("rotations", "translations", "scales"):
        spec = layer.GetAttributeAtPath(f"{rig.animation}.{name}")
        first = layer.QueryTimeSample(spec.path, float(rig.times[0]))
        for t in rig.times:
            layer.EraseTimeSample(spec.path, float(t))
        spec.default = first


def b_animation_without_time_samples(d):
    def still_without_range(layer, rig):
        _still(layer, rig)
        layer.ClearStartTimeCode()
        layer.ClearEndTimeCode()
    return _apply(d, _edited(d, still_without_range))


def b_still_pose_range_too_long(d):
    def still_for_ever(layer, rig):
        _still(layer, rig)
        layer.timeCodesPerSecond = layer.framesPerSecond = 24.0
        layer.startTimeCode, layer.endTimeCode = 0.0, 1e8
    return _apply(d, _edited(d, still_for_ever))


def b_rotations_length_not_joints(d):
    return _apply(d, _edited(d, lambda layer, rig: _set_sample(layer, rig, "rotations", _quats(len(rig.anim_joints) - 3))))


def b_scales_missing(d):
    return _apply(d, _edited(d, lambda layer, rig: _remove(layer, rig.animation + ".scales")))


def b_nan_rotations(d):
    return _apply(d, _edited(d, lambda layer, rig: _set_sample(layer, rig, "rotations", _quats(len(rig.anim_joints), nan=True))))


def b_zero_quaternions(d):
    def zero(layer, rig):
        _set_sample(layer, rig, "rotations", Vt.QuatfArray.FromNumpy(np.zeros((len(rig.anim_joints), 4), np.float32)))
    return _apply(d, _edited(d, zero))


def b_animation_names_no_joint_of_the_skeleton(d):
    def rename(layer, rig):
        spec = layer.GetAttributeAtPath(rig.animation + ".joints")
        spec.default = Vt.TokenArray([f"other_{k}" for k in range(len(spec.default))])
    return _apply(d, _edited(d, rename))


def b_rest_transforms_count(d):
    def short(layer, rig):
        spec = layer.GetAttributeAtPath(rig.skeleton + ".restTransforms")
        spec.default = Vt.Matrix4dArray(list(spec.default)[:-2])
    return _apply(d, _edited(d, short))


def b_no_rest_pose(d):
    def bare(layer, rig):
        _remove(layer, rig.skeleton + ".restTransforms")
        _remove(layer, rig.skeleton + ".bindTransforms")
    return _apply(d, _edited(d, bare))


def b_skeleton_without_joints(d):
    def empty(layer, rig):
        layer.GetAttributeAtPath(rig.skeleton + ".joints").default = Vt.TokenArray([])
    return _apply(d, _edited(d, empty))


def b_joints_out_of_order(d):
    def swap(layer, rig):
        spec = layer.GetAttributeAtPath(rig.skeleton + ".joints")
        joints = list(spec.default)
        joints[0], joints[1] = joints[1], joints[0]
        spec.default = Vt.TokenArray(joints)
    return _apply(d, _edited(d, swap))


def b_joint_token_not_a_path(d):
    def colon(layer, rig):
        for prim in (rig.skeleton, rig.animation):
            spec = layer.GetAttributeAtPath(prim + ".joints")
            spec.default = Vt.TokenArray([j.replace("mixamorig_", "mixamorig:") for j in spec.default])
    return _apply(d, _edited(d, colon))


def b_chain_not_found(d):
    return _apply(d, _rig(d, convention="generic").path)


def b_only_one_eye(d):
    return _apply(d, _rig(d, eyes="left").path)


def b_bind_absent_joint(d):
    return _apply(d, _rig(d).path, "--bind", "head=Skull")


def b_bind_malformed(d):
    return _apply(d, _rig(d).path, "--bind", "head")


def b_bind_unknown_role(d):
    return _apply(d, _rig(d).path, "--bind", "skull=mixamorig_Head")


def b_forward_malformed(d):
    return _apply(d, _rig(d).path, "--forward", "0,1")


def b_input_map_malformed(d):
    def api_only(layer, rig):
        op = Sdf.TokenListOp()
        op.prependedItems = ["GazeMapAPI"]
        layer.GetPrimAtPath(rig.skel_root).SetInfo("apiSchemas", op)
    return _apply(d, _edited(d, api_only))


def b_shift_missing_field(d):
    return _apply(d, _rig(d).path, shifts=["--shift", "0.5s:30"])


def b_shift_text(d):
    return _apply(d, _rig(d).path, shifts=["--shift", "soon:30:0"])


def b_shift_pitch_out_of_range(d):
    return _apply(d, _rig(d).path, shifts=["--shift", "0.5s:30:120"])


def b_shift_not_finite(d):
    return _apply(d, _rig(d).path, shifts=["--shift", "1e999:30:0"])


def b_shift_yaw_out_of_range(d):
    return _apply(d, _rig(d).path, shifts=["--shift", "0.5s:100000:0"])


def b_no_shift(d):
    return _apply(d, _rig(d).path, shifts=[])


def b_two_shifts_same_time(d):
    # 30 time codes at 60 time codes per second is 0.5 s.
    return _apply(d, _rig(d).path, shifts=["--shift", "0.5s:30:0", "--shift", "30:-20:5"])


def b_out_bad_extension(d):
    return _apply(d, _rig(d).path, out="gaze.txt")


def b_out_missing_folder(d):
    return _apply(d, _rig(d).path, out="nofolder/gaze.usdc")


def b_out_is_input(d):
    return _apply(d, _rig(d).path, out="in.usda")


def b_preview_is_input(d):
    return _apply(d, _rig(d).path, "--preview", str(d / "in.usda"))


def b_preview_bad_extension(d):
    return _apply(d, _rig(d).path, "--preview", str(d / "preview.txt"))


def b_map_file_missing(d):
    return _apply(d, _rig(d).path, "--map", str(d / "nomap.usda"))


def b_map_prim_missing(d):
    dump_map(d / "map.usda")
    return _apply(d, _rig(d).path, "--map", f"{d / 'map.usda'}:/Elsewhere")


def b_map_prim_without_map(d):
    rig = _rig(d)
    return _apply(d, rig.path, "--map", f"{rig.path}:{rig.skel_root}")


def b_map_malformed(d):
    dump_map(d / "map.usda")
    layer = Sdf.Layer.FindOrOpen(str(d / "map.usda"))
    spec = layer.GetAttributeAtPath("/GazeMap.gaze:examples:duration")
    values = list(spec.default)
    values[2] = -1.0
    spec.default = Vt.FloatArray(values)
    layer.Save()
    return _apply(d, _rig(d).path, "--map", str(d / "map.usda"))


def b_map_zero_duration(d):
    """A 0 s example (accepted: the shift it gave was the head jumping 10 deg in one frame)."""
    dump_map(d / "map.usda")
    layer = Sdf.Layer.FindOrOpen(str(d / "map.usda"))
    spec = layer.GetAttributeAtPath("/GazeMap.gaze:examples:duration")
    spec.default = Vt.FloatArray([0.0] * len(spec.default))
    layer.Save()
    return _apply(d, _rig(d).path, "--map", str(d / "map.usda"))


def b_map_file_garbage(d):
    (d / "map.usda").write_text("no map here\n")
    return _apply(d, _rig(d).path, "--map", str(d / "map.usda"))


def b_map_file_several_maps(d):
    return _apply(d, _rig(d).path, "--map", str(CROWD))


def b_sublayer_into_and_preview(d):
    return _apply(d, _rig(d).path, "--sublayer-into", str(d / "shot.usda"), "--preview", str(d / "preview.usda"))


def b_sublayer_into_the_input(d):
    return _apply(d, _rig(d).path, "--sublayer-into", str(d / "in.usda"))


def b_sublayer_into_missing_file(d):
    return _apply(d, _rig(d).path, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_garbage(d):
    (d / "shot.usda").write_text("not a layer\n")
    return _apply(d, _rig(d).path, "--sublayer-into", str(d / "shot.usda"))


def b_fixation_zero(d):
    return _apply(d, _rig(d).path, "--fixation", "0")


def b_fixation_not_a_number(d):
    return _apply(d, _rig(d).path, "--fixation", "far")


def b_unknown_option(d):
    return _apply(d, _rig(d).path, "--gaze-at", "camera")


def b_inspect_garbage(d):
    (d / "in.usda").write_text("garbage\n")
    return ["inspect", str(d / "in.usda")]


def b_dump_map_bad_extension(d):
    return ["dump-map", str(d / "map.json")]


def _attend(d: Path, src: Path, *extra: str) -> list[str]:
    return ["attend", str(src), "--out", str(d / "gaze.usdc"), *extra]


def _gaze_object(layer: Sdf.Layer, path: str, type_name: str) -> None:
    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierDef
    spec.typeName = type_name
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))


def b_attend_no_objects(d):
    return _attend(d, _rig(d).path)


def b_attend_object_without_transform(d):
    return _attend(d, _edited(d, lambda layer, rig: _gaze_object(layer, "/Marker", "Scope")))


def b_attend_negative_alpha(d):
    return _attend(d, _edited(d, lambda layer, rig: _gaze_object(layer, "/Ball", "Sphere")), "--alpha", "-0.1")


def b_attend_window_too_short(d):
    return _attend(d, _edited(d, lambda layer, rig: _gaze_object(layer, "/Ball", "Sphere")), "--window", "0.03")


def b_attend_range_outside_the_animation(d):
    def author(layer, rig):
        _gaze_object(layer, "/Ball", "Sphere")
        layer.startTimeCode, layer.endTimeCode = 500.0, 600.0
    return _attend(d, _edited(d, author))


def _ball(d: Path) -> Path:
    return _edited(d, lambda layer, rig: _gaze_object(layer, "/Ball", "Sphere"))


def b_attend_physics_out_symlink_to_input(d):
    src = _ball(d)
    (d / "gaze.usdc").symlink_to(src)
    return _attend(d, src, "--physics")


def b_attend_physics_out_read_only_folder(d):
    bad_cases_files._read_only_folder(d)  # refused before the (long) simulation starts
    return ["attend", str(_ball(d)), "--physics", "--out", str(d / "ro" / "gaze.usdc")]


def b_attend_physics_out_is_another_shot(d):
    src = _ball(d)
    bad_cases_files.other_shot(d, "other.usdc")  # refused before the (long) simulation starts
    return ["attend", str(src), "--physics", "--out", str(d / "other.usdc")]


def b_physics_model_quadruped(d):
    return ["physics-model", str(_rig(d, body="quadruped").path), "--out", str(d / "body.xml")]


BUILDERS = {name[2:].replace("_", "-"): fn for module in (globals(), vars(bad_cases_files), vars(bad_cases_stage),
                                                           vars(bad_cases_values), vars(bad_cases_look),
                                                           vars(bad_cases_sweep), vars(bad_cases_sweep2),
                                                           vars(bad_cases_sweep3), vars(bad_cases_sweep4),
                                                           vars(bad_cases_batch))
            for name, fn in dict(module).items() if name.startswith("b_")}
# Run through a real ``python -m usdgaze`` (or ``pipeline/batch.py``) process: one or more of each class.
SUBPROCESS = {
    "text-garbage", "out-hard-link-of-input", "out-is-a-referenced-layer", "preview-read-only-folder", "out-disk-full",
    "sublayer-into-read-only-file", "rotations-authored-as-float3", "character-inside-an-instance",
    "fixation-negative", "batch-fixation-negative", "build-map-report-is-the-sheet", "unknown-option",
}


# -- the catalogue --------------------------------------------------------------------------------

def catalogue() -> dict[str, tuple[str, str]]:
    """id -> (input, message pattern), from the table in docs/bad-inputs.md."""
    rows = {}
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if line.startswith("|") else []
        if len(cells) == 3 and cells[0].startswith("`") and cells[0] != "`id`":
            rows[cells[0].strip("`")] = (cells[1], cells[2].strip("`"))
    return rows


def pattern(message: str, d: Path, prefix: str = "usdgaze") -> re.Pattern:
    """A doc message -> regex over the whole stderr line (``{dir}``: the case folder, ``…``: any text)."""
    parts = re.split(r"(\{dir\}|…)", message)
    body = "".join(re.escape(str(d)) if p == "{dir}" else ".*?" if p == "…" else re.escape(p) for p in parts)
    return re.compile(re.escape(f"{prefix}: error: ") + body + "$")


@contextlib.contextmanager
def _injected(d: Path):
    """Where this machine cannot mount a small or read-only tmpfs, fail writes into a marked folder
    with the OS error a real one gives (ENOSPC while writing, EROFS when creating the temporary)."""
    from usdgaze.files import transaction

    marked = {m.parent: m.name for m in d.rglob(".inject-*")}
    if not marked:
        yield
        return
    real_stage, real_mkdir = transaction.Outputs.stage_with, Path.mkdir

    def stage_with(self, path, write):
        if marked.get(Path(os.path.realpath(path)).parent) == ".inject-enospc":
            def failing(temp, write=write):
                write(temp)
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real_stage(self, path, failing)
        return real_stage(self, path, write)

    def mkdir(self, *args, **kwargs):
        if marked.get(self.parent) == ".inject-erofs":
            raise OSError(errno.EROFS, os.strerror(errno.EROFS))
        return real_mkdir(self, *args, **kwargs)

    transaction.Outputs.stage_with, Path.mkdir = stage_with, mkdir
    try:
        yield
    finally:
        transaction.Outputs.stage_with, Path.mkdir = real_stage, real_mkdir


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Build every case; run a few in subprocesses (in parallel) and the rest in this process."""
    cases = {}
    try:
        for case_id, build in BUILDERS.items():
            d = tmp_path_factory.mktemp(case_id)
            argv = build(d)
            cases[case_id] = (d, argv, snapshot(d))
        out = {}
        with ThreadPoolExecutor(max_workers=2) as pool:
            futures = {cid: pool.submit(run_subprocess, cases[cid][1], cases[cid][0]) for cid in SUBPROCESS}
            for case_id, (d, argv, before) in cases.items():
                if case_id not in SUBPROCESS:
                    with _injected(d):
                        out[case_id] = (d, argv, before, run_inprocess(argv, d), snapshot(d))
            for case_id, f in futures.items():
                d, argv, before = cases[case_id]
                out[case_id] = (d, argv, before, f.result(), snapshot(d))
        yield out
    finally:
        unmount_all()


def test_catalogue_and_builders_match():
    rows = catalogue()
    assert rows, f"no table rows in {DOC}"
    assert sorted(rows) == sorted(BUILDERS), (sorted(set(rows) ^ set(BUILDERS)))
    assert len(rows) >= 150


@pytest.mark.parametrize("case_id", sorted(catalogue()))
def test_bad_input(results, case_id):
    d, argv, before, (code, stdout, stderr), after = results[case_id]
    _, message = catalogue()[case_id]
    lines = stderr.splitlines()
    assert code == 2, (code, stderr)
    assert "Traceback" not in stderr
    assert len(lines) == 1, stderr
    prefix = "usdgaze"
    assert pattern(message, d, prefix).match(lines[0]), (lines[0], message)
    if argv[0] != "batch":
        assert stdout == ""
    # Nothing written, nothing changed: no output, no temporary, every file's bytes and mode as they were.
    assert after == before


# -- atomic write -------------------------------------------------------------------------------

_DRIVER = textwrap.dedent("""
    import os, sys
    import usdgaze
    from pxr import Sdf

    def dying_export(self, path, *args, **kwargs):
        with open(path, "wb") as f:       # a partial file at the temp path ...
            f.write(b"PXR-USDC" + b"\\0" * 64)
            f.flush()
        os._exit(9)                       # ... and the process dies mid-write

    Sdf.Layer.Export = dying_export
    from usdgaze.console.main import main
    sys.exit(main(sys.argv[1:]))
""")


@pytest.mark.parametrize("previous", [False, True], ids=["fresh", "over-previous-output"])
def test_killed_mid_write_leaves_no_partial_output(tmp_path, previous):
    rig = _rig(tmp_path)
    out = tmp_path / "gaze.usdc"
    if previous:
        ok = subprocess.run([*CLI, *_apply(tmp_path, rig.path)], capture_output=True, text=True)
        assert ok.returncode == 0, ok.stderr
        before = measure.sha256(out)
    src_hash = measure.sha256(rig.path)
    driver = tmp_path / "driver.py"
    driver.write_text(_DRIVER)
    p = subprocess.run([sys.executable, str(driver), *_apply(tmp_path, rig.path, shifts=["--shift", "0.5s:-60:10"])],
                       capture_output=True, text=True)
    assert p.returncode == 9, (p.returncode, p.stderr)
    if previous:
        assert measure.sha256(out) == before
        assert Sdf.Layer.OpenAsAnonymous(str(out)) is not None
    else:
        assert not out.exists()
    assert measure.sha256(rig.path) == src_hash
    # The partial bytes went to a recognizable temporary folder beside the output, never to the output path.
    leftovers = [p for p in tmp_path.iterdir() if p.name.startswith(".usdgaze-tmp-")]
    assert len(leftovers) == 1 and [p.name for p in leftovers[0].iterdir()] == ["gaze.usdc"]
