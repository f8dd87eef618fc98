"""Meshes skinned by joint indices UsdSkel cannot use: an index past the skeleton's joints, or
jointIndices and jointWeights of different lengths. apply and validate accepted them silently; on an
eyeless rig the eyes apply adds became the next joints, and a mesh index just past the joints bound
to the left eye (tests/bad_cases_sweep3.py: ``mesh-index-on-an-added-eye``, refused). validate reports
each mesh (exit 3), apply warns of it once. Read from the files with Sdf and UsdSkel, nothing from usdgaze."""

from __future__ import annotations

import pytest
from pxr import Sdf, Usd, UsdSkel, Vt

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)

from . import bad_common as bad


def _edit_mesh(d, eyes: bool, how: str):
    def edit(layer, r):
        ji = layer.GetAttributeAtPath(r.mesh + ".primvars:skel:jointIndices")
        if how == "range":
            values = list(ji.default)
            values[3] = 55
            ji.default = Vt.IntArray(values)
        else:  # one entry fewer than jointWeights
            ji.default = Vt.IntArray(list(ji.default)[:-1])
    return bad.edited(d, edit, eyes=eyes, mesh=True), bad.rig(d, "ref.usda", eyes=eyes, mesh=True)


@pytest.mark.parametrize("how, said", [("range", "index 55 is out of range for the skeleton's"),
                                       ("length", "entries, but primvars:skel:jointWeights has")])
def test_validate_reports_the_mesh(tmp_path, how, said):
    path, r = _edit_mesh(tmp_path, True, how)
    code, out, err = bad.run_inprocess(["validate", str(path), "--only-usdgaze"], tmp_path)
    lines = [line for line in out.splitlines() if "JointIndices" in line]
    assert code == 3 and len(lines) == 1, (code, out, err)
    assert lines[0].startswith(f"{path}:{r.mesh}.primvars:skel:jointIndices: error: ") and said in lines[0], lines[0]
    code, out, err = bad.run_inprocess(["validate", str(r.path), "--only-usdgaze"], tmp_path)
    assert "JointIndices" not in out, out  # the unedited rig


@pytest.mark.parametrize("eyes", [True, False], ids=["own-eyes", "eyes-added"])
def test_apply_warns_of_an_index_out_of_range_and_writes(tmp_path, eyes):
    """Index 55 is out of range whether or not two eyes are added after the skeleton's joints."""
    path, r = _edit_mesh(tmp_path, eyes, "range")
    out = tmp_path / "gaze.usda"
    code, _, err = bad.run_inprocess(bad.apply_argv(tmp_path, path, out="gaze.usda"), tmp_path)
    warned = [line for line in err.splitlines() if "jointIndices" in line]
    assert code == 0 and len(warned) == 1, (code, err)
    assert warned[0].startswith(f"usdgaze: warning: {path}:{r.mesh}.primvars:skel:jointIndices: index 55 "), warned
    root = Sdf.Layer.CreateAnonymous()
    root.subLayerPaths[:] = [str(out), str(path)]  # the override over the input, as a viewer opens it
    stage = Usd.Stage.Open(root)
    joints = UsdSkel.Skeleton(stage.GetPrimAtPath(r.skeleton)).GetJointsAttr().Get()
    assert len(joints) == len(r.joints) + (0 if eyes else 2) < 55  # still out of range: bound to nothing
