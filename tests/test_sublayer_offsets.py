"""--sublayer-into a shot layer that brings the input in at a layer offset, or already lists the override
below the input, and batch resume with a symlinked sublayer target in another folder.

Measured with UsdSkel's forward kinematics (tests/measure.py) on the composed shot against the composed
preview (override over input, no offsets): the shot must show the same pose at the input's time mapped
through the shot's offsets.
"""

from __future__ import annotations

import json
import os

import numpy as np

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from pxr import Sdf

from usdgaze import api
from usdgaze.console.main import main

from . import measure
from . import synthetic as syn

_HEAD = '#usda 1.0\n(\n    timeCodesPerSecond = {tcps}\n    subLayers = [{subs}]\n)\n'


def _shot(path, subs: str, tcps: float = 60) -> str:
    path.write_text(_HEAD.format(tcps=tcps, subs=subs))
    return str(path)


def _gaze(tmp_path):
    """A rig, its override written with a preview (the reference result, in the input's own time)."""
    r = syn.make_rig(tmp_path / "in.usda", frames=90, mesh=False)
    api.apply(r.path, ["0.3s:40:0"], tmp_path / "ref.usdc", preview=tmp_path / "preview.usda")
    return r


def _pose_gap(shot: str, r, preview: str, map_time) -> float:
    """Largest joint position gap (stage units) between the shot at ``map_time(t)`` and the preview at t."""
    times = np.array(r.times[::10], dtype=float)
    want = measure.posed(preview, r.skeleton, times=times).world[:, :, 3, :3]
    got = measure.posed(shot, r.skeleton, times=[map_time(t) for t in times]).world[:, :, 3, :3]
    return float(np.abs(got - want).max())


def test_the_override_gets_the_offset_the_shot_gives_the_input(tmp_path):
    r = _gaze(tmp_path)
    preview = str(tmp_path / "preview.usda")
    # Directly (offset 10), and nested: top (60 tc/s) -> mid (24 tc/s, offset 6) -> in (offset 4).
    direct = _shot(tmp_path / "direct.usda", "@./in.usda@ (offset = 10)")
    _shot(tmp_path / "mid.usda", "@./in.usda@ (offset = 4)", tcps=24)
    nested = _shot(tmp_path / "top.usda", "@./mid.usda@ (offset = 6)")
    for shot, shift in ((direct, 10.0), (nested, 6.0 + 2.5 * 4.0)):
        api.apply(r.path, ["0.3s:40:0"], tmp_path / f"gaze_{shift:g}.usdc", sublayer_into=shot)
        assert _pose_gap(shot, r, preview, lambda t: t + shift) < 1e-5, shot
    # The gaze is really there: the shot differs from the input at the same mapped time.
    assert _pose_gap(direct, r, str(r.path), lambda t: t + 10.0) > 1e-3


def test_an_override_listed_below_the_input_is_made_the_strongest(tmp_path):
    r = _gaze(tmp_path)
    out = tmp_path / "gaze.usdc"
    api.apply(r.path, ["0.3s:40:0"], out)
    shot = _shot(tmp_path / "shot.usda", "@./in.usda@, @gaze.usdc@")  # listed, but weaker than the input
    api.apply(r.path, ["0.3s:40:0"], out, sublayer_into=shot)
    assert list(Sdf.Layer.OpenAsAnonymous(shot).subLayerPaths) == ["./gaze.usdc", "./in.usda"]
    assert _pose_gap(shot, r, str(tmp_path / "preview.usda"), lambda t: t) < 1e-5
    before = measure.sha256(shot)
    api.apply(r.path, ["0.3s:40:0"], out, sublayer_into=shot)  # in place already: the file is untouched
    assert measure.sha256(shot) == before


def test_batch_skips_a_shot_whose_sublayer_target_is_a_symlink_into_another_folder(tmp_path):
    (tmp_path / "shots").mkdir()
    (tmp_path / "links").mkdir()
    syn.make_rig(tmp_path / "shots" / "in.usda", frames=60, mesh=False)
    _shot(tmp_path / "shots" / "shot.usda", "@./in.usda@")
    os.symlink("../shots/shot.usda", tmp_path / "links" / "shot.usda")
    manifest = tmp_path / "m.toml"
    manifest.write_text('[[job]]\ninput = "shots/in.usda"\nout = "shots/gaze.usdc"\n'
                        'sublayer_into = "links/shot.usda"\nshifts = ["0.3s:30:0"]\n')
    statuses = []
    for _ in range(2):
        assert main(["batch", str(manifest)]) == 0
        statuses.append(json.loads((tmp_path / "m.summary.json").read_text())["shots"][0]["status"])
    assert statuses == ["done", "skipped"]


def test_a_second_run_into_the_same_root_says_it_left_it_as_it_was(tmp_path, capsys):
    """Run twice: the second leaves ROOT byte-identical and says so (it said 'inserted' again)."""
    r = syn.make_rig(tmp_path / "in.usda", frames=30, mesh=False)
    root = _shot(tmp_path / "shot.usda", "@./in.usda@")
    argv = ["apply", str(r.path), "--shift", "0.2s:30:0", "--out", str(tmp_path / "gaze.usdc"), "--sublayer-into", root]
    assert main(argv) == 0
    assert "inserted" in capsys.readouterr().out
    before = measure.sha256(root)
    assert main(argv) == 0
    assert "was already the strongest sublayer" in capsys.readouterr().out
    assert measure.sha256(root) == before


def test_a_rerun_after_the_output_was_deleted_says_nothing_of_usd(tmp_path, capfd):
    """ROOT lists the override, which was deleted: the rerun writes it again, exit 0, and stderr holds
    no USD warning about the missing sublayer it is about to write (it printed one)."""
    r = syn.make_rig(tmp_path / "in.usda", frames=30, mesh=False)
    root = _shot(tmp_path / "shot.usda", "@./in.usda@")
    out = tmp_path / "gaze.usdc"
    argv = ["apply", str(r.path), "--shift", "0.2s:30:0", "--out", str(out), "--sublayer-into", root]
    assert main(argv) == 0
    out.unlink()
    capfd.readouterr()
    assert main(argv) == 0 and out.is_file()
    assert capfd.readouterr().err == ""
