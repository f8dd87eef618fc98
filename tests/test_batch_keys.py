"""Resume keys: what a shot's key hashes, for inputs of every kind USD opens."""

from __future__ import annotations

import json
from pathlib import Path

from pxr import Sdf, UsdUtils

from usdgaze.console.main import main

from . import synthetic as syn


def _package(folder, note: str) -> None:
    (folder / "notes.usda").write_text(f'#usda 1.0\ndef "Notes" {{\n    custom string note = "{note}"\n}}\n')
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(folder / "shot.usda")), str(folder / "shot.usdz"))


def _status(folder) -> str:
    """The first shot's status in the last batch run's summary (``jobs.summary.json`` in ``folder``)."""
    return json.loads((folder / "jobs.summary.json").read_text())["shots"][0]["status"]


def test_a_usdz_input_of_several_layers_runs_and_resumes(tmp_path):
    """A package's layers are 'shot.usdz[notes.usda]' to USD: hashing that as a file was
    'internal error: FileNotFoundError', exit 1, for an input usdgaze apply reads."""
    syn.make_rig(tmp_path / "rig.usda", frames=48)
    (tmp_path / "shot.usda").write_text('#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n'
                                        '    subLayers = [@./notes.usda@, @./rig.usda@]\n)\n')
    _package(tmp_path, "take 1")
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[[job]]\nname = "z"\ninput = "shot.usdz"\nout = "out/z.usdc"\nshifts = ["0.2s:30:0"]\n')
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "done"
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "skipped"
    _package(tmp_path, "take 2")  # a layer inside the package changed: the package file did
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "done"


def test_a_missing_layer_is_said_once_in_the_shots_line_not_in_a_usd_warning(tmp_path, capfd):
    """Computing the key of a shot whose input names a missing sublayer printed USD's own multi-line
    warning into the farm log before the shot's one line said it."""
    syn.make_rig(tmp_path / "rig.usda", frames=24, mesh=False)
    (tmp_path / "wrap.usda").write_text("#usda 1.0\n(\n    subLayers = [@./missing.usda@, @./rig.usda@]\n)\n")
    manifest = tmp_path / "m.toml"
    manifest.write_text('[[job]]\ninput = "wrap.usda"\nout = "o.usdc"\nshifts = ["0.2s:30:0"]\n')
    capfd.readouterr()
    assert main(["batch", str(manifest)]) == 2
    err = capfd.readouterr().err
    assert "Warning" not in err and "assetLocalization" not in err, err
    assert "missing.usda" in err  # the shot's own line


def test_a_binding_spelled_another_way_is_the_same_shot(tmp_path):
    """forward as a list or a string, bind as a list or a table, in any order: the same binding, so
    a respelled manifest skips the shots it already did (it redid them); another binding redoes."""
    rig = syn.make_rig(tmp_path / "rig.usda", frames=24, mesh=False)
    manifest = tmp_path / "jobs.toml"
    job = '[[job]]\nname = "g"\ninput = "rig.usda"\nout = "out/g.usdc"\nshifts = ["0.2s:30:0"]\n'

    def run(binding: str) -> str:
        manifest.write_text(job + binding)
        assert main(["batch", str(manifest)]) == 0
        return json.loads((tmp_path / "jobs.summary.json").read_text())["shots"][0]["status"]

    head, neck = rig.leaf["head"], rig.leaf["neck"]  # joints by their own names
    assert run(f'forward = [0, 0, 1]\nbind = ["head={head}", "neck={neck}"]\n') == "done"
    assert run(f'forward = "0,0,1"\nbind = ["neck={neck}", "head={head}"]\n') == "skipped"
    assert run(f'forward = "0, 0, 1.0"\nbind = {{ head = "{head}", neck = ["{neck}"] }}\n') == "skipped"
    assert run(f'forward = "0,0,1"\nbind = ["head={head}"]\n') == "done"


def test_another_build_of_usdgaze_redoes_a_shot_its_version_string_would_skip(tmp_path, monkeypatch):
    """The key hashes the package's own files beside its version: a build that writes otherwise under
    the same version string (a patched install, a development tree) redoes the shot."""
    import shutil

    import usdgaze
    from usdgaze.batch import keys

    syn.make_rig(tmp_path / "rig.usda", frames=24, mesh=False)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[[job]]\nname = "g"\ninput = "rig.usda"\nout = "out/g.usdc"\nshifts = ["0.2s:30:0"]\n')
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "done"
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "skipped"
    # The digest follows the files: a copy of the package with one byte more in a module.
    copy = tmp_path / "pkg" / "usdgaze"
    shutil.copytree(Path(usdgaze.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    digests = []
    for _ in range(2):
        keys.tool_digest.cache_clear()
        monkeypatch.setattr(usdgaze, "__file__", str(copy / "__init__.py"))
        digests.append(keys.tool_digest())
        (copy / "values.py").write_text((copy / "values.py").read_text() + "\n")
    keys.tool_digest.cache_clear()
    monkeypatch.undo()
    assert digests[0] == keys.tool_digest() and digests[1] != digests[0]
    monkeypatch.setattr(keys, "tool_digest", lambda: digests[1])
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "done"


def test_another_release_of_usd_or_numpy_redoes_a_shot(tmp_path, monkeypatch):
    """The key holds the versions of what computes and writes a shot beside usdgaze (USD's crate
    writer, numpy's arithmetic): an upgrade of either skipped the shot, its output made with the old."""
    import numpy
    from pxr import Usd

    from usdgaze.batch import keys

    syn.make_rig(tmp_path / "rig.usda", frames=24, mesh=False)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text('[[job]]\nname = "g"\ninput = "rig.usda"\nout = "out/g.usdc"\nshifts = ["0.2s:30:0"]\n')
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "done"
    assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "skipped"
    for patch in (lambda: monkeypatch.setattr(numpy, "__version__", "0.0.other"),
                  lambda: monkeypatch.setattr(Usd, "GetVersion", lambda: (0, 99, 1))):
        keys.libraries.cache_clear()
        patch()
        assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "done"
        assert main(["batch", str(manifest)]) == 0 and _status(tmp_path) == "skipped"
        monkeypatch.undo()
    keys.libraries.cache_clear()
