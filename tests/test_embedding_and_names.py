"""Operability and embedding: a file name that is not UTF-8, a Ctrl-C while ``import usdgaze`` loads
OpenUSD, a host that built OpenUSD's schema registry before importing usdgaze, and a studio plugin
folder whose plugInfo.json OpenUSD cannot read.

Before: an output name with a non-UTF-8 byte was an internal error (exit 1, a UnicodeEncodeError in the
writer's name-length check); a SIGINT landing in OpenUSD's module loader was printed as a warning and
swallowed, so the command went on and wrote its output (exit 0); with a stale registry a SkelRoot's
authored GazeMapAPI map, its GazeScheduleAPI and a prim's GazeObjectAPI read as absent (the built-in
map was used without a word; attend said to apply GazeObjectAPI to some prims); a broken plugInfo.json
on PXR_PLUGINPATH_NAME made every command, ``--version`` included, a traceback with exit 1."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _python(code: str, env: dict | None = None, cwd=None) -> subprocess.CompletedProcess:
    full = dict(os.environ, **(env or {}))
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          env=full, cwd=cwd or ROOT, timeout=120)


def test_an_output_name_that_is_not_utf8_is_one_line_exit_2(tmp_path):
    out = os.path.join(os.fsencode(tmp_path), b"map\xff.usda")
    run = subprocess.run([sys.executable, "-m", "usdgaze", "dump-map", out], capture_output=True, cwd=ROOT, timeout=120)
    err = run.stderr.decode(errors="replace")
    assert run.returncode == 2, err
    assert err.count("\n") == 1 and "internal error" not in err and "not UTF-8" in err, err
    assert list(tmp_path.iterdir()) == []  # nothing written, no temporary folder left


def test_a_sigint_in_openusds_module_loader_during_import_is_not_swallowed():
    # A finder raises SIGINT while OpenUSD's loader imports pxr.Kind for `import usdgaze`.
    run = _python("""
        import signal, sys

        # Python's own Ctrl-C handler, as on a terminal: a process started in the background (a shell's
        # `cmd &`) inherits SIGINT ignored, and then no signal is raised at all.
        signal.signal(signal.SIGINT, signal.default_int_handler)

        class Stop:
            fired = False
            def find_spec(self, name, path, target=None):
                if name == "pxr.Kind" and not Stop.fired:
                    Stop.fired = True
                    signal.raise_signal(signal.SIGINT)
                return None

        sys.meta_path.insert(0, Stop())
        try:
            import usdgaze
        except KeyboardInterrupt:
            print("interrupted", Stop.fired)
        else:
            print("swallowed", Stop.fired)
        """)
    assert run.stdout.strip() == "interrupted True", run.stdout + run.stderr


STAGE = """#usda 1.0
def SkelRoot "Char" (
    prepend apiSchemas = ["GazeMapAPI", "GazeScheduleAPI"]
)
{
}

def SkelRoot "Plain"
{
}

def Sphere "Ball" (
    prepend apiSchemas = ["GazeObjectAPI"]
)
{
}
"""


def test_a_registry_built_before_import_makes_authored_gaze_schemas_an_error_not_absent(tmp_path):
    path = tmp_path / "scene.usda"
    path.write_text(STAGE)
    run = _python(f"""
        from pxr import Usd
        Usd.Stage.CreateInMemory()
        Usd.SchemaRegistry()  # a host (a DCC) asked the registry before usdgaze was imported
        import warnings
        warnings.simplefilter("ignore")
        import usdgaze
        from usdgaze.errors import UsdGazeError
        from usdgaze.usd import objects, schedule, schema

        stage = Usd.Stage.Open({str(path)!r})
        checks = [("map", lambda: schema.has_map(stage.GetPrimAtPath("/Char"))),
                  ("schedule", lambda: schedule.has_schedule(stage.GetPrimAtPath("/Char"))),
                  ("objects", lambda: objects.object_prims(stage, "scene.usda", None)),
                  ("plain", lambda: schema.has_map(stage.GetPrimAtPath("/Plain")))]
        for what, check in checks:
            try:
                print(what, "returned", check())
            except UsdGazeError as exc:
                print(what, "error", exc)
        """)
    lines = dict(line.split(" ", 1) for line in run.stdout.splitlines())
    assert set(lines) == {"map", "schedule", "objects", "plain"}, run.stdout + run.stderr
    for what, api_name, prim in (("map", "GazeMapAPI", "/Char"), ("schedule", "GazeScheduleAPI", "/Char"),
                                 ("objects", "GazeObjectAPI", "/Ball")):
        assert lines[what].startswith("error "), (what, lines[what])
        assert f"{prim}: has {api_name} applied" in lines[what] and "PXR_PLUGINPATH_NAME=" in lines[what]
    assert lines["plain"] == "returned False"  # a SkelRoot without a map is still just that


def test_an_unreadable_plugin_on_the_plugin_path_is_a_warning_not_a_traceback(tmp_path):
    bad = tmp_path / "studio"
    bad.mkdir()
    (bad / "plugInfo.json").write_text("{not json")
    run = _python("""
        import usdgaze
        from usdgaze.usd import schema
        print("known", bool(schema.Usd.SchemaRegistry.GetTypeFromSchemaTypeName("GazeMapAPI")))
        """, env={"PXR_PLUGINPATH_NAME": f"{bad}{os.pathsep}{tmp_path / 'missing'}"})
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "known True"
    assert "Traceback" not in run.stderr and "couldn't be read" in run.stderr, run.stderr


def test_standard_output_that_cannot_take_the_report(tmp_path):
    """A report echoed to a full disk was an internal error (exit 1, which a farm retries); to a reader
    that went away (``| head``) click exited 1 too. Now one line, exit 2; and a quiet 141, as a
    process that SIGPIPE stopped (the outputs are written before the report)."""
    cmu = os.path.join(ROOT, "sample_stages", "cmu", "cmu_131_02.usdc")
    args = [sys.executable, "-m", "usdgaze", "apply", cmu, "--shift", "1s:30:0", "--json"]
    with open("/dev/full", "w") as full:
        run = subprocess.run(args + ["--out", str(tmp_path / "a.usdc")], stdout=full, stderr=subprocess.PIPE,
                             text=True, cwd=ROOT, timeout=120)
    assert run.returncode == 2, run.stderr
    assert run.stderr == "usdgaze: error: cannot write to standard output (No space left on device)\n"
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the report is written
    try:
        run = subprocess.run(args + ["--out", str(tmp_path / "b.usdc")], stdout=write, stderr=subprocess.PIPE,
                             text=True, cwd=ROOT, timeout=120)
    finally:
        os.close(write)
    assert run.returncode == 141 and run.stderr == "", (run.returncode, run.stderr)
    assert (tmp_path / "b.usdc").is_file()


def test_a_working_folder_that_is_not_utf8_with_a_relative_input_is_one_line_exit_2(tmp_path):
    """OpenUSD anchors a relative input at the working folder: one whose name is not UTF-8 made apply
    and attend an internal error (exit 1, a UnicodeDecodeError reading a layer's real path), and a
    batch shot said Python's codec message."""
    from . import synthetic as syn

    folder = os.path.join(os.fsencode(tmp_path), b"shot\xff")
    os.mkdir(folder)
    syn.make_rig(tmp_path / "a.usda", frames=48)  # USD cannot write there either
    os.rename(tmp_path / "a.usda", os.path.join(folder, b"a.usda"))
    with open(os.path.join(folder, b"m.toml"), "w") as f:
        f.write(f'[[job]]\ninput = "a.usda"\nout = "{tmp_path / "b.usda"}"\nshifts = ["0.2s:30:0"]\n')
    env = dict(os.environ, PYTHONPATH=ROOT)
    for argv in (["apply", "a.usda", "--shift", "0.2s:30:0", "--out", str(tmp_path / "g.usda")],
                 ["attend", "a.usda", "--out", str(tmp_path / "g.usda")]):
        run = subprocess.run([sys.executable, "-m", "usdgaze", *argv], capture_output=True, cwd=folder, env=env,
                             timeout=120)
        err = run.stderr.decode(errors="replace")
        assert run.returncode == 2, err
        assert err.count("\n") == 1 and "not UTF-8" in err and "a.usda" in err, err
    run = subprocess.run([sys.executable, "-m", "usdgaze", "batch", "m.toml"], capture_output=True, cwd=folder,
                         env=env, timeout=120)
    assert run.returncode == 2, run.stderr
    assert b"not UTF-8" in run.stderr and b"codec" not in run.stderr, run.stderr
    assert sorted(os.listdir(folder)) == [b"a.usda", b"m.summary.json", b"m.toml"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [os.fsdecode(b"shot\xff")]  # no output written
