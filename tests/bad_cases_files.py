"""Catalogue builders: outputs against inputs by identity, write failures, --no-clobber, --sublayer-into."""

from __future__ import annotations

import os
from pathlib import Path

from pxr import Sdf

from .bad_common import JOB, apply_argv, can_mount, dump_map, fill, manifest, rig, sheet, tmpfs

MOUNTABLE = can_mount()


def _layer_file(d: Path, name: str, body: str) -> Path:
    (d / name).write_text("#usda 1.0\n" + body)
    return d / name


def _composed(d: Path, how: str) -> Path:
    """shot.usda bringing in the rig at char.usda by ``how`` (sublayer, reference or payload)."""
    r = rig(d, "char.usda")
    if how == "sublayer":
        body = "(\n    subLayers = [@./char.usda@]\n)\n"
    else:
        body = f'def "Character" (\n    {how} = @./char.usda@</Character>\n)\n{{\n}}\n'
    _layer_file(d, "shot.usda", body)
    return r.path


def _read_only_folder(d: Path) -> Path:
    """A read-only folder: a read-only tmpfs where mounting works, else mode 0555; as root without
    mounting (mode bits do not stop root) the runner fails its writes with EROFS (``.inject-erofs``)."""
    if MOUNTABLE:
        return tmpfs(d / "ro", read_only=True)
    (d / "ro").mkdir()
    if os.geteuid() == 0:
        (d / "ro" / ".inject-erofs").write_text("")
    else:
        os.chmod(d / "ro", 0o555)
    return d / "ro"


def _full_folder(d: Path, before=None) -> Path:
    """A folder on a full disk (a filled 64 KiB tmpfs; ``before(folder)`` runs before it fills), or,
    where mounting is not allowed, a folder whose writes the runner fails with ENOSPC
    (``.inject-enospc``, see test_bad_inputs)."""
    if MOUNTABLE:
        folder = tmpfs(d / "full", size="64k")
    else:
        folder = d / "full"
        folder.mkdir()
    if before:
        before(folder)
    if MOUNTABLE:
        fill(folder)
    else:
        (folder / ".inject-enospc").write_text("")
    return folder


# -- identity: an output is never an input, however it is spelled -----------------------------------

def b_out_symlink_to_input(d):
    src = rig(d).path
    (d / "gaze.usdc").symlink_to(src)
    return apply_argv(d, src)


def b_out_hard_link_of_input(d):
    src = rig(d, "in.usdc").path
    os.link(src, d / "gaze.usdc")
    return apply_argv(d, src)


def b_out_through_symlinked_folder(d):
    src = rig(d).path
    (d / "same").symlink_to(d)
    return apply_argv(d, src, out="same/in.usda")


def b_out_dot_dot_spelling(d):
    src = rig(d).path
    (d / "sub").mkdir()
    return apply_argv(d, src, out="sub/../in.usda")


def b_out_relative_spelling(d):
    src = rig(d).path
    return ["apply", str(src), "--shift", "0.5s:30:0", "--out", "./in.usda"]


def b_input_through_symlink_out_is_target(d):
    r = rig(d, "real/anim.usda")
    (d / "in.usda").symlink_to(r.path)
    return apply_argv(d, d / "in.usda", out="real/anim.usda")


def b_preview_symlink_to_input(d):
    src = rig(d).path
    (d / "preview.usda").symlink_to(src)
    return apply_argv(d, src, "--preview", str(d / "preview.usda"))


def b_preview_hard_link_of_input(d):
    src = rig(d).path
    os.link(src, d / "preview.usda")
    return apply_argv(d, src, "--preview", str(d / "preview.usda"))


def b_out_is_a_sublayer_of_the_input(d):
    _composed(d, "sublayer")
    return apply_argv(d, d / "shot.usda", out="char.usda")


def b_out_is_a_referenced_layer(d):
    _composed(d, "references")
    return apply_argv(d, d / "shot.usda", out="char.usda")


def b_out_is_a_payload(d):
    _composed(d, "payload")
    return apply_argv(d, d / "shot.usda", out="char.usda")


def b_preview_is_a_sublayer_of_the_input(d):
    _composed(d, "sublayer")
    return apply_argv(d, d / "shot.usda", "--preview", str(d / "char.usda"))


def b_out_is_a_value_clip(d):
    rig(d, "clip.usda")
    _layer_file(d, "in.usda", (
        'def "Character" (\n    references = @./clip.usda@</Character>\n)\n{\n'
        '    over "Anim" (\n        clips = {\n            dictionary default = {\n'
        '                asset[] assetPaths = [@./clip.usda@]\n                string primPath = "/Character/Anim"\n'
        '                double2[] active = [(0, 0)]\n            }\n        }\n    )\n    {\n    }\n}\n'))
    return apply_argv(d, d / "in.usda", out="clip.usda")


def b_out_is_the_map_file(d):
    dump_map(d / "map.usda")
    return apply_argv(d, rig(d).path, "--map", str(d / "map.usda"), out="map.usda")


def b_preview_is_the_map_file(d):
    dump_map(d / "map.usda")
    return apply_argv(d, rig(d).path, "--map", str(d / "map.usda"), "--preview", str(d / "map.usda"))


def b_preview_equals_out(d):
    return apply_argv(d, rig(d).path, "--preview", str(d / "gaze.usdc"))


def b_preview_hard_link_of_out(d):
    (d / "gaze.usdc").write_bytes(b"old output")
    os.link(d / "gaze.usdc", d / "preview.usda")
    return apply_argv(d, rig(d).path, "--preview", str(d / "preview.usda"))


def b_sublayer_into_equals_out(d):
    _layer_file(d, "gaze.usdc", "")
    return apply_argv(d, rig(d).path, "--sublayer-into", str(d / "gaze.usdc"))


def b_sublayer_into_symlink_to_input(d):
    src = rig(d).path
    (d / "shot.usda").symlink_to(src)
    return apply_argv(d, src, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_hard_link_of_input(d):
    src = rig(d).path
    os.link(src, d / "shot.usda")
    return apply_argv(d, src, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_a_sublayer_of_the_input(d):
    _composed(d, "sublayer")
    return apply_argv(d, d / "shot.usda", "--sublayer-into", str(d / "char.usda"))


def b_sublayer_into_the_map_file(d):
    dump_map(d / "map.usda")
    return apply_argv(d, rig(d).path, "--map", str(d / "map.usda"), "--sublayer-into", str(d / "map.usda"))


def b_plot_symlink_to_input(d):
    src = rig(d).path
    (d / "plot.png").symlink_to(src)
    return apply_argv(d, src, "--plot", str(d / "plot.png"))


def b_physics_model_out_symlink_to_input(d):
    src = rig(d).path
    (d / "body.xml").symlink_to(src)
    return ["physics-model", str(src), "--out", str(d / "body.xml")]


def b_build_map_out_is_a_trial_file(d):
    rig(d, "t1.usda")
    rig(d, "t2.usda")
    (d / "sheet.csv").write_text("file,yaw,pitch\nt1.usda,0,0\nt2.usda,30,0\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "t2.usda")]


def b_build_map_out_is_a_layer_a_trial_composes(d):
    rig(d, "t1.usda")
    (d / "t2.usda").write_text('#usda 1.0\n(\n    subLayers = [@./t1.usda@]\n)\n')
    (d / "sheet.csv").write_text("trial,file,yaw,pitch\na,t2.usda,0,0\nb,t2.usda,30,0\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "t1.usda")]


def b_build_map_report_is_the_sheet(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--report", str(d / "sheet.csv")]


def b_build_map_report_symlink_to_the_sheet(d):
    path = sheet(d)
    (d / "report.csv").symlink_to(path)
    return ["build-map", str(path), "--out", str(d / "map.usda"), "--report", str(d / "report.csv")]


def b_build_map_out_is_the_marker_set(d):
    (d / "markers.usda").write_text("#usda 1.0\n")
    return ["build-map", str(sheet(d)), "--markers", str(d / "markers.usda"), "--out", str(d / "markers.usda")]


def b_batch_two_jobs_one_out(d):
    return manifest(d, f"[[job]]\nname = \"a\"\n{JOB}\n[[job]]\nname = \"b\"\n{JOB}")


def b_batch_out_is_another_jobs_input(d):
    rig(d, "other.usda")
    return manifest(d, f"[[job]]\nname = \"a\"\n{JOB}\n[[job]]\nname = \"b\"\ninput = \"other.usda\"\n"
                       f"out = \"in.usda\"\nshifts = [\"1:2:3\"]\n")


def b_batch_out_is_a_layer_another_jobs_input_composes(d):
    _composed(d, "sublayer")  # shot.usda sublayers char.usda
    rig(d, "other.usda")
    return manifest(d, '[[job]]\nname = "a"\ninput = "shot.usda"\nout = "a.usdc"\nshifts = ["1:2:3"]\n'
                       '[[job]]\nname = "b"\ninput = "other.usda"\nout = "char.usda"\nshifts = ["1:2:3"]\n')


def b_batch_out_equals_preview(d):
    return manifest(d, f"[[job]]\n{JOB}preview = \"gaze.usdc\"\n")


def b_batch_report_is_the_manifest(d):
    (d / "summary.json").symlink_to("manifest.toml")  # a summary must end in .json
    return manifest(d, f"[[job]]\n{JOB}", "--summary", str(d / "summary.json"))


def b_batch_report_is_a_jobs_out(d):
    (d / "summary.json").symlink_to("gaze.usdc")
    return manifest(d, f"[[job]]\n{JOB}", "--summary", str(d / "summary.json"))


def b_batch_out_is_the_manifest(d):
    return manifest(d, '[[job]]\ninput = "in.usda"\nout = "manifest.usda"\nshifts = ["1:2:3"]\n', name="manifest.usda")


# -- write failures -------------------------------------------------------------------------------

def b_out_read_only_folder(d):
    _read_only_folder(d)
    return apply_argv(d, rig(d).path, out="ro/gaze.usdc")


def b_preview_read_only_folder(d):
    _read_only_folder(d)  # --out itself could be written: it must not remain either
    return apply_argv(d, rig(d).path, "--preview", str(d / "ro" / "preview.usda"))


def b_plot_read_only_folder(d):
    _read_only_folder(d)
    return apply_argv(d, rig(d).path, "--plot", str(d / "ro" / "plot.png"))


def b_dump_map_read_only_folder(d):
    _read_only_folder(d)
    return ["dump-map", str(d / "ro" / "map.usda")]


def b_out_disk_full(d):
    _full_folder(d)
    return apply_argv(d, rig(d).path, out="full/gaze.usdc")


def b_preview_disk_full(d):
    _full_folder(d)
    return apply_argv(d, rig(d).path, "--preview", str(d / "full" / "preview.usda"))


def b_dump_map_disk_full(d):
    _full_folder(d)
    return ["dump-map", str(d / "full" / "map.usda")]


def b_out_name_too_long(d):
    return apply_argv(d, rig(d).path, out="g" * 300 + ".usdc")


def b_preview_name_too_long(d):
    return apply_argv(d, rig(d).path, "--preview", str(d / ("p" * 300 + ".usda")))


def b_out_folder_is_a_file(d):
    rig(d)
    return apply_argv(d, d / "in.usda", out="in.usda/gaze.usdc")


def b_preview_missing_folder(d):
    return apply_argv(d, rig(d).path, "--preview", str(d / "nofolder" / "preview.usda"))


def b_plot_missing_folder(d):
    return apply_argv(d, rig(d).path, "--plot", str(d / "nofolder" / "plot.png"))


def b_plot_bad_extension(d):
    return apply_argv(d, rig(d).path, "--plot", str(d / "plot.gif"))


def b_out_is_a_folder(d):
    (d / "gaze.usdc").mkdir()
    return apply_argv(d, rig(d).path)


def b_dump_map_missing_folder(d):
    return ["dump-map", str(d / "nofolder" / "map.usda")]


def b_dump_map_is_a_folder(d):
    (d / "map.usda").mkdir()
    return ["dump-map", str(d / "map.usda")]


def b_build_map_report_missing_folder(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--report", str(d / "nofolder" / "r.csv")]


def b_build_map_report_bad_extension(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--report", str(d / "r.txt")]


def b_build_map_out_missing_folder(d):
    return ["build-map", str(sheet(d)), "--out", str(d / "nofolder" / "map.usda")]


def b_build_map_series_is_a_file(d):
    (d / "series").write_text("a file\n")
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--series", str(d / "series")]


def b_build_map_out_read_only_folder(d):
    _read_only_folder(d)
    rig(d, "t1.usda")
    return ["build-map", str(sheet(d)), "--out", str(d / "ro" / "map.usda")]


def b_physics_model_out_missing_folder(d):
    return ["physics-model", str(rig(d).path), "--out", str(d / "nofolder" / "body.xml")]


def b_batch_report_missing_folder(d):
    return manifest(d, f"[[job]]\n{JOB}", "--summary", str(d / "nofolder" / "report.json"))


def b_batch_report_is_a_folder(d):
    (d / "report.json").mkdir()
    return manifest(d, f"[[job]]\n{JOB}", "--summary", str(d / "report.json"))


# -- --no-clobber ---------------------------------------------------------------------------------

def b_no_clobber_out_exists(d):
    (d / "gaze.usdc").write_bytes(b"an older output")
    return apply_argv(d, rig(d).path, "--no-clobber")


def b_no_clobber_preview_exists(d):
    (d / "preview.usda").write_text("#usda 1.0\n")
    return apply_argv(d, rig(d).path, "--no-clobber", "--preview", str(d / "preview.usda"))


def b_no_clobber_plot_exists(d):
    (d / "plot.png").write_bytes(b"png")
    return apply_argv(d, rig(d).path, "--no-clobber", "--plot", str(d / "plot.png"))


def other_shot(d: Path, name: str) -> Path:
    """Another character's layer at ``d/name`` (a typo for an output name), in the suffix's encoding."""
    path = d / name
    Sdf.Layer.FindOrOpen(str(rig(d, "other_rig.usda").path)).Export(str(path))
    (d / "other_rig.usda").unlink()
    return path


def b_out_is_another_shot(d):
    other_shot(d, "other.usdc")
    return apply_argv(d, rig(d).path, out="other.usdc")


def b_preview_is_another_shot(d):
    other_shot(d, "other.usda")
    return apply_argv(d, rig(d).path, "--preview", str(d / "other.usda"))


def b_dump_map_onto_another_shot(d):
    other_shot(d, "other.usda")
    return ["dump-map", str(d / "other.usda")]


def b_build_map_out_is_another_shot(d):
    rig(d, "t1.usda")
    other_shot(d, "other.usda")
    return ["build-map", str(sheet(d)), "--out", str(d / "other.usda")]


def b_dump_map_no_clobber(d):
    (d / "map.usda").write_text("#usda 1.0\n")
    return ["dump-map", str(d / "map.usda"), "--no-clobber"]


def b_build_map_no_clobber(d):
    (d / "map.usda").write_text("#usda 1.0\n")
    return ["build-map", str(sheet(d)), "--out", str(d / "map.usda"), "--no-clobber"]


# -- --sublayer-into ------------------------------------------------------------------------------

def b_sublayer_into_read_only_file(d):
    shot = _layer_file(d, "shot.usda", "(\n    subLayers = [@./in.usda@]\n)\n")
    os.chmod(shot, 0o444)
    return apply_argv(d, rig(d).path, "--sublayer-into", str(shot))


def b_sublayer_into_symlink_to_read_only_file(d):
    shot = _layer_file(d, "real_shot.usda", "(\n    subLayers = [@./in.usda@]\n)\n")
    os.chmod(shot, 0o444)
    (d / "shot.usda").symlink_to(shot)
    return apply_argv(d, rig(d).path, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_a_folder(d):
    (d / "shot.usda").mkdir()
    return apply_argv(d, rig(d).path, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_bad_extension(d):
    (d / "shot.txt").write_text("#usda 1.0\n")
    return apply_argv(d, rig(d).path, "--sublayer-into", str(d / "shot.txt"))


def b_sublayer_into_with_own_opinion(d):
    r = rig(d)
    layer = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    layer.subLayerPaths.append("./in.usda")
    prim = Sdf.CreatePrimInLayer(layer, r.animation)
    prim.specifier = Sdf.SpecifierOver
    spec = Sdf.AttributeSpec(prim, "rotations", Sdf.ValueTypeNames.QuatfArray)
    layer.SetTimeSample(spec.path, 0.0, Sdf.Layer.FindOrOpen(str(r.path)).QueryTimeSample(spec.path, float(r.times[0])))
    layer.Save()
    return apply_argv(d, r.path, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_with_own_binding(d):
    r = rig(d)
    layer = Sdf.Layer.FindOrOpen(str(r.path))
    layer.Reload(force=True)
    skel = layer.GetPrimAtPath(r.skeleton)
    del skel.properties["skel:animationSource"]  # unbound: the override defines and binds an animation
    layer.Save()
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    for key in ("upAxis", "metersPerUnit"):
        if layer.pseudoRoot.HasInfo(key):
            shot.pseudoRoot.SetInfo(key, layer.pseudoRoot.GetInfo(key))
    shot.subLayerPaths.append("./in.usda")
    over = Sdf.CreatePrimInLayer(shot, r.skeleton)
    over.specifier = Sdf.SpecifierOver
    Sdf.RelationshipSpec(over, "skel:animationSource", custom=False).targetPathList.explicitItems = []
    shot.Save()
    return apply_argv(d, r.path, "--sublayer-into", str(d / "shot.usda"))


def b_sublayer_into_disk_full(d):
    rig(d)
    full = _full_folder(d, lambda f: (f / "shot.usda").write_text("#usda 1.0\n(\n    subLayers = [@../in.usda@]\n)\n"))
    return apply_argv(d, d / "in.usda", "--sublayer-into", str(full / "shot.usda"))
