"""Catalogue builders: values (CLI, map, manifest alike), malformed manifests and sheets."""

from __future__ import annotations

from pxr import Sdf, Vt

from .bad_common import JOB, ROOT, apply_argv, manifest, map_edit, rig, sheet

T = Sdf.ValueTypeNames


def _shift(d, text):
    return apply_argv(d, rig(d).path, shifts=["--shift", text])


def b_fixation_negative(d):
    return apply_argv(d, rig(d).path, "--fixation", "-2")


def b_fixation_nan(d):
    return apply_argv(d, rig(d).path, "--fixation", "nan")


def b_fixation_inf(d):
    return apply_argv(d, rig(d).path, "--fixation", "inf")


def b_fixation_huge(d):
    return apply_argv(d, rig(d).path, "--fixation", "1e9")


def b_shift_time_huge(d):
    return _shift(d, "1e12:30:0")


def b_shift_seconds_huge(d):
    return _shift(d, "1e9s:30:0")


def b_shift_nan_yaw(d):
    return _shift(d, "0.5s:nan:0")


def b_shift_empty(d):
    return _shift(d, "")


def b_shift_four_fields(d):
    return _shift(d, "1:2:3:4")


def b_shift_yaw_exponent_out_of_range(d):
    return _shift(d, "0.5s:1e3:0")


def b_shift_pitch_exponent_not_finite(d):
    return _shift(d, "0.5s:0:1e400")


def b_map_samples_huge(d):
    return map_edit(d, "gaze:synthesis:samples", 2_000_000_000)


def b_map_neighbors_huge(d):
    return map_edit(d, "gaze:synthesis:neighbors", 100_000)


def b_map_refine_huge(d):
    return map_edit(d, "gaze:synthesis:refine", 1000)


def b_map_blend_size_zero(d):
    return map_edit(d, "gaze:synthesis:blendSize", 0)


def b_map_neck_share_two(d):
    return map_edit(d, "gaze:synthesis:neckShare", 2.0)


def b_map_seed_negative(d):
    return map_edit(d, "gaze:synthesis:seed", -1)


def b_map_samples_authored_as_float(d):
    return map_edit(d, "gaze:synthesis:samples", 5000.0, T.Float)


def b_map_yaw_out_of_range(d):
    return map_edit(d, "gaze:examples:yaw", lambda old: Vt.FloatArray([200.0] + list(old)[1:]))


def b_map_no_examples(d):
    return map_edit(d, "gaze:examples:yaw", lambda old: Vt.FloatArray([]))


def b_map_forward_nan(d):
    from pxr import Gf

    return map_edit(d, "gaze:binding:forward", Gf.Vec3f(float("nan"), 0, 1))


def b_physics_model_timestep(d):
    return ["physics-model", str(rig(d).path), "--out", str(d / "body.xml"), "--timestep", "5"]


# -- batch manifests ------------------------------------------------------------------------------

def b_batch_manifest_missing(d):
    return ["batch", str(d / "none.toml")]


def b_batch_manifest_is_a_folder(d):
    (d / "jobs.toml").mkdir()
    return ["batch", str(d / "jobs.toml")]


def b_batch_manifest_garbage(d):
    return manifest(d, "[[job\ninput = \n")


def b_batch_manifest_not_utf8(d):
    rig(d)
    (d / "manifest.toml").write_bytes(b"name = \"\xff\xfe\"\n")
    return ["batch", str(d / "manifest.toml")]


def b_batch_no_jobs(d):
    return manifest(d, "[defaults]\nfixation = 2.0\n")


def b_batch_jobs_not_tables(d):
    return manifest(d, "job = [1, 2]\n")


def b_batch_job_is_a_string(d):
    return manifest(d, 'job = "walk"\n')


def b_batch_defaults_not_a_table(d):
    return manifest(d, f'defaults = 3\n[[job]]\n{JOB}')


def b_batch_unknown_key(d):
    return manifest(d, f'[[job]]\n{JOB}colour = "red"\n')


def b_batch_missing_input(d):
    return manifest(d, '[[job]]\nout = "gaze.usdc"\nshifts = ["1:2:3"]\n')


def b_batch_look_at_malformed(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "gaze.usdc"\nlook_at = ["door"]\n')


def b_batch_shifts_a_string(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "gaze.usdc"\nshifts = "1:2:3"\n')


def b_batch_shifts_numbers(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "gaze.usdc"\nshifts = [1, 2]\n')


def b_batch_shifts_empty(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "gaze.usdc"\nshifts = []\n')


def b_batch_shift_malformed(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "gaze.usdc"\nshifts = ["soon:30:0"]\n')


def b_batch_shift_pitch_out_of_range(d):
    return manifest(d, '[[job]]\nname = "w"\ninput = "in.usda"\nout = "gaze.usdc"\nshifts = ["1:0:95"]\n')


def b_batch_fixation_negative(d):
    return manifest(d, f'[[job]]\nname = "walk"\n{JOB}fixation = -2\n')


def b_batch_fixation_a_string(d):
    return manifest(d, f'[[job]]\n{JOB}fixation = "far"\n')


def b_batch_fixation_nan(d):
    return manifest(d, f'[[job]]\n{JOB}fixation = nan\n')


def b_batch_fixation_in_defaults(d):
    return manifest(d, f'[defaults]\nfixation = 0\n[[job]]\n{JOB}')


def b_batch_fixation_a_bool(d):
    return manifest(d, f'[[job]]\n{JOB}fixation = true\n')


def b_batch_input_not_a_string(d):
    return manifest(d, '[[job]]\ninput = 3\nout = "gaze.usdc"\nshifts = ["1:2:3"]\n')


def b_batch_name_empty(d):
    return manifest(d, f'[[job]]\nname = ""\n{JOB}')


def b_batch_preview_and_sublayer_into(d):
    return manifest(d, f'[[job]]\n{JOB}preview = "p.usda"\nsublayer_into = "shot.usda"\n')


def b_batch_task_index_out_of_range(d):
    return manifest(d, f"[[job]]\n{JOB}", "--task-index", "3")


def b_batch_map_not_a_string(d):
    return manifest(d, f'[[job]]\n{JOB}map = ["a", "b"]\n')


# -- build-map sheets -----------------------------------------------------------------------------

def b_build_map_sheet_missing(d):
    return ["build-map", str(d / "none.csv"), "--out", str(d / "map.usda")]


def b_build_map_sheet_not_utf8(d):
    (d / "sheet.csv").write_bytes(b"file,yaw,pitch\n\xff\xfe,0,0\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "map.usda")]


def b_build_map_sheet_toml_garbage(d):
    (d / "sheet.toml").write_text("[[trial\n")
    return ["build-map", str(d / "sheet.toml"), "--out", str(d / "map.usda")]


def b_build_map_sheet_no_trials(d):
    (d / "sheet.csv").write_text("file,yaw,pitch\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "map.usda")]


def b_build_map_sheet_yaw_not_a_number(d):
    return ["build-map", str(sheet(d, "a.c3d,left,0\n")), "--out", str(d / "map.usda")]


def b_build_map_bad_out_extension(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.json")]


def b_build_map_rest_speed_inf(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--rest-speed", "inf"]


def b_build_map_start_speed_nan(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--start-speed", "nan"]


def b_build_map_min_trials_zero(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--min-trials", "0"]


def b_batch_unknown_key_in_defaults(d):
    return manifest(d, f'[defaults]\ncolour = "red"\n[[job]]\n{JOB}')


def b_batch_emit_with_workers(d):
    return manifest(d, f'[[job]]\n{JOB}', "--emit", "slurm", str(d / "farm"), "--workers", "2")


def b_batch_input_composes_a_later_out(d):
    (d / "wrap.usda").write_text('#usda 1.0\n(\n    subLayers = [@./out/a.usdc@, @./in.usda@]\n)\n')
    (d / "out").mkdir()
    return manifest(d, '[defaults]\nshifts = ["0.5s:30:0"]\n[[job]]\nname = "a"\ninput = "in.usda"\nout = "out/a.usdc"\n'
                       '[[job]]\nname = "b"\ninput = "wrap.usda"\nout = "out/b.usdc"\n')


def b_batch_look_at_empty(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "gaze.usdc"\nlook_at = []\n')


def b_build_map_trial_missing(d):
    # The example sheet's layout: trial files in trials/ beside the sheet, spelled relative to it.
    (d / "trials").mkdir()
    (d / "sheet.csv").write_text("trial,file,yaw,pitch\nA,trials/A.c3d,36,0\n")
    return ["build-map", str(d / "sheet.csv"), "--markers", str(ROOT / "pipeline" / "examples" / "markerset.toml"),
            "--out", str(d / "map.usda"), "--min-trials", "1", "--quiet"]
