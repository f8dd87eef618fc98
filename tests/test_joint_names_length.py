"""A Skeleton whose jointNames is not one name per joint: ``validate`` flags it (SkeletonArrays), and
where binding finds no chain the line says the names were not read and why. Before, neither said a
word: a generic rig (``bone_000`` ...) whose names were one short failed with "no gaze chain found"
only, while the same rig with every name bound by them."""

from __future__ import annotations

from pathlib import Path

import pytest
from pxr import Sdf, Vt

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze.console.main import main
from usdgaze.review.validation import run as validate

from . import synthetic as syn


def _generic_with_names(tmp_path: Path, extra: int) -> syn.Rig:
    """A generic-token rig whose jointNames spell Mixamo's names, ``extra`` more (or fewer) than its joints."""
    named = syn.make_rig(tmp_path / "named.usda", frames=60, mesh=False)
    rig = syn.make_rig(tmp_path / "in.usda", convention="generic", frames=60, mesh=False)
    names = [j.rsplit("/", 1)[-1].replace("mixamorig_", "") for j in named.joints]
    names = names[:len(names) + extra] if extra < 0 else names + [f"Extra{k}" for k in range(extra)]

    def author(layer: Sdf.Layer) -> None:
        attr = Sdf.AttributeSpec(layer.GetPrimAtPath(rig.skeleton), "jointNames", Sdf.ValueTypeNames.TokenArray,
                                 Sdf.VariabilityUniform)
        attr.default = Vt.TokenArray(names)
    syn.edit(rig.path, author)
    return rig


def _names_problems(path: Path) -> list[dict]:
    return [p for p in validate(path, only_usdgaze=True) if p["site"].endswith(".jointNames")]


@pytest.mark.parametrize("extra", [-1, 2])
def test_joint_names_of_the_wrong_length_are_flagged_and_said(tmp_path, capsys, extra):
    rig = _generic_with_names(tmp_path, extra)
    n = len(rig.joints)
    problems = _names_problems(rig.path)
    assert [p["error"] for p in problems] == ["Length"], problems
    assert f"jointNames: {n + extra} entries, expected {n} (one per joint)" in problems[0]["message"]
    capsys.readouterr()
    assert main(["apply", str(rig.path), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no gaze chain" in err[0], err
    assert err[0].endswith(f"its jointNames holds {n + extra} names for {n} joints (not one per joint), so they were "
                           "not read: author one name per joint"), err[0]
    assert not (tmp_path / "gaze.usdc").exists()


def test_joint_names_one_per_joint_bind_and_pass(tmp_path):
    rig = _generic_with_names(tmp_path, 0)
    assert _names_problems(rig.path) == []
    assert main(["apply", str(rig.path), "--shift", "0.5s:30:0", "--out", str(tmp_path / "gaze.usdc")]) == 0
