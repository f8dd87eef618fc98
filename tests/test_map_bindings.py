"""``gaze:binding:*`` in a ``--map`` file bind the rig: the roles the SkelRoot's own GazeMapAPI leaves
unbound (its own win), under ``--bind``/``--forward``. On a rig whose joint names say nothing
(``j0``, ``j1``, ...) nothing binds without them; the gaze measured on the result by UsdSkel FK
(tests/measure.py, axes from the bind pose) is the one asked for.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from pxr import Usd

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api
from usdgaze.errors import UsdGazeError
from usdgaze.gaze.defaults import default_definition
from usdgaze.usd import schema

from . import synthetic as syn
from .test_rig_binding import SHIFTS, _measured, _numbered


def _map_file(d: Path, bindings: dict, forward=None) -> Path:
    """The built-in map dumped with ``bindings`` (role -> joint leaf) and ``forward``."""
    path = d / "map.usda"
    definition = dataclasses.replace(default_definition(), bindings={r: (j,) for r, j in bindings.items()},
                                     forward=None if forward is None else tuple(float(v) for v in forward))
    schema.dump_map(definition, path)
    return path


def _own_bindings(rig: syn.Rig, bindings: dict) -> None:
    """The built-in map authored on the rig's SkelRoot with ``bindings`` and no forward."""
    stage = Usd.Stage.Open(str(rig.path))
    definition = dataclasses.replace(default_definition(), bindings={r: (j,) for r, j in bindings.items()})
    schema.write_map(stage.GetPrimAtPath(rig.skel_root), definition)
    stage.GetRootLayer().Save()


def _chain_roles(rig: syn.Rig) -> dict:
    leaf = rig.leaf
    return {"pelvis": leaf["pelvis"], "head": leaf["head"], "leftEye": leaf["eye_l"], "rightEye": leaf["eye_r"]}


def test_a_map_files_bindings_bind_an_unnamed_rig(tmp_path):
    rig = _numbered(tmp_path)
    with pytest.raises(UsdGazeError, match="no gaze chain"):
        api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", map_spec=str(_map_file(tmp_path, {})))
    spec = str(_map_file(tmp_path, _chain_roles(rig), rig.forward))
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda", map_spec=spec)
    assert [j.rsplit("/", 1)[-1] for j in report.characters[0].chain["head"]] == [rig.leaf["head"]]
    _, _, error = _measured(rig, report, tmp_path / "preview.usda")
    assert error <= 0.5, error


def test_the_skelroots_own_bindings_win_role_by_role(tmp_path):
    """The SkelRoot binds the chain, the map file binds head to a joint the rig lacks and gives the
    forward: the head is the SkelRoot's (else 'Skull' would be refused) and the forward the file's
    (else the rig's forward could not be told)."""
    rig = _numbered(tmp_path)
    _own_bindings(rig, _chain_roles(rig))
    with pytest.raises(UsdGazeError, match="cannot tell the character's forward"):
        api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc")
    spec = str(_map_file(tmp_path, {"head": "Skull"}, rig.forward))
    report = api.apply(rig.path, SHIFTS, tmp_path / "gaze.usdc", preview=tmp_path / "preview.usda", map_spec=spec)
    assert [j.rsplit("/", 1)[-1] for j in report.characters[0].chain["head"]] == [rig.leaf["head"]]
    _, _, error = _measured(rig, report, tmp_path / "preview.usda")
    assert error <= 0.5, error
