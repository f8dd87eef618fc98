"""GazeMapAPI: plugin registration, generated files, storage round trips, malformed maps, sharing."""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from usdgaze.usd import plugin as _plugin

_plugin.register()  # until usdgaze/__init__.py does it

from pxr import Gf, Sdf, Usd, Vt  # noqa: E402

from usdgaze.gaze import motion  # noqa: E402
from usdgaze.errors import UsdGazeError  # noqa: E402
from usdgaze.core import rotations as rot  # noqa: E402
from usdgaze.usd import schema  # noqa: E402
from usdgaze.gaze.definition import (  # noqa: E402
    BINDING_ATTRS,
    EXAMPLE_ATTRS,
    FORWARD_ATTR,
    SETTING_ATTRS,
    GazeMapDefinition,
    SynthesisSettings,
    validate,
)
from usdgaze.errors import GazeMapError  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCHEMAS = REPO / "schemas"
SHARED = REPO / "sample_stages" / "shared_map"


def make_definition(n: int = 4, seed: int = 0, **changes) -> GazeMapDefinition:
    """``n`` examples on a yaw line with random (but consistent: eyes aimed) offsets."""
    rng = np.random.default_rng(seed)
    params = np.column_stack([np.linspace(-150.0, 150.0, n), rng.uniform(-30.0, 30.0, n)])
    body = rot.normalize(rot.identity((n, 4)) + rng.normal(scale=0.1, size=(n, 4, 4)))
    eyes = motion.aim_eyes(body, params[:, 0], params[:, 1])
    offsets = np.concatenate([body, eyes[:, None, :]], axis=1)
    timing = np.column_stack(
        [rng.uniform(0.2, 1.0, n), rng.uniform(0.0, 0.5, (n, 4)), rng.uniform(0.5, 0.9, n), rng.uniform(0.0, 0.3, n)]
    )
    fields = dict(
        params=params,
        motions=motion.GazeMotions(offsets, timing),
        settings=SynthesisSettings(samples=500, blend_size=3, neighbors=4, refine=2, seed=7, neck_share=0.3),
        bindings={"head": ("Hips/Spine/Neck/Head",), "neck": ("Hips/Spine/Neck", "Hips/Spine/Neck/Neck1")},
        forward=(0.0, 0.0, 1.0),
    )
    fields.update(changes)
    return GazeMapDefinition(**fields)


def f32(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=np.float32)


def assert_same_map(a: GazeMapDefinition, b: GazeMapDefinition) -> None:
    """Equal as stored: float arrays to the float32 bit, everything else exactly."""
    np.testing.assert_array_equal(f32(a.params), f32(b.params))
    np.testing.assert_array_equal(f32(a.motions.offsets), f32(b.motions.offsets))
    np.testing.assert_array_equal(f32(a.motions.timing), f32(b.motions.timing))
    assert a.settings == b.settings
    assert a.bindings == b.bindings
    assert a.forward == b.forward


def new_stage() -> Usd.Stage:
    return Usd.Stage.CreateInMemory("walk.usda")


# -- plugin ----------------------------------------------------------------------------------------


def test_registry_knows_schema():
    assert Usd.SchemaRegistry.GetTypeFromSchemaTypeName("GazeMapAPI")
    definition = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("GazeMapAPI")
    assert definition is not None
    names = set(EXAMPLE_ATTRS) | set(BINDING_ATTRS.values()) | {FORWARD_ATTR} | set(SETTING_ATTRS.values())
    assert set(definition.GetPropertyNames()) == names
    # Schema fallbacks and the dataclass defaults must not drift apart.
    defaults = SynthesisSettings()
    for field, name in SETTING_ATTRS.items():
        assert definition.GetAttributeFallbackValue(name) == pytest.approx(getattr(defaults, field))
    assert definition.GetAttributeFallbackValue(FORWARD_ATTR) == Gf.Vec3f(0, 0, 0)
    assert _plugin.plugin_dir() == SCHEMAS


def test_can_apply_only_to_skel_root():
    stage = new_stage()
    assert stage.DefinePrim("/Root", "SkelRoot").CanApplyAPI("GazeMapAPI")
    assert not stage.DefinePrim("/Xf", "Xform").CanApplyAPI("GazeMapAPI")
    assert not stage.DefinePrim("/Root/Skel", "Skeleton").CanApplyAPI("GazeMapAPI")


def _run(code: str, env_extra: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PXR_PLUGINPATH_NAME", "PYTHONPATH")}
    env.update(env_extra)
    return subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True, text=True, timeout=120)


def test_env_var_alone_registers_schema(tmp_path):
    code = (
        "import sys\n"
        "from pxr import Usd\n"
        "s = Usd.Stage.CreateInMemory()\n"
        "ok = bool(s.DefinePrim('/R', 'SkelRoot').CanApplyAPI('GazeMapAPI'))\n"
        "print(bool(Usd.SchemaRegistry.GetTypeFromSchemaTypeName('GazeMapAPI')), ok, 'usdgaze' in sys.modules)\n"
    )
    proc = _run(code, {"PXR_PLUGINPATH_NAME": str(_plugin.plugin_dir())}, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["True", "True", "False"]


def test_register_is_quiet_when_env_var_already_registered(tmp_path):
    code = (
        "import warnings; warnings.simplefilter('error')\n"
        "from usdgaze import _plugin\n"
        "_plugin.register(); _plugin.register()\n"
        "from pxr import Plug\n"
        "print(Plug.Registry().GetPluginWithName('usdGaze').path)\n"
    )
    other = tmp_path / "elsewhere"
    shutil.copytree(SCHEMAS, other, ignore=shutil.ignore_patterns("__pycache__"))
    proc = _run(code, {"PXR_PLUGINPATH_NAME": str(other), "PYTHONPATH": str(REPO)}, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.strip()) == other  # the env var's copy was kept


def test_register_after_registry_built_warns(tmp_path):
    code = (
        "from pxr import Usd\n"
        "Usd.Stage.CreateInMemory().DefinePrim('/R', 'SkelRoot')  # builds the schema registry\n"
        "import warnings\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    from usdgaze import _plugin; _plugin.register()\n"
        "print(len(caught), 'PXR_PLUGINPATH_NAME' in str(caught[0].message))\n"
    )
    proc = _run(code, {"PYTHONPATH": str(REPO)}, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["1", "True"]


def test_generated_files_are_up_to_date(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(SCHEMAS / "generate.py"), "--out", str(tmp_path)], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for name in ("generatedSchema.usda", "plugInfo.json"):
        assert (tmp_path / name).read_bytes() == (SCHEMAS / name).read_bytes(), f"{name}: run python schemas/generate.py"


# -- round trips -------------------------------------------------------------------------------------


def test_write_read_round_trip():
    definition = make_definition(n=40, seed=3)
    stage = new_stage()
    prim = stage.DefinePrim("/Char", "SkelRoot")
    schema.write_map(prim, definition)
    assert schema.has_map(prim)
    back = schema.read_map(prim)
    assert_same_map(definition, back)
    # Stored as-is: the authored quaternions are the definition's, cast to float32.
    stored = np.asarray(prim.GetAttribute("gaze:examples:neckOffset").Get())
    np.testing.assert_array_equal(stored, f32(definition.motions.offsets[:, 3]))
    # Writing what was read authors the same bits (no drift from renormalizing).
    again = stage.DefinePrim("/Char2", "SkelRoot")
    schema.write_map(again, back)
    for name in EXAMPLE_ATTRS:
        np.testing.assert_array_equal(np.asarray(again.GetAttribute(name).Get()), np.asarray(prim.GetAttribute(name).Get()))


def test_round_trip_defaults_and_empty_bindings():
    definition = make_definition(settings=SynthesisSettings(), bindings={}, forward=None)
    stage = new_stage()
    prim = stage.DefinePrim("/Char", "SkelRoot")
    schema.write_map(prim, definition)
    assert_same_map(definition, schema.read_map(prim))


def test_unauthored_settings_fall_back_to_defaults():
    stage = new_stage()
    prim = stage.DefinePrim("/Char", "SkelRoot")
    schema.write_map(prim, make_definition())
    for name in list(SETTING_ATTRS.values()) + list(BINDING_ATTRS.values()) + [FORWARD_ATTR]:
        prim.RemoveProperty(name)
    back = schema.read_map(prim)
    assert back.settings == SynthesisSettings()
    assert back.bindings == {} and back.forward is None


@pytest.mark.parametrize("ext", ["usda", "usdc", "usd"])
def test_dump_load(tmp_path, ext):
    definition = make_definition()
    path = tmp_path / f"map.{ext}"
    schema.dump_map(definition, path, custom_layer_data={"usdgaze": {"madeBy": "test"}})
    assert_same_map(definition, schema.load_map(str(path)))
    assert_same_map(definition, schema.load_map(f"{path}:/GazeMap"))
    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    assert layer.defaultPrim == "GazeMap"
    assert layer.GetPrimAtPath("/GazeMap").specifier == Sdf.SpecifierClass
    assert layer.customLayerData == {"usdgaze": {"madeBy": "test"}}
    assert (path.read_bytes()[:8] == b"PXR-USDC") == (ext != "usda")


def test_dump_is_deterministic(tmp_path):
    schema.dump_map(make_definition(), tmp_path / "a.usda")
    schema.dump_map(make_definition(), tmp_path / "b.usda")
    assert (tmp_path / "a.usda").read_bytes() == (tmp_path / "b.usda").read_bytes()


def test_load_finds_the_only_map_prim(tmp_path):
    path = tmp_path / "maps.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.DefinePrim("/World", "Xform")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))  # a default prim without the map
    prim = stage.CreateClassPrim("/Maps")
    prim.SetTypeName("SkelRoot")
    schema.write_map(prim, make_definition())
    stage.Save()
    assert_same_map(make_definition(), schema.load_map(str(path)))


def test_load_errors_name_the_file(tmp_path):
    path = tmp_path / "two.usda"
    stage = Usd.Stage.CreateNew(str(path))
    for name in ("A", "B"):
        schema.write_map(stage.DefinePrim(f"/{name}", "SkelRoot"), make_definition())
    stage.Save()
    none = tmp_path / "none.usda"
    Usd.Stage.CreateNew(str(none)).Save()
    for spec, words in [
        (str(path), ["2 prims", "/A", "/B"]),
        (str(none), ["no prim has GazeMapAPI"]),
        (f"{path}:/Nope", ["/Nope", "no such prim"]),
        (str(tmp_path / "missing.usda"), ["no such file"]),
    ]:
        with pytest.raises(GazeMapError) as info:
            schema.load_map(spec)
        message = str(info.value)
        assert "\n" not in message and spec.partition(":/")[0] in message
        assert all(w in message for w in words), message
    assert_same_map(make_definition(), schema.load_map(f"{path}:/B"))


def test_write_refuses_other_prim_types():
    stage = new_stage()
    prim = stage.DefinePrim("/Char/Skel", "Skeleton")
    with pytest.raises(GazeMapError, match=r"walk\.usda:/Char/Skel: .*Skeleton.*SkelRoot") as info:
        schema.write_map(prim, make_definition())
    assert "\n" not in str(info.value)
    assert not prim.HasAPI("GazeMapAPI")


def test_write_refuses_invalid_definition():
    stage = new_stage()
    prim = stage.DefinePrim("/Char", "SkelRoot")
    bad = make_definition(settings=SynthesisSettings(neighbors=0))
    with pytest.raises(GazeMapError, match=r"/Char\.gaze:synthesis:neighbors"):
        schema.write_map(prim, bad)
    assert not prim.HasAPI("GazeMapAPI")


def test_dump_rejects_unknown_extension(tmp_path):
    with pytest.raises(GazeMapError, match="map.json"):
        schema.dump_map(make_definition(), tmp_path / "map.json")


def test_dump_is_atomic(tmp_path, monkeypatch):
    def failing_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(UsdGazeError, match=r"map.usdc: cannot write \(disk full\)"):
        schema.dump_map(make_definition(), tmp_path / "map.usdc")
    assert list(tmp_path.iterdir()) == []

    # An existing map is left as it was.
    monkeypatch.undo()
    target = tmp_path / "map.usda"
    schema.dump_map(make_definition(seed=1), target)
    before = target.read_bytes()
    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(UsdGazeError, match="disk full"):
        schema.dump_map(make_definition(seed=2), target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["map.usda"]


# -- malformed maps ----------------------------------------------------------------------------------

Edit = Callable[[Usd.Prim], None]


def _set(name: str, transform: Callable[[np.ndarray], np.ndarray]) -> Edit:
    """Rewrite one example array through numpy, keeping its type."""

    def edit(prim: Usd.Prim) -> None:
        attr = prim.GetAttribute(name)
        value = np.array(attr.Get())
        new = transform(value)
        vt_type = Vt.QuatfArray if value.ndim == 2 else Vt.FloatArray
        attr.Set(vt_type.FromNumpy(np.ascontiguousarray(new, dtype=np.float32)))

    return edit


def _at(i: int, v: float) -> Callable[[np.ndarray], np.ndarray]:
    def f(a: np.ndarray) -> np.ndarray:
        a[i] = v
        return a

    return f


def _retype(name: str, type_name: Sdf.ValueTypeName, value) -> Edit:
    """Someone authored ``name`` with the wrong type (the schema keeps reporting its own type)."""

    def edit(prim: Usd.Prim) -> None:
        spec = prim.GetStage().GetRootLayer().GetPrimAtPath(prim.GetPath())
        spec.RemoveProperty(spec.properties[name])
        Sdf.AttributeSpec(spec, name, type_name, Sdf.VariabilityUniform).default = value

    return edit


def _set_value(name: str, value) -> Edit:
    return lambda prim: prim.GetAttribute(name).Set(value)


def _remove(name: str) -> Edit:
    return lambda prim: prim.RemoveProperty(name)


def _empty_all(prim: Usd.Prim) -> None:
    for name in EXAMPLE_ATTRS:
        _set(name, lambda a: a[:0])(prim)


def _duplicate(prim: Usd.Prim) -> None:
    _set("gaze:examples:yaw", _at(2, 42.0))(prim)
    _set("gaze:examples:yaw", _at(0, 42.0))(prim)
    _set("gaze:examples:pitch", lambda a: np.where(np.arange(len(a)) == 2, a[0], a))(prim)


def _retype_to_xform(prim: Usd.Prim) -> None:
    prim.SetTypeName("Xform")


def _time_samples(prim: Usd.Prim) -> None:
    attr = prim.GetAttribute("gaze:examples:yaw")
    attr.Set(attr.Get(), Usd.TimeCode(1))


MALFORMED: list[tuple[str, Edit, str]] = [
    ("missing", _remove("gaze:examples:pitch"), "gaze:examples:pitch: missing"),
    ("short", _set("gaze:examples:neckOffset", lambda a: a[:-1]), "gaze:examples:neckOffset: 3 entries, expected 4 (one per example)"),
    ("long", _set("gaze:examples:duration", lambda a: np.append(a, 1.0)), "gaze:examples:duration: 5 entries, expected 4"),
    ("no examples", _empty_all, "gaze:examples:yaw: no examples"),
    ("non-unit quaternion", _set("gaze:examples:eyesOffset", lambda a: a * np.array([[1], [1], [1.01], [1]])), "gaze:examples:eyesOffset: example 2"),
    ("zero quaternion", _set("gaze:examples:pelvisOffset", _at(1, 0.0)), "gaze:examples:pelvisOffset: example 1"),
    ("nan quaternion", _set("gaze:examples:upperSpineOffset", _at(3, np.nan)), "gaze:examples:upperSpineOffset: example 3 is not finite"),
    ("yaw range", _set("gaze:examples:yaw", _at(1, 181.0)), "gaze:examples:yaw: example 1 is 181"),
    ("pitch range", _set("gaze:examples:pitch", _at(0, -95.0)), "gaze:examples:pitch: example 0 is -95"),
    ("nan yaw", _set("gaze:examples:yaw", _at(0, np.nan)), "gaze:examples:yaw: example 0"),
    ("duplicate", _duplicate, "gaze:examples:yaw: examples 0 and 2 share"),
    ("negative duration", _set("gaze:examples:duration", _at(2, -0.1)), "gaze:examples:duration: example 2"),
    ("infinite duration", _set("gaze:examples:duration", _at(2, np.inf)), "gaze:examples:duration: example 2"),
    ("start at 1", _set("gaze:examples:neckStart", _at(1, 1.0)), "gaze:examples:neckStart: example 1 is 1, expected in [0, 1)"),
    ("negative start", _set("gaze:examples:pelvisStart", _at(0, -0.2)), "gaze:examples:pelvisStart: example 0"),
    ("overshoot time 0", _set("gaze:examples:overshootTime", _at(3, 0.0)), "gaze:examples:overshootTime: example 3 is 0, expected in (0, 1]"),
    ("overshoot", _set("gaze:examples:overshoot", _at(0, 1.5)), "gaze:examples:overshoot: example 0 is 1.5, expected in [0, 1]"),
    ("samples", _set_value("gaze:synthesis:samples", 0), "gaze:synthesis:samples: 0, expected >= 1"),
    ("blend size", _set_value("gaze:synthesis:blendSize", 0), "gaze:synthesis:blendSize"),
    ("neighbors", _set_value("gaze:synthesis:neighbors", -1), "gaze:synthesis:neighbors"),
    ("refine", _set_value("gaze:synthesis:refine", -1), "gaze:synthesis:refine: -1, expected >= 0"),
    ("seed", _set_value("gaze:synthesis:seed", -5), "gaze:synthesis:seed"),
    ("neck share", _set_value("gaze:synthesis:neckShare", 1.5), "gaze:synthesis:neckShare"),
    ("not a SkelRoot", _retype_to_xform, "GazeMapAPI is applied to a prim of type Xform; it applies only to SkelRoot"),
    ("empty binding", _set_value("gaze:binding:head", Vt.TokenArray(["Hips/Neck", ""])), "gaze:binding:head: entry 1"),
    ("bad binding path", _set_value("gaze:binding:leftEye", Vt.TokenArray(["Head/eye L"])), "gaze:binding:leftEye: entry 0"),
    ("float[] for quatf[]", _retype("gaze:examples:neckOffset", Sdf.ValueTypeNames.FloatArray, Vt.FloatArray([1, 2, 3, 4])), "gaze:examples:neckOffset: authored as float[], expected quatf[]"),
    ("double[] for float[]", _retype("gaze:examples:yaw", Sdf.ValueTypeNames.DoubleArray, Vt.DoubleArray([0, 1, 2, 3])), "gaze:examples:yaw: authored as double[]"),
    ("float for int", _retype("gaze:synthesis:samples", Sdf.ValueTypeNames.Float, 100.0), "gaze:synthesis:samples: authored as float, expected int"),
    ("double3 forward", _retype("gaze:binding:forward", Sdf.ValueTypeNames.Double3, Gf.Vec3d(0, 0, 1)), "gaze:binding:forward: authored as double3"),
    ("nan forward", _set_value("gaze:binding:forward", Gf.Vec3f(0, float("nan"), 1)), "gaze:binding:forward"),
    ("animated", _time_samples, "gaze:examples:yaw: has time samples"),
]


@pytest.mark.parametrize("edit, expected", [m[1:] for m in MALFORMED], ids=[m[0] for m in MALFORMED])
def test_malformed_map(tmp_path, edit: Edit, expected: str):
    path = tmp_path / "walk.usda"
    schema.dump_map(make_definition(n=4), path)
    stage = Usd.Stage.Open(str(path))
    prim = stage.GetPrimAtPath("/GazeMap")
    edit(prim)
    with pytest.raises(GazeMapError) as info:
        schema.read_map(prim, source="walk.usda")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("walk.usda:/GazeMap"), message
    assert expected in message, message


def test_malformed_file_through_load_map(tmp_path):
    path = tmp_path / "walk.usda"
    schema.dump_map(make_definition(n=4), path)
    layer = Sdf.Layer.FindOrOpen(str(path))
    layer.GetAttributeAtPath("/GazeMap.gaze:examples:overshoot").default = Vt.FloatArray([0, 0, 2, 0])
    layer.Save()
    del layer
    with pytest.raises(GazeMapError, match=rf"^{path}:/GazeMap\.gaze:examples:overshoot: example 2 is 2,"):
        schema.load_map(str(path))


IN_MEMORY = [
    (dict(settings=SynthesisSettings(samples=0)), "gaze:synthesis:samples"),
    (dict(settings=SynthesisSettings(neck_share=-0.1)), "gaze:synthesis:neckShare"),
    (dict(bindings={"head": ("",)}), "gaze:binding:head: entry 0"),
    (dict(bindings={"chin": ("Head/Chin",)}), "unknown joint role 'chin'"),
    (dict(bindings={"head": "Head"}), "gaze:binding:head: a single string"),
    (dict(forward=(0.0, 0.0, 0.0)), "gaze:binding:forward"),
    (dict(params=np.array([[0, 0], [10, 0], [200, 0], [30, 0]])), "gaze:examples:yaw: example 2 is 200 deg"),
]


@pytest.mark.parametrize("changes, expected", IN_MEMORY)
def test_validate_in_memory(changes, expected):
    with pytest.raises(GazeMapError) as info:
        validate(make_definition(n=4, **changes), "default map")
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_validate_in_memory_timing():
    good = make_definition(n=4)
    timing = good.motions.timing.copy()
    timing[1, 5] = 1.2  # overshoot time
    bad = dataclasses.replace(good, motions=motion.GazeMotions(good.motions.offsets, timing))
    with pytest.raises(GazeMapError, match=r"^mem\.gaze:examples:overshootTime: example 1 is 1\.2, expected in \(0, 1\]$"):
        validate(bad, "mem")
    validate(good, "mem")


# -- one map shared by many characters ---------------------------------------------------------------


def test_shared_map_sample():
    stage = Usd.Stage.Open(str(SHARED / "crowd.usda"))
    expected = schema.load_map(str(SHARED / "gaze_map.usda"))
    for path in ("/Crowd/CrowdA/Body", "/Crowd/CrowdB/Body"):
        prim = stage.GetPrimAtPath(path)
        assert prim.GetTypeName() == "SkelRoot" and not prim.IsAbstract()
        assert schema.has_map(prim)
        assert_same_map(expected, schema.read_map(prim))
    assert stage.GetStartTimeCode() == 1 and stage.GetEndTimeCode() == 1249
    assert stage.GetTimeCodesPerSecond() == pytest.approx(120.00479955795427)


def test_editing_the_shared_map_changes_every_character(tmp_path):
    root = tmp_path / "sample_stages"
    shutil.copytree(SHARED, root / "shared_map", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(SHARED.parent / "cmu", root / "cmu")
    layer = Sdf.Layer.FindOrOpen(str(root / "shared_map" / "gaze_map.usda"))
    layer.GetAttributeAtPath("/GazeMap.gaze:synthesis:neckShare").default = 0.8
    yaw = np.array(layer.GetAttributeAtPath("/GazeMap.gaze:examples:yaw").default)
    yaw[0] = -179.5
    layer.GetAttributeAtPath("/GazeMap.gaze:examples:yaw").default = Vt.FloatArray.FromNumpy(yaw)
    layer.Save()
    stage = Usd.Stage.Open(str(root / "shared_map" / "crowd.usda"))
    for path in ("/Crowd/CrowdA/Body", "/Crowd/CrowdB/Body"):
        definition = schema.read_map(stage.GetPrimAtPath(path))
        assert definition.settings.neck_share == 0.8
        assert definition.params[0, 0] == -179.5


def test_make_map_script_reproduces_committed_map(tmp_path):
    script = tmp_path / "make_map.py"
    shutil.copy(SHARED / "make_map.py", script)
    env = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    env["PYTHONPATH"] = str(REPO)
    proc = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "gaze_map.usda").read_bytes() == (SHARED / "gaze_map.usda").read_bytes()
