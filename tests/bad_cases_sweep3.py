"""Catalogue builders for what the unusual-inputs sweep found (2026-12-07)."""

from __future__ import annotations

from pxr import Gf, Sdf, Vt

from .bad_common import JOB, apply_argv, edited, manifest, remove, rig


def b_sparse_animation_without_rest_transforms(d):
    """No restTransforms, and the animation leaves one joint out: UsdSkel poses nothing (0 joint
    transforms), and a layer over it posed nothing either, while apply said it was written."""
    def bare(layer, rig):
        remove(layer, rig.skeleton + ".restTransforms")
    return apply_argv(d, edited(d, bare, unanimated=("spine_b",)))


def _shot_over(d, arc: str, up_axis: str = "Y", **shot_meta):
    """``shot.usda`` bringing a metre rig (``char.usda``, built ``up_axis`` up) in at /Character through
    ``arc`` (a reference or payload), its own metadata ``shot_meta`` (no metersPerUnit: USD takes 0.01)."""
    from pxr import Sdf

    from .bad_common import rig

    r = rig(d, "char.usda", meters_per_unit=1.0, **({"up_axis": up_axis} if up_axis != "Y" else {}))
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    for key, value in {"upAxis": "Y", **shot_meta}.items():
        if value is not None:  # None: left unauthored
            shot.pseudoRoot.SetInfo(key, value)
    prim = Sdf.CreatePrimInLayer(shot, r.skel_root)
    prim.specifier = Sdf.SpecifierDef
    items = [(Sdf.Reference if arc == "reference" else Sdf.Payload)("./char.usda", r.skel_root)]
    (prim.referenceList if arc == "reference" else prim.payloadList).prependedItems = items
    shot.Save()
    return apply_argv(d, d / "shot.usda")


def b_meters_per_unit_only_in_a_reference(d):
    """A stage that authors no metersPerUnit referencing a metre character: a 1.6 cm character, said
    only as targets out of reach."""
    return _shot_over(d, "reference")


def b_meters_per_unit_only_in_a_payload(d):
    return _shot_over(d, "payload", metersPerUnit=0.01)


def b_up_axis_only_in_a_reference(d):
    """A Y-up stage referencing a Z-up export: USD does not turn it, so the character lay on its back,
    and apply wrote a gaze turned about the wrong axis without a word."""
    return _shot_over(d, "reference", up_axis="Z", metersPerUnit=1.0)


def b_up_axis_only_in_a_payload(d):
    """A stage that authors no upAxis (USD takes Y) bringing a Z-up export in as a payload."""
    return _shot_over(d, "payload", up_axis="Z", metersPerUnit=1.0, upAxis=None)


def b_joint_names_wrong_length_no_chain(d):
    """Generic joint tokens (``bone_000``) and a jointNames list one short: the names, the only words a
    binder could read, were ignored, and the "no gaze chain" line did not say why."""
    from pxr import Vt

    from . import synthetic as syn

    named = syn.make_rig(d / "named.usda", frames=30, mesh=False)

    def short_names(layer, r):
        names = [j.rsplit("/", 1)[-1].replace("mixamorig_", "") for j in named.joints]
        attr = layer.GetPrimAtPath(r.skeleton).attributes.get("jointNames") or _token_array(layer, r.skeleton)
        attr.default = Vt.TokenArray(names[:-1])
    return apply_argv(d, edited(d, short_names, convention="generic"))


def _token_array(layer, prim_path: str):
    from pxr import Sdf

    return Sdf.AttributeSpec(layer.GetPrimAtPath(prim_path), "jointNames", Sdf.ValueTypeNames.TokenArray,
                             Sdf.VariabilityUniform)


def b_physics_skelroot_squashed(d):
    """A SkelRoot scaled (1, 1.2, 1): rigid bodies cannot follow the squash (the model's joints were
    10-15 cm from UsdSkel's as they turned, exit 0)."""
    def squash(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "xformOp:scale", Sdf.ValueTypeNames.Float3).default = Gf.Vec3f(1.0, 1.2, 1.0)
        Sdf.AttributeSpec(root, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:scale"])
    return ["physics-model", str(edited(d, squash)), "--out", str(d / "body.xml")]


def b_preview_command_sheet_bad_extension(d):
    return ["preview", str(rig(d).path), "--layer", str(d / "gaze.usdc"), "--out", str(d / "x.gif"),
            "--sheet", str(d / "y.gif")]


def b_preview_command_out_bad_extension(d):
    return ["preview", str(rig(d).path), "--layer", str(d / "gaze.usdc"), "--out", str(d / "x.avi")]


def _physics_model(d, author, **kw):
    return ["physics-model", str(edited(d, author, **kw)), "--out", str(d / "body.xml")]


def b_physics_body_too_small(d):
    """A rig in metres on a stage that says centimetres: 1.9 cm tall (an MJCF MuJoCo refuses, 'inertia
    must satisfy A + B >= C', was written with exit 0; attend --physics failed with exit 1)."""
    def centimetres(layer, r):
        layer.pseudoRoot.SetInfo("metersPerUnit", 0.01)
    return _physics_model(d, centimetres)


def b_physics_body_too_tall(d):
    """A SkelRoot scaled 4 by one factor: a 7.8 m body, no person's size."""
    def giant(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "xformOp:scale", Sdf.ValueTypeNames.Float3).default = Gf.Vec3f(4.0)
        Sdf.AttributeSpec(root, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:scale"])
    return _physics_model(d, giant)


def b_mesh_index_on_an_added_eye(d):
    """An eyeless rig whose mesh is skinned by index J on a J-joint skeleton (out of range): the eyes
    apply adds became joints J and J + 1, and the mesh silently followed the left eye."""
    def past_the_joints(layer, r):
        attr = layer.GetAttributeAtPath(r.mesh + ".primvars:skel:jointIndices")
        indices = list(attr.default)
        indices[0] = len(r.joints)
        attr.default = Vt.IntArray(indices)
    return apply_argv(d, edited(d, past_the_joints, eyes=False, mesh=True))


def b_map_on_the_skeleton(d):
    """A map file referenced onto the Skeleton, not the SkelRoot: the built-in map was used, exit 0."""
    from .bad_common import dump_map

    path = dump_map(d / "map.usda")

    def author(layer, r):
        layer.GetPrimAtPath(r.skeleton).referenceList.Prepend(Sdf.Reference(path.name, "/GazeMap"))
    return apply_argv(d, edited(d, author))


def b_map_value_in_a_referenced_map_file(d):
    """A bad value in a map file a character references: the line named the stage, which holds no such value."""
    from .bad_common import dump_map

    path = dump_map(d / "map.usda")
    map_layer = Sdf.Layer.FindOrOpen(str(path))
    map_layer.Reload(force=True)
    map_layer.GetAttributeAtPath("/GazeMap.gaze:synthesis:blendSize").default = 99
    map_layer.Save()

    def author(layer, r):
        layer.GetPrimAtPath(r.skel_root).referenceList.Prepend(Sdf.Reference(path.name, "/GazeMap"))
    return apply_argv(d, edited(d, author))


def b_build_map_sheet_semicolons(d):
    (d / "a.c3d").write_bytes(b"trial")
    (d / "sheet.csv").write_text("file;yaw;pitch\na.c3d;0;0\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "map.usda")]


def b_build_map_sheet_trial_and_trials(d):
    for name in ("a.c3d", "b.c3d"):
        (d / name).write_bytes(b"trial")
    (d / "sheet.toml").write_text('[[trials]]\nfile = "a.c3d"\nyaw = 0\npitch = 0\n'
                                  '[[trial]]\nfile = "b.c3d"\nyaw = 36\npitch = 0\n')
    return ["build-map", str(d / "sheet.toml"), "--out", str(d / "map.usda")]


def b_build_map_c3d_metres_in_a_mm_file(d):
    """Points in metres, POINT:UNITS left blank (C3D reads mm; ezc3d writes none by default)."""
    import numpy as np

    from . import ingest_synth as syn
    from .c3d_bytes import write_c3d_bytes

    motion = syn.known_motions(np.array([[72.0, 0.0]]))[0]
    points, _ = syn.simulate_trial(motion, np.random.default_rng(0))
    write_c3d_bytes(d / "a.c3d", list(syn.LABELS), points / 1000.0, syn.RATE, units=" ")
    (d / "markers.toml").write_text(syn.MARKERSET_TOML)
    (d / "sheet.csv").write_text("file,yaw,pitch\na.c3d,72,0\n")
    return ["build-map", str(d / "sheet.csv"), "--markers", str(d / "markers.toml"), "--out", str(d / "map.usda"),
            "--min-trials", "1", "--quiet"]


def b_attend_objects_property_path(d):
    """``--objects`` naming an attribute's path (copied from usdview): it said 'no such prim'."""
    return ["attend", str(rig(d).path), "--objects", "/Character.radius", "--out", str(d / "a.usda")]


def b_build_map_sheet_markers_not_a_file(d):
    """A TOML sheet whose ``markers`` names no file: it said 'nope.toml: no such file', not where."""
    (d / "a.c3d").write_bytes(b"trial")
    (d / "sheet.toml").write_text('markers = "nope.toml"\n[[trial]]\nfile = "a.c3d"\nyaw = 0\npitch = 0\n')
    return ["build-map", str(d / "sheet.toml"), "--out", str(d / "map.usda")]


def b_directive_on_one_sample_without_a_range(d):
    """One time sample per array and no playback range: 'lies outside the animation (time codes 0 to 0)'
    said nothing of why."""
    def one_sample(layer, r):
        for name in ("rotations", "translations", "scales"):
            path = Sdf.Path(f"{r.animation}.{name}")
            for t in layer.ListTimeSamplesForPath(path)[1:]:
                layer.EraseTimeSample(path, t)
        layer.ClearStartTimeCode()
        layer.ClearEndTimeCode()
    return apply_argv(d, edited(d, one_sample))


def b_character_transform_a_double(d):
    """The SkelRoot's ``xformOp:translate`` authored as a double: USD cannot evaluate the character's
    transform, and apply stopped with USD's internal error (exit 1)."""
    def double_translate(layer, r):
        prim = layer.GetPrimAtPath(r.skel_root)
        for name in ("xformOpOrder", "xformOp:translate"):
            if name in prim.properties:
                prim.RemoveProperty(prim.properties[name])
        order = Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                                  variability=Sdf.VariabilityUniform)
        order.default = ["xformOp:translate"]
        Sdf.AttributeSpec(prim, "xformOp:translate", Sdf.ValueTypeNames.Double).default = 1.0
    return apply_argv(d, edited(d, double_translate))


def b_look_at_target_unknown_op(d):
    """A look-at target whose xformOpOrder names an op USD does not evaluate (``xformOp:foo``): an
    internal error (exit 1) before."""
    def target(layer, r):
        prim = Sdf.CreatePrimInLayer(layer, "/World/Target")
        prim.specifier = Sdf.SpecifierDef
        prim.typeName = "Xform"
        order = Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                                  variability=Sdf.VariabilityUniform)
        order.default = ["xformOp:foo"]
        Sdf.AttributeSpec(prim, "xformOp:foo", Sdf.ValueTypeNames.Double3).default = Gf.Vec3d(0, 1.5, 2)
    return ["apply", str(edited(d, target)), "--look-at", "/World/Target@0.5s", "--out", str(d / "gaze.usdc")]


def b_batch_emit_manifest_folder_line_break(d):
    """``--emit slurm`` of a manifest in a folder whose name holds a line break: it ended the SLURM
    script's comment line, so the rest of the name ran as a command and sbatch ignored the #SBATCH
    lines after it."""
    folder = d / "shots\nday2"
    folder.mkdir()
    return manifest(folder, f"[[job]]\n{JOB}", "--emit", "slurm", str(d / "jobs"))


def b_batch_manifest_in_a_missing_folder(d):
    """A mistyped manifest folder: it was said as its default summary's folder missing."""
    return ["batch", str(d / "shots" / "manifest.toml")]


def _review_with_record(d, command: list[str], **record):
    """The rig and apply's layer for it, whose ``customLayerData["usdgaze"]`` a hand edit (or another
    tool) gave ``record``'s values (None: the key removed); ``command``: plot or preview and its output options."""
    from usdgaze import api

    r = rig(d)
    layer_path = d / "gaze.usda"
    api.apply(str(r.path), ["0.5s:30:0"], layer_path)
    layer = Sdf.Layer.FindOrOpen(str(layer_path))
    data = dict(layer.customLayerData)
    data["usdgaze"] = {k: v for k, v in {**dict(data["usdgaze"]), **record}.items() if v is not None}
    layer.customLayerData = data
    layer.Save()
    return [command[0], str(r.path), "--layer", str(layer_path), *command[1:]]


def b_plot_layer_record_shifts_not_a_list(d):
    """``shifts = 7`` in a layer that records no directives (one older than them): exit 1 ('int'
    object is not iterable)."""
    return _review_with_record(d, ["plot", "--out", str(d / "plots")], shifts=7, directives=None)


def b_plot_layer_record_eye_range_nan(d):
    """``eyeRange.yaw`` NaN: exit 1 (matplotlib's 'Axis limits cannot be NaN or Inf')."""
    return _review_with_record(d, ["plot", "--out", str(d / "plots")],
                               eyeRange={"yaw": float("nan"), "up": 27.7, "down": 47.1})


def b_plot_layer_record_bind_not_a_list(d):
    """``bind = 7``: exit 1 ('int' object is not iterable), validate's too."""
    return _review_with_record(d, ["plot", "--out", str(d / "plots")], bind=7)


def b_preview_layer_record_fixation_text(d):
    """``fixation = "far"``: exit 1 (could not convert string to float)."""
    return _review_with_record(d, ["preview", "--out", str(d / "review.gif")], fixation="far")


def b_preview_layer_record_fixation_negative(d):
    """``fixation = -3``: every line of sight drawn backwards, out of the back of the head, exit 0."""
    return _review_with_record(d, ["preview", "--out", str(d / "review.gif")], fixation=-3.0)


def b_preview_layer_record_directives_not_a_table(d):
    """``directives = 5``: exit 1 ('int' object has no attribute 'get')."""
    return _review_with_record(d, ["preview", "--out", str(d / "review.gif")], directives=5)


def b_preview_sheet_too_large(d):
    """``--sheet-count 200 --size 2048``, both in their ranges: a 1.7 gigapixel sheet stopped on a
    MemoryError (exit 1); 100 at 1024 wrote one of 214 megapixels that Pillow refuses to open."""
    return _review_with_record(d, ["preview", "--out", str(d / "sheet.png"), "--sheet-count", "200", "--size", "2048"])
