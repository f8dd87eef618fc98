"""Property-based fuzzing (hypothesis): the tool's own error or a correct result, never another
exception, never a file left behind.

Budget: the ``ci`` profile (the default, registered in tests/conftest.py) runs a fixed, derandomized
50 examples per test (the stage test 25, it runs a whole ``apply`` each time); set
``USDGAZE_FUZZ=long`` for 2000 examples per test with random seeds, e.g.
``USDGAZE_FUZZ=long python -m pytest tests/test_fuzz.py``.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from usdgaze.errors import UsdGazeError
from usdgaze.gaze.definition import GazeMapDefinition, SynthesisSettings, validate
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.gaze.motion import GazeMotions

from .bad_common import snapshot

FUNCTION_DIR = settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
nice = st.floats(-1e3, 1e3, allow_nan=False)


# -- the gaze map ---------------------------------------------------------------------------------

@st.composite
def definitions(draw):
    n = draw(st.integers(1, 6))
    valid = draw(st.booleans())
    value = (lambda lo, hi: draw(st.floats(lo, hi))) if valid else (lambda lo, hi: draw(st.one_of(floats, st.floats(lo, hi))))
    params = np.array([[value(-180, 180), value(-90, 90)] for _ in range(n)])
    q = np.array([[[value(-1, 1) for _ in range(4)] for _ in range(5)] for _ in range(n)])
    if valid or draw(st.booleans()):
        with np.errstate(all="ignore"):
            q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    timing = np.array([[value(0.05, 1.0)] + [value(0.0, 0.5) for _ in range(4)] + [value(0.3, 0.9), value(0.0, 0.5)]
                       for _ in range(n)])
    s = SynthesisSettings(samples=draw(st.integers(-5, 300)), blend_size=draw(st.integers(-1, 8)),
                          neighbors=draw(st.integers(-1, 12)), refine=draw(st.integers(-1, 3)),
                          seed=draw(st.integers(-3, 2**33)), neck_share=value(0.0, 1.0))
    forward = draw(st.one_of(st.none(), st.tuples(floats, floats, floats)))
    return GazeMapDefinition(params=params, motions=GazeMotions(q, timing), settings=s, forward=forward)


@given(definitions(), st.lists(st.tuples(st.floats(-360, 360), st.floats(-90, 90)), min_size=1, max_size=4))
def test_a_map_is_refused_with_its_own_error_or_answers_finite(definition, queries):
    try:
        validate(definition, "fuzz.usda:/GazeMap")
    except UsdGazeError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("fuzz.usda:/GazeMap")
        return
    result = ParametricGazeMap(definition).query_full(*np.array(queries).T)
    offsets, timing = result.motions.offsets, result.motions.timing
    assert np.isfinite(offsets).all() and np.isfinite(timing).all()
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=-1), 1.0, atol=1e-5)
    assert (timing[..., 0] > 0).all()


@given(st.text(max_size=40))
def test_shift_parsing_is_a_shift_or_one_line(text):
    from usdgaze.values import MAX_SHIFT_TIME, ShiftRequest

    try:
        shift = ShiftRequest.parse(text)
    except UsdGazeError as exc:
        assert "\n" not in str(exc)
        return
    assert abs(shift.time) <= MAX_SHIFT_TIME and abs(shift.yaw) <= 360 and abs(shift.pitch) <= 90


# -- manifests and sheets -------------------------------------------------------------------------

def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)
    return "[" + ", ".join(_toml(v) for v in value) + "]"


scalars = st.one_of(st.booleans(), st.integers(-10, 10), floats, st.text(max_size=12),
                    st.sampled_from(["in.usda", "gaze.usdc", "0.5s:30:0", "../in.usda", "/", "p.usda"]))
values = st.one_of(scalars, st.lists(scalars, max_size=3))
keys = st.sampled_from(["name", "input", "out", "preview", "sublayer_into", "shifts", "map", "skel_root",
                        "fixation", "colour"])
jobs = st.dictionaries(keys, values, max_size=6)


@FUNCTION_DIR
@given(st.lists(jobs, max_size=3), st.dictionaries(keys, values, max_size=2), st.binary(max_size=20))
def test_manifests_load_or_fail_with_one_line_and_write_nothing(tmp_path, job_list, defaults, junk):
    from usdgaze.batch.manifest import load_manifest

    (tmp_path / "in.usda").write_text("#usda 1.0\n")
    text = ""
    if defaults:
        text += "[defaults]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in defaults.items())
    for job in job_list:
        text += "[[job]]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in job.items())
    path = tmp_path / "m.toml"
    path.write_bytes(text.encode() + (junk if junk.startswith(b"#") else b""))
    before = snapshot(tmp_path)
    try:
        loaded = load_manifest(path)
    except UsdGazeError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
    else:
        fixations = [s.values.get("fixation", 2.0) for s in loaded]
        assert all(isinstance(f, float) and 0 < f < float("inf") for f in fixations), fixations
    assert snapshot(tmp_path) == before


cells = st.one_of(st.text(max_size=8), st.sampled_from(["a.c3d", "b.usda", "0", "45", "-200", "nan", "1e400", ""]))


@FUNCTION_DIR
@given(st.lists(st.lists(cells, min_size=1, max_size=6), max_size=4),
       st.sampled_from(["file,yaw,pitch", "file,yaw,pitch,crop_start,crop_end,trial", "trial,file", ""]),
       st.binary(max_size=12))
def test_sheets_load_or_fail_with_one_line(tmp_path, rows, header, junk):
    from usdgaze.ingest.sheet import load_sheet

    path = tmp_path / "sheet.csv"
    body = "\n".join(",".join(c.replace("\n", " ").replace("\r", " ") for c in row) for row in rows)
    path.write_bytes(f"{header}\n{body}\n".encode() + junk)
    try:
        sheet = load_sheet(path)
    except UsdGazeError as exc:
        assert "\n" not in str(exc)
    else:
        assert all(-180 <= t.yaw <= 180 and -90 <= t.pitch <= 90 for t in sheet.trials)


# -- broken UsdSkel stages -------------------------------------------------------------------------

def _mutations():
    from pxr import Sdf, Vt

    T = Sdf.ValueTypeNames
    attrs = ["/Character/Anim.rotations", "/Character/Anim.translations", "/Character/Anim.scales",
             "/Character/Anim.joints", "/Character/Skel.joints", "/Character/Skel.restTransforms",
             "/Character/Skel.bindTransforms", "/Character/Skel.jointNames"]
    odd_values = [Vt.FloatArray([1.0, float("nan")]), Vt.Vec3fArray(3), Vt.QuatfArray(2), Vt.TokenArray(["a", "a/b"]),
                  Vt.Matrix4dArray(1), Vt.Vec3hArray(1), Vt.StringArray(["x"]), 7, "text"]
    types = [T.FloatArray, T.Float3Array, T.Double3Array, T.StringArray, T.Matrix4dArray, T.QuatdArray, T.Int]
    metadata = [("upAxis", "X"), ("upAxis", "Z"), ("metersPerUnit", -1.0), ("metersPerUnit", 0.01),
                ("metersPerUnit", float("nan")), ("timeCodesPerSecond", 0.0), ("timeCodesPerSecond", 24.0)]
    return st.lists(st.one_of(
        st.tuples(st.just("remove"), st.sampled_from(attrs)),
        st.tuples(st.just("set"), st.sampled_from(attrs), st.sampled_from(odd_values), st.integers(0, 19)),
        st.tuples(st.just("retype"), st.sampled_from(attrs), st.sampled_from(types)),
        st.tuples(st.just("meta"), st.sampled_from(metadata)),
        st.tuples(st.just("nan"), st.sampled_from(attrs[:3]), st.integers(0, 19)),
        st.tuples(st.just("prim"), st.sampled_from(["/Character/Skel", "/Character/Anim", "/Character"])),
    ), min_size=1, max_size=3)


def _mutate(layer, op) -> None:
    from pxr import Sdf

    kind = op[0]
    if kind == "meta":
        key, value = op[1]
        if key == "timeCodesPerSecond":
            layer.timeCodesPerSecond = value
        else:
            layer.pseudoRoot.SetInfo(key, value)
        return
    if kind == "prim":
        path = Sdf.Path(op[1])
        parent = layer.GetPrimAtPath(path.GetParentPath()) if path.GetParentPath() != Sdf.Path.absoluteRootPath else layer.pseudoRoot
        if parent and path.name in parent.nameChildren:
            del parent.nameChildren[path.name]
        return
    path = Sdf.Path(op[1])
    prim = layer.GetPrimAtPath(path.GetPrimPath())
    spec = layer.GetAttributeAtPath(path)
    if prim is None or spec is None:
        return
    if kind == "remove":
        prim.RemoveProperty(spec)
    elif kind == "retype":
        prim.RemoveProperty(spec)
        Sdf.AttributeSpec(prim, path.name, op[2])
    elif kind == "set":
        times = layer.ListTimeSamplesForPath(path)
        try:
            if times:
                layer.SetTimeSample(path, times[op[3] % len(times)], op[2])
            else:
                spec.default = op[2]
        except Exception:  # a value this attribute type cannot hold: Sdf refuses, nothing to fuzz
            pass
    elif kind == "nan":
        times = layer.ListTimeSamplesForPath(path)
        if times:
            t = times[op[2] % len(times)]
            value = np.array(layer.QueryTimeSample(path, t), dtype=float)
            value[len(value) // 2] = np.nan
            layer.SetTimeSample(path, t, type(layer.QueryTimeSample(path, t)).FromNumpy(value.astype(np.float32 if "scales" not in str(path) else np.float16)))


@pytest.fixture(scope="module")
def base_rig(tmp_path_factory):
    from . import synthetic as syn

    return syn.make_rig(tmp_path_factory.mktemp("fuzzrig") / "in.usda", frames=20, mesh=False)


@settings(max_examples=25 if os.environ.get("USDGAZE_FUZZ", "ci") == "ci" else 500)
@given(ops=_mutations())
def test_broken_stages_get_the_tools_error_or_a_result_and_no_mess(tmp_path_factory, base_rig, ops):
    from pxr import Sdf

    from usdgaze import api

    d = tmp_path_factory.mktemp("fuzz")
    layer = Sdf.Layer.OpenAsAnonymous(str(base_rig.path))
    for op in ops:
        _mutate(layer, op)
    src = d / "in.usda"
    assume(layer.Export(str(src)))
    before = snapshot(d)
    try:
        api.apply(src, ["0.1s:30:0"], d / "gaze.usdc", preview=d / "preview.usda")
    except UsdGazeError as exc:
        assert "\n" not in str(exc)
        assert snapshot(d) == before
    else:
        after = snapshot(d)
        assert set(after) - set(before) == {"gaze.usdc", "preview.usda"}
        assert {k: after[k] for k in before} == before
