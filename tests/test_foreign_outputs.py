"""An output name that names a USD layer usdgaze did not write (another shot's stage: a typo for
``shot_02_gaze.usdc``) is refused, one line, exit 2, the file's bytes and mode as they were and
nothing left beside it; so is a shot's root of sublayers and no prims. usdgaze's own outputs (a
rerun, previews included), truly empty layers (a pipeline's placeholder) and non-USD files are
replaced as before."""

from __future__ import annotations

import os
import stat

import pytest
from pxr import Sdf

from .bad_common import SHIFT, rig, run_inprocess, snapshot


def _foreign(path, d):
    """Another character's stage at ``path``, read-write for everyone (a mode a replacement keeps)."""
    Sdf.Layer.FindOrOpen(str(rig(d, "other_shot.usda").path)).Export(str(path))  # in the suffix's encoding
    os.chmod(path, 0o666)
    return path


def _refused(code: int, err: str, name: str, flag: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert name in lines[0] and flag in lines[0] and "usdgaze did not write" in lines[0], lines[0]
    assert "it holds /" in lines[0]  # names what is in it


@pytest.mark.parametrize("flag, name", [("--out", "gaze.usdc"), ("--preview", "preview.usda")])
def test_apply_does_not_replace_another_shots_layer(tmp_path, flag, name):
    src = rig(tmp_path, "in.usda").path
    _foreign(tmp_path / name, tmp_path)
    before = snapshot(tmp_path)
    argv = ["apply", str(src), *SHIFT, "--out", "gaze.usdc", "--preview", "preview.usda"]
    code, _, err = run_inprocess(argv, tmp_path)
    _refused(code, err, name, flag)
    assert snapshot(tmp_path) == before  # bytes, modes, and no temporaries or partial outputs


def test_a_rerun_replaces_its_own_outputs_and_a_placeholder(tmp_path):
    src = rig(tmp_path, "in.usda").path
    (tmp_path / "gaze.usda").write_text("#usda 1.0\n")  # an empty placeholder layer
    argv = ["apply", str(src), *SHIFT, "--out", "gaze.usda", "--preview", "preview.usda"]
    assert run_inprocess(argv, tmp_path)[0] == 0
    assert Sdf.Layer.FindOrOpen(str(tmp_path / "gaze.usda")).rootPrims  # the override replaced it
    first = (tmp_path / "gaze.usda").read_bytes()
    argv[3] = "0.5s:-30:0"
    code, _, err = run_inprocess(argv, tmp_path)
    assert code == 0, err
    assert (tmp_path / "gaze.usda").read_bytes() != first


_SHOT_ROOT = ('#usda 1.0\n(\n    doc = "Shot 010 root"\n    upAxis = "Y"\n'
              '    subLayers = [@./lighting.usda@, @./layout.usda@]\n)\n')


@pytest.mark.parametrize("flag", ["--out", "--preview"])
def test_a_shot_root_of_sublayers_only_is_not_replaced(tmp_path, flag):
    """No prims, only sublayers: a shot's root (its lighting and layout), not a placeholder."""
    src = rig(tmp_path, "in.usda").path
    (tmp_path / "shot_root.usda").write_text(_SHOT_ROOT)
    before = snapshot(tmp_path)
    names = {"--out": "gaze.usda", "--preview": "preview.usda", flag: "shot_root.usda"}
    argv = ["apply", str(src), *SHIFT, "--out", names["--out"], "--preview", names["--preview"]]
    code, _, err = run_inprocess(argv, tmp_path)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "shot_root.usda" in lines[0] and flag in lines[0], err
    assert "./lighting.usda" in lines[0]  # names what is in it
    assert snapshot(tmp_path) == before


def test_preview_edited_by_hand_is_not_replaced(tmp_path):
    """A preview root an animator saved edits into holds prims of their own now."""
    src = rig(tmp_path, "in.usda").path
    argv = ["apply", str(src), *SHIFT, "--out", "gaze.usda", "--preview", "preview.usda"]
    assert run_inprocess(argv, tmp_path)[0] == 0
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "preview.usda"))
    Sdf.CreatePrimInLayer(layer, "/Notes").specifier = Sdf.SpecifierDef
    layer.Save()
    before = snapshot(tmp_path)
    code, _, err = run_inprocess(argv, tmp_path)
    _refused(code, err, "preview.usda", "--preview")
    assert snapshot(tmp_path) == before


def test_dump_map_and_build_map_outputs(tmp_path):
    _foreign(tmp_path / "map.usda", tmp_path)
    before = snapshot(tmp_path)
    code, _, err = run_inprocess(["dump-map", "map.usda"], tmp_path)
    _refused(code, err, "map.usda", "OUT")
    assert snapshot(tmp_path) == before
    assert run_inprocess(["dump-map", "own.usda"], tmp_path)[0] == 0
    code, _, err = run_inprocess(["dump-map", "own.usda", "--prim", "/Other"], tmp_path)
    assert code == 0, err  # its own map, replaced


def test_attend_out_is_refused_before_the_work(tmp_path):
    src = os.path.join(os.path.dirname(__file__), "..", "sample_stages", "attend", "ball_throw.usda")
    _foreign(tmp_path / "gaze.usdc", tmp_path)
    mode = stat.S_IMODE((tmp_path / "gaze.usdc").stat().st_mode)
    before = snapshot(tmp_path)
    code, out, err = run_inprocess(["attend", str(src), "--out", "gaze.usdc"], tmp_path)
    _refused(code, err, "gaze.usdc", "--out")
    assert out == ""  # no report: nothing was planned
    assert snapshot(tmp_path) == before and mode == 0o666


def test_a_non_usd_output_is_replaced_as_any_file(tmp_path):
    """Plots, reports and models are not layers: an existing one is replaced (unless --no-clobber)."""
    src = rig(tmp_path, "in.usda").path
    (tmp_path / "model.xml").write_text("<mujoco/>")
    code, _, err = run_inprocess(["physics-model", str(src), "--out", "model.xml"], tmp_path)
    if code == 2 and "mujoco" in err.lower() and "install" in err.lower():
        pytest.fail("the test extra installs mujoco")
    assert code == 0, err
    assert (tmp_path / "model.xml").read_text() != "<mujoco/>"


def test_a_gaze_map_the_shot_composes_is_no_override_to_replace(tmp_path):
    """``--sublayer-into`` lets ``--out`` replace an earlier override in ROOT's stack (a rerun); a gaze
    map there is usdgaze's file too, but no override: it was replaced by the override, its map lost."""
    src = rig(tmp_path, "in.usda").path
    assert run_inprocess(["dump-map", "map.usda"], tmp_path)[0] == 0
    (tmp_path / "shot.usda").write_text("#usda 1.0\n(\n    subLayers = [@./map.usda@, @./in.usda@]\n)\n")
    before = snapshot(tmp_path)
    code, _, err = run_inprocess(["apply", str(src), *SHIFT, "--out", "map.usda", "--sublayer-into", "shot.usda"],
                                 tmp_path)
    assert code == 2 and "map.usda" in err and "--sublayer-into" in err, err
    assert snapshot(tmp_path) == before
