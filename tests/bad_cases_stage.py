"""Catalogue builders: stage metadata, non-finite and singular values, wrong types, instancing."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Vt

from .bad_common import apply_argv, edited, quats, remove, retype, rig, set_sample

T = Sdf.ValueTypeNames


def _meta(key: str, value):
    def edit(layer, r):
        layer.pseudoRoot.SetInfo(key, value)
    return edit


def b_up_axis_x(d):
    return apply_argv(d, edited(d, _meta("upAxis", "X")))


def b_up_axis_garbage(d):
    return apply_argv(d, edited(d, _meta("upAxis", "up")))


def b_meters_per_unit_zero(d):
    return apply_argv(d, edited(d, _meta("metersPerUnit", 0.0)))


def b_meters_per_unit_negative(d):
    return apply_argv(d, edited(d, _meta("metersPerUnit", -0.01)))


def b_meters_per_unit_nan(d):
    return apply_argv(d, edited(d, _meta("metersPerUnit", float("nan"))))


def b_meters_per_unit_inf(d):
    return apply_argv(d, edited(d, _meta("metersPerUnit", float("inf"))))


def b_time_codes_per_second_zero(d):
    return apply_argv(d, edited(d, lambda layer, r: setattr(layer, "timeCodesPerSecond", 0.0)))


def b_time_codes_per_second_negative(d):
    return apply_argv(d, edited(d, lambda layer, r: setattr(layer, "timeCodesPerSecond", -24.0)))


def b_frames_per_second_zero(d):
    return apply_argv(d, edited(d, lambda layer, r: setattr(layer, "framesPerSecond", 0.0)))


def b_inspect_up_axis_x(d):
    return ["inspect", str(edited(d, _meta("upAxis", "X")))]


def _vec3(r, value, half=False):
    a = np.ones((len(r.anim_joints), 3), dtype=np.float16 if half else np.float32)
    a[len(a) // 2] = value
    return (Vt.Vec3hArray if half else Vt.Vec3fArray).FromNumpy(a)


def b_nan_translations(d):
    return apply_argv(d, edited(d, lambda layer, r: set_sample(layer, r, "translations", _vec3(r, np.nan))))


def b_inf_translations(d):
    return apply_argv(d, edited(d, lambda layer, r: set_sample(layer, r, "translations", _vec3(r, np.inf))))


def b_nan_scales(d):
    return apply_argv(d, edited(d, lambda layer, r: set_sample(layer, r, "scales", _vec3(r, np.nan, half=True))))


def b_inf_scales(d):
    return apply_argv(d, edited(d, lambda layer, r: set_sample(layer, r, "scales", _vec3(r, np.inf, half=True))))


def b_inf_rotations(d):
    def edit(layer, r):
        q = np.array(quats(len(r.anim_joints)))
        q[2] = np.inf
        set_sample(layer, r, "rotations", Vt.QuatfArray.FromNumpy(q.astype(np.float32)))
    return apply_argv(d, edited(d, edit))


def b_rotations_not_unit(d):
    def edit(layer, r):
        q = np.array(quats(len(r.anim_joints))) * 2.0
        set_sample(layer, r, "rotations", Vt.QuatfArray.FromNumpy(q.astype(np.float32)))
    return apply_argv(d, edited(d, edit))


def b_rotations_blocked_sample(d):
    """A blocked sample among the rotations (UsdSkel poses the rest pose there): it was said to hold
    "0 entries", as if an empty array had been authored."""
    return apply_argv(d, edited(d, lambda layer, r: set_sample(layer, r, "rotations", Sdf.ValueBlock())))


def _matrix_edit(name: str, index: int, value):
    def edit(layer, r):
        spec = layer.GetAttributeAtPath(f"{r.skeleton}.{name}")
        mats = [Gf.Matrix4d(m) for m in spec.default]
        m = np.array(mats[index])
        if value == "singular":
            m[:3, :3] = 0.0
        else:
            m[3, 0] = value
        mats[index] = Gf.Matrix4d(m.tolist())
        spec.default = Vt.Matrix4dArray(mats)
    return edit


def b_nan_rest_transforms(d):
    return apply_argv(d, edited(d, _matrix_edit("restTransforms", 3, float("nan"))))


def b_inf_rest_transforms(d):
    return apply_argv(d, edited(d, _matrix_edit("restTransforms", 3, float("inf"))))


def b_nan_bind_transforms(d):
    return apply_argv(d, edited(d, _matrix_edit("bindTransforms", 4, float("nan"))))


def b_inf_bind_transforms(d):
    return apply_argv(d, edited(d, _matrix_edit("bindTransforms", 4, float("-inf"))))


def b_singular_bind_transform(d):
    return apply_argv(d, edited(d, _matrix_edit("bindTransforms", 5, "singular")))


def b_singular_rest_transform(d):
    return apply_argv(d, edited(d, _matrix_edit("restTransforms", 5, "singular")))


def _anim_retype(name: str, type_name, width: int, vt):
    def edit(layer, r):
        path = Sdf.Path(f"{r.animation}.{name}")
        times = layer.ListTimeSamplesForPath(path)
        retype(layer, str(path), type_name, None)
        row = np.ones((len(r.anim_joints), width))
        for t in times:
            layer.SetTimeSample(path, t, vt.FromNumpy(row.astype(np.float32 if vt is not Vt.Vec3dArray else float)))
    return edit


def b_rotations_authored_as_float3(d):
    return apply_argv(d, edited(d, _anim_retype("rotations", T.Float3Array, 3, Vt.Vec3fArray)))


def b_rotations_authored_as_float4(d):
    return apply_argv(d, edited(d, _anim_retype("rotations", T.Float4Array, 4, Vt.Vec4fArray)))


def b_translations_authored_as_double3(d):
    return apply_argv(d, edited(d, _anim_retype("translations", T.Double3Array, 3, Vt.Vec3dArray)))


def b_scales_authored_as_float3(d):
    return apply_argv(d, edited(d, _anim_retype("scales", T.Float3Array, 3, Vt.Vec3fArray)))


def b_animation_joints_authored_as_strings(d):
    def edit(layer, r):
        retype(layer, f"{r.animation}.joints", T.StringArray, Vt.StringArray(list(r.anim_joints)))
    return apply_argv(d, edited(d, edit))


def b_skeleton_joints_authored_as_strings(d):
    def edit(layer, r):
        retype(layer, f"{r.skeleton}.joints", T.StringArray, Vt.StringArray(list(r.joints)))
    return apply_argv(d, edited(d, edit))


def b_rest_transforms_authored_as_floats(d):
    def edit(layer, r):
        retype(layer, f"{r.skeleton}.restTransforms", T.FloatArray, Vt.FloatArray([1.0] * 16 * len(r.joints)))
    return apply_argv(d, edited(d, edit))


def b_bind_transforms_authored_as_matrix3d(d):
    def edit(layer, r):
        retype(layer, f"{r.skeleton}.bindTransforms", T.Matrix3dArray, Vt.Matrix3dArray([Gf.Matrix3d(1)] * len(r.joints)))
    return apply_argv(d, edited(d, edit))


def b_joint_names_authored_as_ints(d):
    def edit(layer, r):
        retype(layer, f"{r.skeleton}.jointNames", T.IntArray, Vt.IntArray(list(range(len(r.joints)))))
    return apply_argv(d, edited(d, edit))


def b_instanceable_skelroot(d):
    rig(d, "char.usda")
    (d / "in.usda").write_text('#usda 1.0\n(\n    timeCodesPerSecond = 60\n)\n\n'
                               'def "Character" (\n    instanceable = true\n    references = @./char.usda@</Character>\n)\n{\n}\n')
    return apply_argv(d, d / "in.usda")


def _crowd(d):
    """A crowd member that is an instance of a group holding the character: the character is a proxy."""
    rig(d, "char.usda")
    (d / "group.usda").write_text('#usda 1.0\n\ndef Xform "Group"\n{\n'
                                  '    def "Character" (\n        references = @./char.usda@</Character>\n    )\n    {\n    }\n}\n')
    (d / "in.usda").write_text('#usda 1.0\n(\n    timeCodesPerSecond = 60\n)\n\ndef Xform "Crowd"\n{\n'
                               '    def Xform "Member" (\n        instanceable = true\n'
                               '        references = @./group.usda@</Group>\n    )\n    {\n    }\n}\n')


def b_character_inside_an_instance(d):
    _crowd(d)
    return apply_argv(d, d / "in.usda")


def b_skel_root_option_inside_an_instance(d):
    _crowd(d)
    return apply_argv(d, d / "in.usda", "--skel-root", "/Crowd/Member/Character")


def b_translations_length_not_joints(d):
    return apply_argv(d, edited(d, lambda layer, r: set_sample(
        layer, r, "translations", Vt.Vec3fArray.FromNumpy(np.zeros((2, 3), np.float32)))))


def b_scales_length_not_joints(d):
    return apply_argv(d, edited(d, lambda layer, r: set_sample(
        layer, r, "scales", Vt.Vec3hArray.FromNumpy(np.ones((len(r.anim_joints) + 1, 3), np.float16)))))


def b_rotations_missing(d):
    return apply_argv(d, edited(d, lambda layer, r: remove(layer, r.animation + ".rotations")))


def b_translations_missing(d):
    return apply_argv(d, edited(d, lambda layer, r: remove(layer, r.animation + ".translations")))


def b_animation_joints_empty(d):
    return apply_argv(d, edited(d, lambda layer, r: setattr(layer.GetAttributeAtPath(r.animation + ".joints"),
                                                            "default", Vt.TokenArray([]))))


def b_bind_transforms_count(d):
    def short(layer, r):
        spec = layer.GetAttributeAtPath(r.skeleton + ".bindTransforms")
        spec.default = Vt.Matrix4dArray(list(spec.default)[:-1])
    return apply_argv(d, edited(d, short))


def b_input_map_samples_huge(d):
    def huge(layer, r):
        from usdgaze.gaze.defaults import default_definition
        from usdgaze.usd import schema
        from pxr import Usd

        stage = Usd.Stage.Open(layer)
        schema.write_map(stage.GetPrimAtPath(r.skel_root), default_definition())
        layer.GetAttributeAtPath(f"{r.skel_root}.gaze:synthesis:samples").default = 2_000_000_000
    return apply_argv(d, edited(d, huge))
