"""Catalogue builders for what a later sweep found (2026-12-06): rigs the physics body cannot stand,
a marker set or stage whose up axis is not the capture's."""

from __future__ import annotations

from pxr import Sdf, Usd, UsdSkel, Vt

from .bad_common import edited, rig


def _without(path, words: tuple[str, ...]) -> None:
    """Drop every joint whose name holds one of ``words`` (and its row in every per-joint array)."""
    stage = Usd.Stage.Open(str(path))
    for prim in stage.Traverse():
        if prim.IsA(UsdSkel.Skeleton) or prim.IsA(UsdSkel.Animation):
            joints = [str(j) for j in prim.GetAttribute("joints").Get()]
            keep = [i for i, j in enumerate(joints) if not any(w in j.rsplit("/", 1)[-1] for w in words)]
            for attr in prim.GetAttributes():
                samples = attr.GetTimeSamples() or [Usd.TimeCode.Default()]
                for t in samples:
                    value = attr.Get(t)
                    if isinstance(value, (Vt.TokenArray, Vt.Matrix4dArray, Vt.QuatfArray, Vt.Vec3fArray, Vt.Vec3hArray)) \
                            and len(value) == len(joints):
                        attr.Set(type(value)([value[i] for i in keep]), t)
    stage.Save()


def b_physics_rig_without_feet(d):
    r = rig(d)
    _without(r.path, ("Foot", "Toe"))
    return ["physics-model", str(r.path), "--out", str(d / "body.xml")]


def b_physics_legs_from_a_root_on_the_ground(d):
    """``root > {pelvis, thigh_l, thigh_r}``, the root on the ground at rest (UE's): the legs hang beside the pelvis."""
    r = rig(d, convention="ue", legs_on="root")
    return ["physics-model", str(r.path), "--out", str(d / "body.xml")]


def b_sublayer_into_a_shot_that_references_elsewhere(d):
    """A shot layer that references the character at /Hero, not at the input's /Character."""
    r = rig(d)
    (d / "shot.usda").write_text('#usda 1.0\ndef "Hero" (references = @./in.usda@</Character>) {}\n')
    return ["apply", str(r.path), "--shift", "10:30:0", "--out", str(d / "gaze.usdc"),
            "--sublayer-into", str(d / "shot.usda")]


def b_sublayer_into_a_shot_that_references_at_an_offset(d):
    """A shot layer that references the character at its own path, 10 time codes later."""
    r = rig(d)
    (d / "shot.usda").write_text('#usda 1.0\ndef "Character" (references = @./in.usda@</Character> (offset = 10)) {}\n')
    return ["apply", str(r.path), "--shift", "10:30:0", "--out", str(d / "gaze.usdc"),
            "--sublayer-into", str(d / "shot.usda")]


def b_look_at_its_own_skeleton(d):
    r = rig(d)
    return ["apply", str(r.path), "--look-at", f"{r.skeleton}@10", "--out", str(d / "gaze.usdc")]


def b_look_at_a_prim_under_its_skeleton(d):
    """A marker Xform authored under the Skeleton prim (it moves with the skeleton's space)."""
    def author(layer, r):
        marker = Sdf.CreatePrimInLayer(layer, r.skeleton + "/Marker")
        marker.specifier, marker.typeName = Sdf.SpecifierDef, "Xform"
    src = edited(d, author)
    return ["apply", str(src), "--look-at", "/Character/Skel/Marker@10", "--out", str(d / "gaze.usdc")]


def _into_shot_over(d, name: str, text: str, out: str) -> list[str]:
    """``apply --sublayer-into shot.usda``, the shot sublayering [``name`` (holding ``text``), in.usda]."""
    r = rig(d)
    (d / name).write_text(text)
    (d / "shot.usda").write_text(f'#usda 1.0\n(\n    subLayers = [@./{name}@, @./in.usda@]\n)\n')
    return ["apply", str(r.path), "--shift", "10:30:0", "--out", str(d / out), "--sublayer-into", str(d / "shot.usda")]


def b_out_is_a_layer_the_sublayer_root_composes(d):
    """``--out set.usda`` where ``shot.usda`` sublayers [set.usda, in.usda]: the set dressing was replaced."""
    return _into_shot_over(d, "set.usda", '#usda 1.0\ndef Xform "Set" {}\n', out="set.usda")


def b_look_at_an_ill_formed_prim_path(d):
    """USD's own warning about the path had come first, a second line on stderr."""
    r = rig(d)
    return ["apply", str(r.path), "--look-at", "/World/Do or@10", "--out", str(d / "gaze.usdc")]


def b_sublayer_into_a_shot_with_a_broken_sublayer(d):
    """Another sublayer of the shot does not parse (it was said not to compose the input at all)."""
    return _into_shot_over(d, "broken.usda", '#usda 1.0\ndef Xform "A" { garbage }\n', out="gaze.usdc")


def b_out_is_a_dangling_link_into_a_missing_folder(d):
    """The link's own folder exists: "folder . does not exist" named the wrong one."""
    r = rig(d)
    (d / "gaze.usdc").symlink_to(d / "missing" / "x.usdc")
    return ["apply", str(r.path), "--shift", "10:30:0", "--out", str(d / "gaze.usdc")]


def b_build_map_marker_set_up_axis_not_the_captures(d):
    """A Y-up capture read with the default up_axis Z: stored 'ok', exit 0."""
    import numpy as np

    from . import ingest_synth as syn

    motion = syn.known_motions(np.array([[72.0, 0.0]]))[0]
    points, _ = syn.simulate_trial(motion, np.random.default_rng(0))
    syn.write_points(d / "a.c3d", syn.LABELS, points[..., [0, 2, 1]] * np.array([1.0, 1.0, -1.0]), syn.RATE)
    (d / "markers.toml").write_text(syn.MARKERSET_TOML)
    (d / "sheet.csv").write_text("file,yaw,pitch\na.c3d,72,0\n")
    return ["build-map", str(d / "sheet.csv"), "--markers", str(d / "markers.toml"), "--out", str(d / "map.usda"),
            "--min-trials", "1", "--quiet"]


def b_build_map_clip_stage_up_axis_not_the_rigs(d):
    """A Z-up UsdSkel clip in a stage that says upAxis Y (an export without axis conversion): stored 'ok', exit 0."""
    import numpy as np

    from . import ingest_synth as syn

    motion = syn.known_motions(np.array([[72.0, 0.0]]))[0]
    syn.write_skel_clip(d / "a.usda", motion, 30, 120)
    stage = Usd.Stage.Open(str(d / "a.usda"))
    stage.SetMetadata("upAxis", "Y")
    stage.Save()
    (d / "sheet.toml").write_text('[[trial]]\nfile = "a.usda"\nyaw = 72\npitch = 0\n')
    return ["build-map", str(d / "sheet.toml"), "--out", str(d / "map.usda"), "--min-trials", "1", "--quiet"]


def b_build_map_c3d_label_twice(d):
    """Two trajectories labelled HLF (the last one was taken without a word)."""
    import numpy as np

    from . import ingest_synth as syn

    motion = syn.known_motions(np.array([[72.0, 0.0]]))[0]
    points, _ = syn.simulate_trial(motion, np.random.default_rng(0))
    labels = list(syn.LABELS) + ["HLF"]
    syn.write_points(d / "a.c3d", labels, np.concatenate([points, points[:, :1]], axis=1), syn.RATE)
    (d / "markers.toml").write_text(syn.MARKERSET_TOML)
    (d / "sheet.csv").write_text("file,yaw,pitch\na.c3d,72,0\n")
    return ["build-map", str(d / "sheet.csv"), "--markers", str(d / "markers.toml"), "--out", str(d / "map.usda"),
            "--min-trials", "1", "--quiet"]
