"""``usdgaze attend`` with GazeObjectAPI attributes as a layout artist's DCC writes them: radius and kind
are uniform (one value for the shot), but an export often writes them as time samples. USD's value at
the default time is then the schema's fallback (0.1 m, no kind), so before, a sampled "ballistic" was
read as no kind and a sampled negative radius went through. Now equal samples are that value, and
samples that differ are one line naming the prim and attribute, exit 2."""

from __future__ import annotations

from pathlib import Path

from pxr import Gf, Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

ATTEND = Path(__file__).resolve().parents[1] / "sample_stages" / "attend"
FPS = 120.00479955795427


def _stage(path: Path, radius=None, kind=None, sampled: bool = False) -> Path:
    """The standing clip and one ball thrown towards the character; radius/kind as a default or as samples."""
    layer = Sdf.Layer.CreateNew(str(path))
    layer.startTimeCode, layer.endTimeCode = 1, 241
    layer.timeCodesPerSecond = layer.framesPerSecond = FPS
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    layer.subLayerPaths[:] = [str(ATTEND / "standing.usdc"), str(ATTEND.parent / "cmu" / "cmu_131_01.usdc")]
    Sdf.CreatePrimInLayer(layer, "/Objects").specifier = Sdf.SpecifierDef
    ball = Sdf.CreatePrimInLayer(layer, "/Objects/Ball")
    ball.specifier, ball.typeName = Sdf.SpecifierDef, "Sphere"
    ball.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
    tr = Sdf.AttributeSpec(ball, "xformOp:translate", Sdf.ValueTypeNames.Double3)
    for f in range(1, 242, 8):  # from 6 m ahead and to the left, falling under gravity
        t = (f - 1) / FPS
        layer.SetTimeSample(tr.path, f, Gf.Vec3d(2.0 - 1.2 * t, 1.6 + 3.0 * t - 4.905 * t * t, 4.0 - 3.5 * t))
    Sdf.AttributeSpec(ball, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      variability=Sdf.VariabilityUniform).default = ["xformOp:translate"]
    for name, type_name, value in (("gaze:object:radius", Sdf.ValueTypeNames.Float, radius),
                                   ("gaze:object:kind", Sdf.ValueTypeNames.Token, kind)):
        if value is None:
            continue
        attr = Sdf.AttributeSpec(ball, name, type_name)
        if not sampled:
            attr.default = value
            continue
        values = value if isinstance(value, list) else [value, value]
        for f, v in zip((1, 121), values):
            layer.SetTimeSample(attr.path, f, v)
    layer.Save()
    return path


def test_a_uniform_attribute_written_as_equal_samples_is_that_value(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    plain = _stage(tmp_path / "a" / "shot.usda", radius=0.25, kind="ballistic")
    sampled = _stage(tmp_path / "b" / "shot.usda", radius=0.25, kind="ballistic", sampled=True)
    for stage in (plain, sampled):
        assert main(["attend", str(stage), "--out", str(stage.parent / "out.usda")]) == 0
    # the same ball, the same belief, the same layer (the input's file name is the same too)
    assert (tmp_path / "a" / "out.usda").read_bytes() == (tmp_path / "b" / "out.usda").read_bytes()


def test_uniform_attribute_samples_that_differ_are_one_line(tmp_path, capsys):
    for i, (radius, kind, attr) in enumerate((([0.2, -1.0], None, "gaze:object:radius"),
                                              (None, ["ballistic", "bouncy"], "gaze:object:kind"))):
        stage = _stage(tmp_path / f"shot{i}.usda", radius=radius, kind=kind, sampled=True)
        out = tmp_path / f"out{i}.usda"
        assert main(["attend", str(stage), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"/Objects/Ball.{attr}" in err[0], err
        assert not out.exists()


def test_no_eye_turns_faster_than_800_deg_s_on_a_near_object(tmp_path):
    """The planner bounds the eyes' common (cyclopean) direction at 800 deg/s; vergence on an object
    20 cm away took one eye to 856 deg/s on top of it. Each eye, by UsdSkel FK on the written layer."""
    import numpy as np
    from pxr import Sdf

    from tests import measure
    from tests.attend_support import ATTEND, compose

    from usdgaze.console.main import main

    rate = Sdf.Layer.FindOrOpen(str(ATTEND / "ball_throw.usda")).timeCodesPerSecond
    at = (0.30673, 1.32057, -1.66412)  # 20 cm from the standing character's eyes, low and to its right
    inp = _stage_with(tmp_path, [("/Objects/Near", at, 1.0, None, 0.02)])
    fwd = measure.character_forward_skel(measure.posed(str(inp), "/root/Body/BodySkel"), "LeftHip", "RightHip")
    out = tmp_path / "gaze.usda"
    assert main(["attend", str(inp), "--out", str(out)]) == 0
    new = measure.posed(str(compose(tmp_path, inp, out)), "/root/Body/BodySkel")
    up = np.linalg.solve(new.skel_to_world[:3, :3].T, new.up)
    for eye in ("LeftEye", "RightEye"):
        yaw, pitch = measure.eye_in_head(new, "Head", eye, fwd, np.cross(up, fwd), up)
        y, p = np.radians(yaw), np.radians(pitch)
        d = np.stack([np.cos(p) * np.cos(y), np.cos(p) * np.sin(y), np.sin(p)], -1)
        step = np.degrees(np.arccos(np.clip((d[1:] * d[:-1]).sum(-1), -1, 1)))
        speed = step / np.diff(new.times) * float(rate)
        assert speed.max() <= 800.0 * 1.02, (eye, speed.max())



def _stage_with(tmp_path, objects):
    """The standing sample's character and ``objects``: (path, position, importance, visibility samples
    or None[, an authored radius])."""
    from pxr import Sdf

    from tests.attend_support import ATTEND

    src = Sdf.Layer.FindOrOpen(str(ATTEND / "ball_throw.usda"))
    inp = tmp_path / "objects.usda"
    layer = Sdf.Layer.CreateNew(str(inp))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        setattr(layer, key, getattr(src, key))
    for key in ("upAxis", "metersPerUnit", "defaultPrim"):
        layer.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    layer.subLayerPaths[:] = [str(ATTEND / "standing.usdc"), str(ATTEND.parent / "cmu" / "cmu_131_01.usdc")]
    group = Sdf.CreatePrimInLayer(layer, "/Objects")
    group.specifier, group.typeName = Sdf.SpecifierDef, "Xform"
    for path, at, importance, shown, *sized in objects:
        ball = Sdf.CreatePrimInLayer(layer, path)
        ball.specifier, ball.typeName = Sdf.SpecifierDef, "Sphere"
        ball.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["GazeObjectAPI"]))
        Sdf.AttributeSpec(ball, "gaze:object:importance", Sdf.ValueTypeNames.Float).default = importance
        Sdf.AttributeSpec(ball, "radius", Sdf.ValueTypeNames.Double).default = sized[0] if sized else 0.1
        if sized:
            Sdf.AttributeSpec(ball, "gaze:object:radius", Sdf.ValueTypeNames.Float).default = sized[0]
        Sdf.AttributeSpec(ball, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform).default = ["xformOp:translate"]
        Sdf.AttributeSpec(ball, "xformOp:translate", Sdf.ValueTypeNames.Double3).default = at
        if shown:
            vis = Sdf.AttributeSpec(ball, "visibility", Sdf.ValueTypeNames.Token, Sdf.VariabilityVarying)
            for t, token in shown:
                layer.SetTimeSample(vis.path, t, token)
    layer.Save()
    return inp


def test_an_object_is_not_seen_while_it_is_invisible(tmp_path):
    """Visibility was not read: a prop hidden the whole shot was fixated on 92% of its frames, and one
    shown at 1 s was looked at from its first frame. Measured by UsdSkel FK: the angle between each
    eye's line of sight and the object, against 2 deg."""
    import numpy as np

    from tests import measure
    from tests.attend_support import compose

    from usdgaze.console.main import main

    shown_at = 121.0  # 1 s in
    # 2 m ahead of the standing character's head: 20 deg left and 10 down; 20 right; 30 right, 5 up.
    hidden, late = (-0.0057, 1.3553, 0.115), (-0.3417, 1.5296, 0.0242)
    inp = _stage_with(tmp_path, [("/Objects/A", (1.321, 1.008, -0.175), 1.0, None),
                                 ("/Objects/Hidden", hidden, 5.0, [(1.0, "invisible")]),
                                 ("/Objects/Late", late, 5.0, [(1.0, "invisible"), (shown_at, "inherited")])])
    out = tmp_path / "gaze.usda"
    assert main(["attend", str(inp), "--out", str(out)]) == 0
    new = measure.posed(str(compose(tmp_path, inp, out)), "/root/Body/BodySkel")
    fwd = measure.character_forward_skel(new, "LeftHip", "RightHip")
    looked = {}
    for name, at in (("Hidden", hidden), ("Late", late)):
        miss = []
        for eye in ("LeftEye", "RightEye"):
            to = np.asarray(at) - new.position(eye)
            to /= np.linalg.norm(to, axis=-1, keepdims=True)
            miss.append(measure.angle_between(new.axis(eye, measure.local_forward(new, eye, fwd)), to))
        on = np.maximum(*miss) < 2.0
        unseen = np.ones(len(new.times), bool) if name == "Hidden" else new.times < shown_at
        assert not on[unseen].any(), (name, new.times[unseen & on][:5])
        looked[name] = on
    assert looked["Late"][new.times >= shown_at].any()  # once shown, it is looked at
