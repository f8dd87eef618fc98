"""``usdgaze plot`` on a SkelRoot holding two skeletons: each is its own character (``apply`` writes
both), so each gets its own set of PNGs; the second's must not overwrite the first's."""

from __future__ import annotations

import hashlib

from pxr import Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import synthetic as syn

KINDS = ("cascade", "gaze", "eyes", "speed")


def _two_skeletons(tmp_path):
    """One SkelRoot, /Character/Skel and /Character/Skel2, each bound to its own SkelAnimation; the
    second animation looks 30 deg aside, so the two characters' plots differ."""
    rig = syn.make_rig(tmp_path / "in.usda", frames=24, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    other = syn.make_rig(tmp_path / "other.usda", frames=24, time_codes_per_second=24, mesh=False,
                         walk_speed=0.0, look_aside_deg=(0.0, 30.0))
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    Sdf.CopySpec(layer, rig.skeleton, layer, rig.skeleton + "2")
    Sdf.CopySpec(Sdf.Layer.FindOrOpen(str(other.path)), other.animation, layer, rig.animation + "2")
    rel = layer.GetPrimAtPath(rig.skeleton + "2").relationships["skel:animationSource"]
    rel.targetPathList.explicitItems = [Sdf.Path(rig.animation + "2")]
    layer.Save()
    return rig


def test_plot_writes_one_set_per_skeleton_of_one_skel_root(tmp_path):
    rig = _two_skeletons(tmp_path)
    out = tmp_path / "g.usdc"
    assert main(["apply", str(rig.path), "--shift", "6:40:0", "--out", str(out)]) == 0
    plots = tmp_path / "plots"
    assert main(["plot", str(rig.path), "--layer", str(out), "--out", str(plots)]) == 0
    files = sorted(p.name for p in plots.iterdir())
    assert len(files) == 2 * len(KINDS), files
    for kind in KINDS:
        pair = [p for p in plots.iterdir() if p.stem.endswith("_" + kind)]
        assert len(pair) == 2, files
        digests = {hashlib.sha256(p.read_bytes()).hexdigest() for p in pair}
        assert len(digests) == 2, f"the two skeletons' {kind} plots are the same picture"
