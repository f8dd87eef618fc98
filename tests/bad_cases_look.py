"""Catalogue builders: look-at targets, directive syntax and range, GazeScheduleAPI schedules."""

from __future__ import annotations

from pathlib import Path

from pxr import Sdf, Vt

from . import measure
from .bad_common import apply_argv, edited, rig


def _with_prims(d: Path, **kw) -> Path:
    """The rig plus look-at targets: an animated Xform /World/Ball and a typeless /World/Note."""
    def add(layer, rig):
        ball = Sdf.CreatePrimInLayer(layer, "/World/Ball")
        ball.specifier, ball.typeName = Sdf.SpecifierDef, "Xform"
        Sdf.CreatePrimInLayer(layer, "/World").specifier = Sdf.SpecifierDef
        note = Sdf.CreatePrimInLayer(layer, "/World/Note")
        note.specifier = Sdf.SpecifierDef
    return edited(d, add, **kw)


def _with_schedule(d: Path, **arrays) -> Path:
    """The rig with GazeScheduleAPI on its SkelRoot and the given gaze:schedule:* arrays."""
    types = {"time": Sdf.ValueTypeNames.DoubleArray, "kind": Sdf.ValueTypeNames.TokenArray,
             "target": Sdf.ValueTypeNames.IntArray, "weight": Sdf.ValueTypeNames.FloatArray}

    def schedule(layer, rig):
        prim = layer.GetPrimAtPath(rig.skel_root)
        op = Sdf.TokenListOp()
        op.prependedItems = ["GazeScheduleAPI"]
        prim.SetInfo("apiSchemas", op)
        for name, value in arrays.items():
            attr = Sdf.AttributeSpec(prim, f"gaze:schedule:{name}", types[name], Sdf.VariabilityUniform)
            attr.default = value
    return edited(d, schedule)


def b_look_at_missing_prim(d):
    return apply_argv(d, rig(d).path, shifts=["--look-at", "/World/Door@10"])


def b_look_at_not_xformable(d):
    return apply_argv(d, _with_prims(d), shifts=["--look-at", "/World/Note@10"])


def _with_instancer(layer, rig):
    """/World/PI, a PointInstancer with one instance of its prototype /World/PI/Protos/Rock (a Cube)."""
    Sdf.CreatePrimInLayer(layer, "/World").specifier = Sdf.SpecifierDef
    for path, type_name in (("/World/PI", "PointInstancer"), ("/World/PI/Protos", "Scope"),
                            ("/World/PI/Protos/Rock", "Cube")):
        prim = Sdf.CreatePrimInLayer(layer, path)
        prim.specifier, prim.typeName = Sdf.SpecifierDef, type_name
    pi = layer.GetPrimAtPath("/World/PI")
    Sdf.RelationshipSpec(pi, "prototypes", custom=False).targetPathList.explicitItems = [Sdf.Path("/World/PI/Protos/Rock")]
    Sdf.AttributeSpec(pi, "protoIndices", Sdf.ValueTypeNames.IntArray).default = Vt.IntArray([0])
    Sdf.AttributeSpec(pi, "positions", Sdf.ValueTypeNames.Point3fArray).default = Vt.Vec3fArray([(-1.5, 1.7, 3.0)])


def b_look_at_prototype(d):
    return apply_argv(d, edited(d, _with_instancer), shifts=["--look-at", "/World/PI/Protos/Rock@10"])


def b_look_at_malformed(d):
    return apply_argv(d, rig(d).path, shifts=["--look-at", "/World/Door"])


def b_look_at_weight_out_of_range(d):
    return apply_argv(d, rig(d).path, shifts=["--look-at", "0,1.6,3@10:weight=1.5"])


def b_look_at_the_eyes(d):
    r = rig(d)
    p = measure.posed(str(r.path), r.skeleton)
    left, right = r.eye_leaves
    eyes = 0.5 * (p.position(left)[0] + p.position(right)[0])
    return apply_argv(d, r.path, shifts=["--look-at", ",".join(repr(float(v)) for v in eyes) + "@0"])


def b_directive_outside_animation(d):
    return apply_argv(d, rig(d).path, shifts=["--look-at", "0,1.6,3@99s"])


def b_release_bad_option(d):
    return apply_argv(d, rig(d).path, shifts=["--release", "10:weight=0"])


def b_schedule_unequal_arrays(d):
    return apply_argv(d, _with_schedule(d, time=Vt.DoubleArray([10.0]), kind=Vt.TokenArray(["look", "shift"])), shifts=[])


def b_schedule_bad_kind(d):
    return apply_argv(d, _with_schedule(d, time=Vt.DoubleArray([10.0]), kind=Vt.TokenArray(["stare"])), shifts=[])


def b_schedule_target_index(d):
    return apply_argv(d, _with_schedule(d, time=Vt.DoubleArray([10.0]), kind=Vt.TokenArray(["look"]),
                                    target=Vt.IntArray([3])), shifts=[])


def b_two_shifts_one_frame(d):
    # At 120.48 time codes per second 2 s is time code 240.96: 0.3 ms before 241, both start on frame 241.
    return apply_argv(d, rig(d, time_codes_per_second=120.48, frames=300).path,
                      shifts=["--shift", "241:60:0", "--shift", "2s:10:0"])


def b_look_and_release_one_frame(d):
    # Time codes 10.2 and 10.7 fall between frames 10 and 11: both start on frame 11.
    return apply_argv(d, rig(d).path, shifts=["--look-at", "0,1.6,3@10.2", "--release", "10.7"])


def b_schedule_directives_one_frame(d):
    return apply_argv(d, _with_schedule(d, time=Vt.DoubleArray([10.2, 10.7]), kind=Vt.TokenArray(["release", "release"])),
                      shifts=[])


def b_shift_yaw_not_a_number(d):
    return apply_argv(d, rig(d).path, shifts=["--shift", "5s:abc:0"])


def b_look_at_time_not_a_time(d):
    return apply_argv(d, rig(d).path, shifts=["--look-at", "0,1.6,3@soon"])


def b_release_blend_not_a_time(d):
    return apply_argv(d, rig(d).path, shifts=["--release", "10:blend=long"])
