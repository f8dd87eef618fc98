"""The ``usdgaze`` console command, run as a user would (a subprocess), on real CMU capture.

``cmu_131_01.usdc``: 994 samples at 120.0048 time codes per second from time code 1, Y up, no eyes.
"""

from __future__ import annotations

import json
import re
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import usdgaze
from pxr import Sdf, Usd, Vt

from . import measure

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "sample_stages" / "cmu" / "cmu_131_01.usdc"
TCPS = 120.00479955795427
ANIM = "/root/Body/BodySkel/scaled_131_01"
ENTRY = Path(sys.executable).with_name("usdgaze")  # the installed console script
MODULE = [sys.executable, "-m", "usdgaze"]
SHIFTS = ["--shift", "150:60:0", "--shift", "2.5s:-30:-10"]


def usdgaze_cmd(*args, env=None, cwd=None) -> subprocess.CompletedProcess:
    exe = [str(ENTRY)] if ENTRY.is_file() else MODULE
    return subprocess.run([*exe, *map(str, args)], capture_output=True, text=True, env=env, cwd=cwd, timeout=300)


@pytest.fixture(scope="module")
def src(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("cmu")
    shutil.copy(CMU, d / CMU.name)
    return d / CMU.name


@pytest.fixture(scope="module")
def applied(src):
    """One ``apply --json --preview`` with a shift in time codes and one in seconds."""
    d = src.parent
    before = measure.sha256(src)
    p = usdgaze_cmd("apply", src, *SHIFTS, "--out", d / "gaze.usdc", "--preview", d / "preview.usda", "--json")
    return dict(dir=d, proc=p, before=before)


def test_entry_point_is_installed_and_matches_the_module():
    assert ENTRY.is_file(), "pip install -e . should install the usdgaze console script"
    a = usdgaze_cmd("--version")
    b = subprocess.run([*MODULE, "--version"], capture_output=True, text=True)
    assert a.returncode == b.returncode == 0
    assert a.stdout == b.stdout == f"usdgaze, version {usdgaze.__version__}\n"


def test_apply_json_report(applied, src):
    p, d = applied["proc"], applied["dir"]
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""
    report = json.loads(p.stdout)
    assert report["output"] == str(d / "gaze.usdc")
    assert report["preview"] == str(d / "preview.usda")
    assert report["sublayered_into"] is None and report["warnings"] == []
    (c,) = report["characters"]
    assert (c["skel_root"], c["skeleton"], c["animation"]) == ("/root/Body", "/root/Body/BodySkel", ANIM)
    assert c["frames"] == 994
    assert c["chain"] == {"pelvis": ["Hips"], "lowerSpine": ["lowerback"], "upperSpine": ["Chest", "Chest2"],
                          "neck": ["lowerneck", "Neck"], "head": ["Head"], "leftEye": [], "rightEye": []}
    assert [j.rsplit("/", 1)[-1] for j in c["added_joints"]] == ["LeftEye", "RightEye"]
    first, second = c["shifts"]
    # 150 is a time code: (150 - 1) / 120.0048 s from the stage start; 2.5s is seconds.
    assert first["at"] == f"{(150 - 1) / TCPS:.3f}s" == "1.242s"
    assert second["at"] == "2.500s"
    assert (first["yaw"], first["pitch"], second["yaw"], second["pitch"]) == (60.0, 0.0, -30.0, -10.0)
    for s in (first, second):
        assert s["duration_s"] > 0 and not s["interrupted"]
        assert float(s["hold_error_deg"].split()[0]) <= 0.5
    assert measure.sha256(src) == applied["before"]


def test_apply_writes_the_override_and_a_preview_that_sublayers_it(applied, src):
    d = applied["dir"]
    layer = Sdf.Layer.FindOrOpen(str(d / "gaze.usdc"))
    assert list(layer.customLayerData["usdgaze"]["shifts"]) == ["150:60:0", "2.5s:-30:-10"]
    assert len(layer.ListTimeSamplesForPath(ANIM + ".rotations")) == 994
    preview = Sdf.Layer.FindOrOpen(str(d / "preview.usda"))
    assert list(preview.subLayerPaths) == ["./gaze.usdc", f"./{src.name}"]
    stage = Usd.Stage.Open(str(d / "preview.usda"))
    assert len(stage.GetPrimAtPath("/root/Body/BodySkel").GetAttribute("joints").Get()) == 33


def test_a_shift_in_seconds_equals_the_same_shift_in_time_codes(src, tmp_path):
    seconds = (150 - 1) / TCPS
    a = usdgaze_cmd("apply", src, "--shift", "150:60:0", "--out", tmp_path / "tc.usdc")
    b = usdgaze_cmd("apply", src, "--shift", f"{seconds!r}s:60:0", "--out", tmp_path / "s.usdc")
    assert a.returncode == b.returncode == 0, (a.stderr, b.stderr)
    la, lb = (Sdf.Layer.FindOrOpen(str(tmp_path / n)) for n in ("tc.usdc", "s.usdc"))
    path = Sdf.Path(ANIM + ".rotations")
    for t in la.ListTimeSamplesForPath(path)[::25]:
        assert np.asarray(la.QueryTimeSample(path, t)).tobytes() == np.asarray(lb.QueryTimeSample(path, t)).tobytes()


def test_apply_text_output(src, tmp_path):
    p = usdgaze_cmd("apply", src, *SHIFTS, "--out", tmp_path / "gaze.usda")
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    assert lines[0].startswith("/root/Body  (994 frames, map: built-in default")
    assert "chain: pelvis=Hips, lowerSpine=lowerback, upperSpine=Chest+Chest2, neck=lowerneck+Neck, head=Head" in lines[1]
    assert sum("shift" in line and "hold error" in line for line in lines) == 2
    assert lines[-1] == f"wrote {tmp_path / 'gaze.usda'}"
    assert (tmp_path / "gaze.usda").read_text().startswith("#usda 1.0")


def test_warnings_go_to_stderr_and_into_the_json_report(src, tmp_path):
    p = usdgaze_cmd("apply", src, "--shift", "150:250:0", "--out", tmp_path / "g.usdc", "--json")
    assert p.returncode == 0, p.stderr
    warnings = json.loads(p.stdout)["warnings"]
    assert len(warnings) == 1
    assert p.stderr.splitlines() == [f"usdgaze: warning: {w}" for w in warnings]
    assert any("yaw 250" in w and "reach" in w for w in warnings)


def test_inspect_names_the_chain_and_the_time_range(src):
    p = usdgaze_cmd("inspect", src)
    assert p.returncode == 0, p.stderr
    out = p.stdout
    assert f"{src}: upAxis Y, metersPerUnit 1, time codes 1..996 at 120.005/s" in out
    assert "SkelRoot /root/Body  gaze map: none (the built-in map is used)" in out
    assert "Skeleton /root/Body/BodySkel  31 joints" in out
    assert f"animation {ANIM}  994 samples, time codes 1..994" in out
    for role, joints in (("pelvis", "Hips"), ("lowerSpine", "lowerback"), ("upperSpine", "Chest, Chest2"),
                         ("neck", "lowerneck, Neck"), ("head", "Head"), ("leftEye", "- (eye joints will be added)")):
        assert re.search(rf"^    {role:<11} {re.escape(joints)}(  \[[^\n]+\])?$", out, re.M), role
    assert "    head        Head  [name 'Head']\n" in out  # what was bound, and why
    assert "    neutral pose: bindTransforms\n" in out
    assert "[left/right pair LeftHip/RightHip]" in out
    j = usdgaze_cmd("inspect", src, "--json")
    info = json.loads(j.stdout)
    (skel,) = info["skel_roots"][0]["skeletons"]
    assert (skel["first"], skel["last"], skel["frames"]) == (1.0, 994.0, 994)
    assert skel["chain"]["upperSpine"] == ["Chest", "Chest2"]
    assert (info["start"], info["end"]) == (1.0, 996.0)


def test_dump_map_edit_it_and_apply_it(src, tmp_path):
    map_file = tmp_path / "slow_map.usda"
    p = usdgaze_cmd("dump-map", map_file, "--prim", "/SlowMap")
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == f"wrote {map_file}"

    # Far enough apart that the slow first shift settles before the second.
    shifts = ["--shift", "150:60:0", "--shift", "5s:-30:-10"]

    def shifts_with_map(name, *use_map):
        p = usdgaze_cmd("apply", src, *shifts, "--out", tmp_path / name, *use_map, "--json")
        assert p.returncode == 0, p.stderr
        character = json.loads(p.stdout)["characters"][0]
        assert character["map"] == (use_map[1] if use_map else f"built-in default (usdgaze {usdgaze.__version__})")
        assert not any(s["interrupted"] for s in character["shifts"])
        return character["shifts"]

    # As dumped, the map is the built-in one (stored as float32: equal to ~1e-4).
    dumped = shifts_with_map("dumped.usdc", "--map", f"{map_file}:/SlowMap")
    default = shifts_with_map("default.usdc")
    for a, b in zip(dumped, default):
        assert a["duration_s"] == pytest.approx(b["duration_s"], rel=1e-3)
    # Edit it as a user would, with Sdf: every gaze shift takes twice as long.
    layer = Sdf.Layer.FindOrOpen(str(map_file))
    spec = layer.GetAttributeAtPath("/SlowMap.gaze:examples:duration")
    spec.default = Vt.FloatArray([2.0 * v for v in spec.default])
    assert layer.Save()
    slow = shifts_with_map("slow.usdc", "--map", f"{map_file}:/SlowMap")
    for s_slow, s_dumped in zip(slow, dumped):
        assert s_slow["duration_s"] == pytest.approx(2.0 * s_dumped["duration_s"], rel=1e-6)
        assert s_slow["overshoot"] == pytest.approx(s_dumped["overshoot"], rel=1e-6)
    data = Sdf.Layer.FindOrOpen(str(tmp_path / "slow.usdc")).customLayerData["usdgaze"]
    assert list(data["maps"]) == [f"{map_file}:/SlowMap"]


def test_plugin_path_lets_plain_usd_know_the_schema(tmp_path):
    p = usdgaze_cmd("plugin-path")
    assert p.returncode == 0, p.stderr
    folder = Path(p.stdout.strip())
    assert (folder / "plugInfo.json").is_file()
    # A process that never imports usdgaze knows GazeMapAPI through PXR_PLUGINPATH_NAME.
    env = dict(os.environ, PXR_PLUGINPATH_NAME=str(folder))
    probe = "from pxr import Usd; print(bool(Usd.SchemaRegistry.GetTypeFromSchemaTypeName('GazeMapAPI')))"
    q = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert q.stdout.strip() == "True", q.stderr


def test_exit_codes(src, tmp_path):
    assert usdgaze_cmd("--help").returncode == 0
    plain = usdgaze_cmd()
    assert plain.returncode == 0 and plain.stdout.startswith("Usage: usdgaze") and plain.stderr == ""
    bad = usdgaze_cmd("apply", src, "--shift", "1:2", "--out", tmp_path / "x.usdc")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and bad.stderr.startswith("usdgaze: error: ")
    assert not (tmp_path / "x.usdc").exists()
    ok = usdgaze_cmd("apply", src, "--shift", "10:5:0", "--out", tmp_path / "x.usdc")
    assert ok.returncode == 0 and (tmp_path / "x.usdc").is_file()


def test_internal_errors_exit_1_with_one_line_unless_debugging(src, tmp_path):
    driver = tmp_path / "driver.py"
    driver.write_text(textwrap.dedent("""
        import sys
        import usdgaze.api

        def broken(*args, **kwargs):
            raise RuntimeError("boom")

        usdgaze.api.apply = broken
        from usdgaze.console.main import main
        sys.exit(main(sys.argv[1:]))
    """))
    args = [sys.executable, str(driver), "apply", str(src), "--shift", "10:5:0", "--out", str(tmp_path / "x.usdc")]
    env = {k: v for k, v in os.environ.items() if k != "USDGAZE_DEBUG"}
    p = subprocess.run(args, capture_output=True, text=True, env=env)
    assert p.returncode == 1
    assert p.stderr == ("usdgaze: error: internal error: RuntimeError: boom "
                        "(set USDGAZE_DEBUG=1 for the traceback)\n")
    p = subprocess.run(args, capture_output=True, text=True, env=dict(env, USDGAZE_DEBUG="1"))
    assert p.returncode == 1 and "Traceback" in p.stderr and 'raise RuntimeError("boom")' in p.stderr


def test_an_option_of_one_value_given_twice_is_refused(tmp_path, capsys):
    """click kept the last of two --skel-root without a word: only the second character got its gaze."""
    import pathlib

    from usdgaze.console.main import main

    crowd = pathlib.Path(__file__).resolve().parents[1] / "sample_stages" / "shared_map" / "crowd.usda"
    args = ["apply", str(crowd), "--shift", "1s:30:0", "--out", str(tmp_path / "g.usda")]
    assert main(args + ["--skel-root", "/Crowd/CrowdA/Body", "--skel-root=/Crowd/CrowdB/Body"]) == 2
    assert capsys.readouterr().err == "usdgaze: error: --skel-root is given 2 times; it takes one value\n"
    assert not (tmp_path / "g.usda").exists()
    assert main(args + ["--skel-root", "/Crowd/CrowdA/Body", "--shift", "2s:0:0"]) == 0  # repeatable options repeat


def _options():
    """(command, option name, help) of every option of every command (and subcommand)."""
    import importlib

    import click

    from usdgaze.console.main import _COMMANDS

    for name, (module, attr) in sorted(_COMMANDS.items()):
        command = getattr(importlib.import_module(module), attr)
        subs = list(command.commands.items()) if isinstance(command, click.Group) else []
        for label, cmd in [(name, command)] + [(f"{name} {n}", c) for n, c in subs]:
            for p in cmd.params:
                if isinstance(p, click.Option):
                    yield label, p.opts[0], p.help or ""


def test_every_option_has_help_and_its_units():
    """preview --layout and --sheet-count had no help; --release's and --shift's B gave no unit while
    --look-at's did; dump-map --prim did not say it must be a root prim path."""
    helps = {(c, o): h for c, o, h in _options()}
    assert [k for k, h in helps.items() if not h.strip()] == []
    for flag in ("--shift", "--look-at", "--release"):
        assert "B time codes (or seconds with 's')" in helps["apply", flag], flag
    assert "root prim path" in helps["dump-map", "--prim"]


def test_readme_synopses_of_apply_and_validate_name_every_option():
    """README's `## Command line` block left out apply's --bind/--forward and validate's --only-usdgaze."""
    text = (ROOT / "README.md").read_text()
    block = text[text.index("## Command line"):]
    block = block[block.index("```") + 3:]
    block = block[:block.index("```")]
    synopses: dict[str, str] = {}
    name = None
    for line in block.splitlines():
        if line.startswith("usdgaze "):
            name = line.split()[1]
        if name is not None:
            synopses[name] = synopses.get(name, "") + " " + line.split("#")[0]
    for command in ("apply", "validate"):
        named = set(re.findall(r"--[a-z][a-z-]*", synopses[command]))
        assert [o for c, o, _ in _options() if c == command and o not in named | {"-h"}] == [], command
