"""What the outputs hold, byte for byte, where a sweep of files and formats found them off:

* ``--sublayer-into`` a text ``.usd`` root keeps it text (it became a binary crate file);
* ``--plot`` as PDF or SVG gives the same bytes from the same run (a creation date and random
  clip-path ids made every run's file differ);
* a Skeleton with no animation bound: the new animation lists only the joints the pass drives, so
  every other joint keeps the skeleton's rest pose to the bit by UsdSkel (listed, each was its float
  copy of the double-precision rest, ~1e-7 off).
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


def test_a_text_usd_root_stays_text(tmp_path):
    rig = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False)
    shot = tmp_path / "shot.usd"
    shot.write_text("#usda 1.0\n(\n    subLayers = [\n        @./in.usda@\n    ]\n)\n")
    assert main(["apply", str(rig.path), "--shift", "10:30:0", "--out", str(tmp_path / "gaze.usdc"),
                 "--sublayer-into", str(shot)]) == 0
    assert shot.read_bytes().startswith(b"#usda 1.0")
    root = Sdf.Layer.OpenAsAnonymous(str(shot))
    assert list(root.subLayerPaths) == ["./gaze.usdc", "./in.usda"]


@pytest.mark.parametrize("suffix", ["pdf", "svg"])
def test_plots_are_the_same_bytes_run_to_run(tmp_path, suffix):
    rig = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False)
    made = []
    for i in range(2):
        plot = tmp_path / f"p{i}.{suffix}"
        assert main(["apply", str(rig.path), "--shift", "10:30:0", "--out", str(tmp_path / f"g{i}.usdc"),
                     "--plot", str(plot)]) == 0
        made.append(plot.read_bytes())
    assert made[0] == made[1]
    assert b"CreationDate" not in made[0] and b"<dc:date>" not in made[0]  # the clock, to the second


def _locals(stage_path: str, skeleton: str, time: float) -> tuple[list[str], np.ndarray]:
    stage = Usd.Stage.Open(stage_path)
    query = UsdSkel.Cache().GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath(skeleton)))
    return [str(j) for j in query.GetJointOrder()], np.array(query.ComputeJointLocalTransforms(Usd.TimeCode(time)))


def test_a_skeleton_with_no_animation_keeps_its_undriven_joints_to_the_bit(tmp_path):
    rig = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False)
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    del layer.GetPrimAtPath(rig.skeleton).properties["skel:animationSource"]
    layer.Save()
    preview = tmp_path / "preview.usda"
    assert main(["apply", str(rig.path), "--shift", "10:30:0", "--out", str(tmp_path / "gaze.usda"),
                 "--preview", str(preview)]) == 0
    base_joints, base = _locals(str(rig.path), rig.skeleton, 30)
    joints, new = _locals(str(preview), rig.skeleton, 30)
    driven = set(rig.chain_leaves) | set(rig.leg_root_leaves) | set(rig.eye_leaves)
    kept = [j for j in base_joints if j.rsplit("/", 1)[-1] not in driven]
    assert len(kept) > 10
    for j in kept:
        assert new[joints.index(j)].tobytes() == base[base_joints.index(j)].tobytes(), j
    head = rig.leaf["head"]
    moved = next(j for j in joints if j.endswith(head))
    assert np.abs(new[joints.index(moved)] - base[base_joints.index(moved)]).max() > 1e-3  # the pass did act
    posed = measure.posed(str(preview), rig.skeleton)
    assert np.isfinite(posed.world).all()


def test_a_shot_that_sublayers_a_hard_link_of_the_input_takes_the_override(tmp_path):
    """Files are compared by identity: the shot's hard link of the input was said not to be the input."""
    import os

    rig = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False)
    (tmp_path / "shots").mkdir()
    os.link(rig.path, tmp_path / "shots" / "linked.usda")
    shot = tmp_path / "shots" / "shot.usda"
    shot.write_text("#usda 1.0\n(\n    subLayers = [@./linked.usda@]\n)\n")
    assert main(["apply", str(rig.path), "--shift", "10:30:0", "--out", str(tmp_path / "gaze.usdc"),
                 "--sublayer-into", str(shot)]) == 0
    root = Sdf.Layer.OpenAsAnonymous(str(shot))
    assert list(root.subLayerPaths) == ["../gaze.usdc", "./linked.usda"]
