"""Catalogue builders for what an adversarial sweep found (2026-12-03): outputs that are pipes,
bindings off the chain or shared by two roles, composition that failed, joints listed twice, an
inactive animation, far look-at targets, loose option and sheet values."""

from __future__ import annotations

import os

from pxr import Sdf, Vt

from .bad_common import JOB, apply_argv, edited, manifest, rig

SAMPLE_BALLS = os.path.join(os.path.dirname(__file__), "..", "sample_stages", "attend", "two_balls.usda")


def b_out_is_a_named_pipe(d):
    os.mkfifo(d / "gaze.usdc")
    return apply_argv(d, rig(d).path)


def b_bind_spine_off_the_chain(d):
    return apply_argv(d, rig(d).path, "--bind", "upperSpine=mixamorig_LeftArm")


def b_bind_eye_that_is_the_head(d):
    return apply_argv(d, rig(d).path, "--bind", "leftEye=mixamorig_Head")


def b_bind_one_joint_two_roles(d):
    return apply_argv(d, rig(d).path, "--bind", "leftEye=mixamorig_RightEye")


def b_bind_joint_twice(d):
    return apply_argv(d, rig(d).path, "--bind", "head=mixamorig_Head+mixamorig_Head")


def b_bind_neck_above_head(d):
    return apply_argv(d, rig(d).path, "--bind", "neck=mixamorig_Head", "--bind", "head=mixamorig_Neck")


def b_batch_bind_not_a_list(d):
    return manifest(d, f"[[job]]\n{JOB}bind = 7\n")


def b_look_at_too_far(d):
    return apply_argv(d, rig(d).path, "--look-at", "1,2,1e300@10", shifts=[])


def _sublayer(layer: Sdf.Layer, r) -> None:
    layer.subLayerPaths.append("./nothere.usda")


def b_missing_sublayer(d):
    return apply_argv(d, edited(d, _sublayer))


def _cycle(layer: Sdf.Layer, r) -> None:
    layer.GetPrimAtPath("/Character").referenceList.Prepend(Sdf.Reference("./in.usda", "/Character"))


def b_reference_cycle(d):
    return apply_argv(d, edited(d, _cycle))


def _joints_twice(attr: str):
    def edit(layer: Sdf.Layer, r) -> None:
        spec = layer.GetAttributeAtPath(attr.format(skel=r.skeleton, anim=r.animation))
        tokens = list(spec.default)
        spec.default = Vt.TokenArray(tokens[:-1] + [tokens[1]])
    return edit


def b_skeleton_joint_twice(d):
    return apply_argv(d, edited(d, _joints_twice("{skel}.joints")))


def b_animation_joint_twice(d):
    return apply_argv(d, edited(d, _joints_twice("{anim}.joints")))


def b_animation_inactive(d):
    return apply_argv(d, edited(d, lambda layer, r: setattr(layer.GetPrimAtPath(r.animation), "active", False)))


def b_attend_seed_negative(d):
    return ["attend", SAMPLE_BALLS, "--out", str(d / "gaze.usdc"), "--seed", "-1"]


def b_attend_objects_empty(d):
    return ["attend", SAMPLE_BALLS, "--out", str(d / "gaze.usdc"), "--objects", ""]


def b_attend_objects_twice(d):
    return ["attend", SAMPLE_BALLS, "--out", str(d / "gaze.usdc"), "--objects", "/Objects/BallLeft,/Objects/BallLeft"]


def b_attend_object_holds_the_character(d):
    return ["attend", SAMPLE_BALLS, "--out", str(d / "gaze.usdc"), "--objects", "/root"]


def b_physics_model_mass_nan(d):
    return ["physics-model", str(rig(d).path), "--out", str(d / "body.xml"), "--mass", "nan"]


def b_preview_fps_too_high(d):
    return ["preview", str(rig(d).path), "--layer", str(d / "gaze.usdc"), "--out", str(d / "p.gif"), "--fps", "1e9"]


def b_batch_dask_not_an_address(d):
    return manifest(d, f"[[job]]\n{JOB}", "--dask", "not an address")


def b_batch_dask_tls_without_a_context(d):
    return manifest(d, f"[[job]]\n{JOB}", "--dask", "tls://127.0.0.1:1")


def b_batch_emit_with_a_task_index(d):
    return manifest(d, f"[[job]]\n{JOB}", "--emit", "slurm", str(d / "jobs"), "--task-index", "0")


def b_batch_summary_not_json(d):
    return manifest(d, f"[[job]]\n{JOB}", "--summary", str(d / "summary.txt"))


def b_batch_name_with_a_newline(d):
    return manifest(d, f'[[job]]\n{JOB}name = "walk\\n01"\n')


def b_sublayer_into_a_layer_without_the_input(d):
    shot = d / "shot.usda"
    Sdf.Layer.CreateNew(str(shot)).Save()
    return apply_argv(d, rig(d).path, "--sublayer-into", str(shot))


def b_build_map_sheet_unknown_column(d):
    (d / "a.c3d").write_bytes(b"trial")
    (d / "sheet.csv").write_text("file,yaw,pitch,colour\na.c3d,0,0,red\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "map.usda")]


def b_build_map_sheet_crop_not_a_list(d):
    (d / "a.c3d").write_bytes(b"trial")
    (d / "sheet.toml").write_text('[[trial]]\nfile = "a.c3d"\nyaw = 0\npitch = 0\ncrop = "1-5"\n')
    return ["build-map", str(d / "sheet.toml"), "--out", str(d / "map.usda")]


def _second_character_on_the_same_animation(layer: Sdf.Layer, r) -> None:
    Sdf.CopySpec(layer, r.skel_root, layer, "/Character2")
    skel = layer.GetPrimAtPath("/Character2/Skel")
    skel.relationships["skel:animationSource"].targetPathList.ClearEditsAndMakeExplicit()
    skel.relationships["skel:animationSource"].targetPathList.explicitItems = [r.animation]


def b_skel_root_animation_shared(d):
    return apply_argv(d, edited(d, _second_character_on_the_same_animation), "--skel-root", "/Character")


def b_up_axis_only_in_a_sublayer(d):
    rig(d, "char.usda", up_axis="Z")
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    shot.subLayerPaths.append("./char.usda")
    shot.Save()
    return apply_argv(d, d / "shot.usda")


def _start_after_end(layer: Sdf.Layer, r) -> None:
    layer.startTimeCode, layer.endTimeCode = 89.0, 0.0


def b_start_after_end(d):
    return apply_argv(d, edited(d, _start_after_end))


def b_map_prim_path_not_absolute(d):
    from .bad_common import dump_map

    dump_map(d / "map.usda")
    return apply_argv(d, rig(d).path, "--map", f"{d / 'map.usda'}:GazeMap")


def b_meters_per_unit_only_in_a_sublayer(d):
    rig(d, "char.usda", meters_per_unit=1.0)
    shot = Sdf.Layer.CreateNew(str(d / "shot.usda"))
    shot.subLayerPaths.append("./char.usda")
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.Save()
    return apply_argv(d, d / "shot.usda")


# -- pushes on the physics body (a second sweep, 2026-12-03) ---------------------------------------

def _pushed(d, type_name, samples=None, default=None):
    """``attend --physics`` on the rig with a push on its spine authored as given."""
    def author(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
        force = Sdf.AttributeSpec(root, "usdgaze:physics:pushForce", type_name)
        for t, v in (samples or {}).items():
            layer.SetTimeSample(force.path, t, v)
        if default is not None:
            force.default = default
    return ["attend", str(edited(d, author)), "--physics", "--out", str(d / "gaze.usdc")]


def b_push_force_nan(d):
    return _pushed(d, Sdf.ValueTypeNames.Float3, {10.0: (float("nan"), 0.0, 0.0), 20.0: (0.0, 0.0, 0.0)})


def b_push_force_huge(d):
    return _pushed(d, Sdf.ValueTypeNames.Float3, {10.0: (1e7, 0.0, 0.0), 20.0: (0.0, 0.0, 0.0)})


def b_push_force_a_float(d):
    return _pushed(d, Sdf.ValueTypeNames.Float, {10.0: 150.0, 20.0: 0.0})


def b_push_force_blocked_sample(d):
    return _pushed(d, Sdf.ValueTypeNames.Float3, {10.0: (150.0, 0.0, 0.0), 15.0: Sdf.ValueBlock(), 20.0: (0.0, 0.0, 0.0)})


def b_physics_character_lying_down(d):
    def lay_down(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "xformOp:rotateX", Sdf.ValueTypeNames.Float).default = 90.0
        Sdf.AttributeSpec(root, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:rotateX"])
    return ["physics-model", str(edited(d, lay_down)), "--out", str(d / "body.xml")]


# -- stones, obstacles, objects and shot ranges of the physics body (a third sweep, 2026-12-06) ----

def _physics(d, author):
    return ["attend", str(edited(d, author)), "--physics", "--out", str(d / "gaze.usdc")]


def _defined(layer, path, type_name="Xform"):
    """A defined prim at ``path`` (its new ancestors defined too, as Xforms)."""
    prim = Sdf.CreatePrimInLayer(layer, path)
    p = prim
    while p and p.path != Sdf.Path.absoluteRootPath:
        if p.specifier != Sdf.SpecifierDef:
            p.specifier, p.typeName = Sdf.SpecifierDef, "Xform"
        p = p.nameParent
    if type_name:
        prim.typeName = type_name
    else:  # a typeless prim
        prim.ClearInfo("typeName")
    return prim


def _translated(prim, value, op="translate"):
    Sdf.AttributeSpec(prim, f"xformOp:{op}", Sdf.ValueTypeNames.Double3).default = value
    Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray([f"xformOp:{op}"])


def _task(where, kind="stone", type_name="Xform", sampled=False, at=None):
    """A ``usdgaze:physics:task`` on the prim ``where(rig)``."""
    def author(layer, r):
        path = where(r)
        prim = layer.GetPrimAtPath(path) or _defined(layer, path, type_name)
        task = Sdf.AttributeSpec(prim, "usdgaze:physics:task", Sdf.ValueTypeNames.Token)
        if sampled:
            layer.SetTimeSample(task.path, 0.0, kind)
        else:
            task.default = kind
        if at is not None:
            _translated(prim, at)
    return author


def b_physics_stone_without_transform(d):
    return _physics(d, _task(lambda r: "/Stones/A", type_name=""))


def b_physics_stone_inside_the_character(d):
    return _physics(d, _task(lambda r: r.skeleton))


def b_physics_obstacle_holds_the_character(d):
    return _physics(d, _task(lambda r: r.skel_root, kind="obstacle"))


def b_physics_task_time_sampled(d):
    return _physics(d, _task(lambda r: "/Stones/A", sampled=True, at=(0.3, 0.0, 0.4)))


def b_physics_stone_too_far(d):
    return _physics(d, _task(lambda r: "/Stones/A", at=(1e30, 0.0, 0.0)))


def b_physics_stone_transform_overflows(d):
    def author(layer, r):
        _task(lambda r: "/Stones/A", at=(1e300, 0.0, 0.0))(layer, r)
        _translated(layer.GetPrimAtPath("/Stones"), (1e300, 1e300, 1e300), op="scale")
    return _physics(d, author)


def b_physics_object_is_the_character(d):
    def author(layer, r):
        layer.GetPrimAtPath(r.skel_root).SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    return _physics(d, author)


def _range(start, end):
    def author(layer, r):
        layer.startTimeCode, layer.endTimeCode = start, end
    return author


def b_physics_range_outside_the_animation(d):
    return _physics(d, _range(500.0, 600.0))


def b_physics_range_one_frame(d):
    return _physics(d, _range(10.0, 10.0))


def b_physics_on_a_platform(d):
    def author(layer, r):  # the character stands 1 m up: on a raised floor the simulated ground is not
        _translated(layer.GetPrimAtPath(r.skel_root), (0.0, 1.0, 0.0))
    return _physics(d, author)


def b_push_joint_time_sampled(d):
    def author(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        joint = Sdf.AttributeSpec(root, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token)
        layer.SetTimeSample(joint.path, 0.0, r.leaf["spine_b"])
        Sdf.AttributeSpec(root, "usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3).default = (150.0, 0.0, 0.0)
    return _physics(d, author)


# -- sheets, farm jobs, obstacles and --map bindings (a fourth sweep, 2026-12-06) ------------------

def b_build_map_sheet_row_extra_cells(d):
    for name in ("a.c3d", "b.c3d"):
        (d / name).write_bytes(b"trial")
    # A decimal comma: "1,5" read as yaw 1 and pitch 5, the pitch cell dropped. The comment line makes
    # the row's number its line in the file (4), not its place among the trials (3).
    (d / "sheet.csv").write_text("file,yaw,pitch\n# degrees\na.c3d,0,0\nb.c3d,1,5,10\n")
    return ["build-map", str(d / "sheet.csv"), "--out", str(d / "map.usda")]


def b_batch_emit_missing_input(d):
    return manifest(d, '[[job]]\ninput = "nothere.usda"\nout = "gaze.usdc"\nshifts = ["0.5s:30:0"]\n',
                    "--emit", "slurm", str(d / "jobs"))


def b_batch_emit_missing_map(d):
    second = 'name = "two"\ninput = "in.usda"\nout = "gaze2.usdc"\nshifts = ["0.5s:30:0"]\nmap = "maps/nomap.usda"\n'
    return manifest(d, f"[[job]]\n{JOB}\n[[job]]\n{second}", "--emit", "deadline", str(d / "jobs"))


def _obstacle(radius):
    """An obstacle (a GazeObjectAPI sphere in front of the character) of ``gaze:object:radius`` ``radius``."""
    def author(layer, r):
        _task(lambda r: "/Obstacles/A", kind="obstacle", type_name="Sphere", at=(1.0, 0.0, 0.5))(layer, r)
        prim = layer.GetPrimAtPath("/Obstacles/A")
        prim.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
        Sdf.AttributeSpec(prim, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = radius
    return author


def b_physics_obstacle_radius_huge(d):
    return _physics(d, _obstacle(1e6))


def b_physics_obstacle_radius_zero(d):
    return _physics(d, _obstacle(0.0))


def b_map_binding_absent_joint(d):
    from .bad_common import map_edit

    return map_edit(d, "gaze:binding:head", Vt.TokenArray(["Skull"]))


def b_push_on_the_skeleton(d):
    def author(layer, r):
        skel = layer.GetPrimAtPath(r.skeleton)
        Sdf.AttributeSpec(skel, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
        force = Sdf.AttributeSpec(skel, "usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3)
        layer.SetTimeSample(force.path, 10.0, (150.0, 0.0, 0.0))
        layer.SetTimeSample(force.path, 20.0, (0.0, 0.0, 0.0))
    return _physics(d, author)


def b_push_on_the_skelroot_parent(d):
    def author(layer, r):  # read on the SkelRoot only: on its parent it was ignored (exit 0, "pushes": 0)
        parent = layer.GetPrimAtPath("/World")
        Sdf.AttributeSpec(parent, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
        Sdf.AttributeSpec(parent, "usdgaze:physics:pushForce", Sdf.ValueTypeNames.Float3).default = (150.0, 0.0, 0.0)
    return ["attend", str(edited(d, author, root_path="/World/Character")), "--physics", "--out", str(d / "gaze.usdc")]


def b_push_force_misspelled(d):
    def author(layer, r):  # "pushforce": the push was left out (exit 0, "pushes": 0)
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
        Sdf.AttributeSpec(root, "usdgaze:physics:pushforce", Sdf.ValueTypeNames.Float3).default = (150.0, 0.0, 0.0)
    return _physics(d, author)


def b_push_joint_without_force(d):
    def author(layer, r):
        root = layer.GetPrimAtPath(r.skel_root)
        Sdf.AttributeSpec(root, "usdgaze:physics:pushJoint", Sdf.ValueTypeNames.Token).default = r.leaf["spine_b"]
    return _physics(d, author)


def _review_of_a_broken_input(d, *command):
    """An input whose sublayer is missing, reviewed with an override layer (USD's own warning about the
    sublayer went to stderr as a second line before)."""
    Sdf.Layer.CreateNew(str(d / "gaze.usda")).Save()
    return [command[0], str(edited(d, _sublayer)), "--layer", str(d / "gaze.usda"), *command[1:]]


def b_plot_input_missing_sublayer(d):
    return _review_of_a_broken_input(d, "plot", "--out", str(d / "plots"))


def b_preview_input_missing_sublayer(d):
    return _review_of_a_broken_input(d, "preview", "--out", str(d / "review.gif"))


def b_validate_layer_input_missing_sublayer(d):
    return _review_of_a_broken_input(d, "validate")
