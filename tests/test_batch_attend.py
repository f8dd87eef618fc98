"""``usdgaze batch`` runs ``attend`` jobs (``command = "attend"``), kinematic and ``physics = true``.

Each job's override is compared sample for sample with what the ``usdgaze attend`` command writes for
the same options, so the manifest -> attend mapping is checked against the command itself; the
kinematic job's eyes are checked to turn to the ball by UsdSkel FK on the written layer; a second run
skips both (their resume keys recorded in the layers), a changed parameter redoes only its job; keys
of the other command, or physics-only keys without physics, are one line naming the job and key."""

from __future__ import annotations

import pytest
from pxr import Sdf

import usdgaze  # noqa: F401  (registers the schemas before any stage is opened)
from usdgaze.console.main import main

from . import synthetic as syn
from .attend_support import compose
from .test_attend_binding import _angle_to_ball, _scene
from .test_pipeline import _samples, _status, _summary

JOBS = """
[defaults]
shifts = ["0.5s:30:0"]   # an apply key in [defaults]: attend jobs do not take it

[[job]]
name = "look"
command = "attend"
input = "scene.usda"
out = "out/look.usdc"
window = 0.3
seed = 3

[[job]]
name = "body"
command = "attend"
input = "still.usda"
out = "out/body.usdc"
physics = true
window = 0.3
fd_stride = 2
fd_reuse = 2
iterations = 2
mass = 60
raw_contacts = true
"""


def _tree(tmp_path):
    rig = syn.make_rig(tmp_path / "in.usda", frames=24, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    scene, ball = _scene(tmp_path, rig)
    still = syn.make_rig(tmp_path / "still.usda", frames=5, time_codes_per_second=24, mesh=False, walk_speed=0.0)
    manifest = tmp_path / "jobs.toml"
    manifest.write_text(JOBS)
    return manifest, rig, scene, ball, still


def test_attend_jobs_write_what_the_attend_command_writes_and_resume(tmp_path, monkeypatch):
    manifest, rig, scene, ball, still = _tree(tmp_path)
    assert main(["batch", str(manifest)]) == 0
    assert _status(_summary(manifest)) == {"look": "done", "body": "done"}
    out = tmp_path / "out"
    assert main(["attend", str(scene), "--out", str(tmp_path / "cli_look.usdc"), "--window", "0.3", "--seed", "3"]) == 0
    assert main(["attend", str(still.path), "--physics", "--out", str(tmp_path / "cli_body.usdc"), "--window", "0.3",
                 "--fd-stride", "2", "--fd-reuse", "2", "--iterations", "2", "--mass", "60", "--raw-contacts"]) == 0
    assert _samples(out / "look.usdc") == _samples(tmp_path / "cli_look.usdc")
    assert _samples(out / "body.usdc") == _samples(tmp_path / "cli_body.usdc")
    for name in ("look", "body"):
        data = Sdf.Layer.OpenAsAnonymous(str(out / f"{name}.usdc")).customLayerData["usdgaze"]
        assert len(data["batchKey"]) == 64
    assert "usdgaze:physics" in Sdf.Layer.OpenAsAnonymous(str(out / "body.usdc")).customLayerData
    # The mass reaches the simulation: recorded, and the default's 75 kg body moves otherwise.
    assert Sdf.Layer.OpenAsAnonymous(str(out / "body.usdc")).customLayerData["usdgaze"]["massKg"] == 60.0
    assert Sdf.Layer.OpenAsAnonymous(str(out / "body.usdc")).customLayerData["usdgaze"]["planner"]["iterations"] == 2
    assert Sdf.Layer.OpenAsAnonymous(str(out / "body.usdc")).customLayerData["usdgaze"]["planner"]["groundFeet"] is False
    planner = Sdf.Layer.OpenAsAnonymous(str(out / "body.usdc")).customLayerData["usdgaze"]["planner"]
    assert planner["window"] == 0.3 and "stonesWindow" not in planner  # a job's window is every shot's, as --window
    assert main(["attend", str(still.path), "--physics", "--out", str(tmp_path / "cli_75.usdc"), "--window", "0.3",
                 "--fd-stride", "2", "--fd-reuse", "2", "--iterations", "2", "--raw-contacts"]) == 0
    assert _samples(tmp_path / "cli_75.usdc") != _samples(tmp_path / "cli_body.usdc")
    angle = _angle_to_ball(compose(tmp_path, scene, out / "look.usdc", "composed.usda"), rig, ball)
    assert angle[-8:].max() < 5.0, angle  # the eyes on the ball by the last third of a second

    assert main(["batch", str(manifest)]) == 0
    assert _status(_summary(manifest)) == {"look": "skipped", "body": "skipped"}
    manifest.write_text(JOBS.replace("seed = 3", "seed = 4"))
    assert main(["batch", str(manifest)]) == 0
    assert _status(_summary(manifest)) == {"look": "done", "body": "skipped"}
    # Another MuJoCo release simulates other bits: the physics job is redone, the kinematic one not.
    import mujoco

    monkeypatch.setattr(mujoco, "__version__", "3.0.0.other")
    assert main(["batch", str(manifest)]) == 0
    assert _status(_summary(manifest)) == {"look": "skipped", "body": "done"}
    assert Sdf.Layer.OpenAsAnonymous(str(out / "body.usdc")).customLayerData["usdgaze"]["planner"]["mujoco"] == "3.0.0.other"


@pytest.mark.parametrize("job, words", [
    ('command = "attend"\nshifts = ["1s:30:0"]', ["job 0 'x'", "shifts: not a key of attend jobs"]),
    ('command = "attend"\nfd_stride = 2', ["job 0 'x'", "fd_stride: a key of physics jobs"]),
    ('command = "attend"\nraw_contacts = true', ["job 0 'x'", "raw_contacts: a key of physics jobs"]),
    ('command = "attend"\nphysics = true\nfd_reuse = 0', ["job 0 'x'", "fd_reuse"]),
    ('command = "attend"\nphysics = true\niterations = 0', ["job 0 'x'", "iterations"]),
    ('command = "attend"\nphysics = true\nretry_iterations = 11', ["job 0 'x'", "retry_iterations"]),
    ('command = "attend"\niterations = 2', ["job 0 'x'", "iterations: a key of physics jobs"]),
    ('command = "attend"\nphysics = true\nalpha = 0.4', ["job 0 'x'", "alpha: not taken by physics jobs"]),
    ('command = "attend"\nwindow = 9', ["job 0 'x'", "window = 9", "from 0.05 to 5"]),
    ('command = "attend"\ncost = "greedy"', ["job 0 'x'", "cost = 'greedy'", "uncertainty"]),
    ('physics = true', ["job 0 'x'", "physics: not a key of apply jobs"]),
    ('command = "look"', ["job 0 'x'", "command = 'look'", "apply, attend"]),
])
def test_bad_attend_job_is_one_line_naming_job_and_key(tmp_path, capsys, job, words):
    manifest, *_ = _tree(tmp_path)
    manifest.write_text(f'[[job]]\nname = "x"\ninput = "scene.usda"\nout = "out/x.usdc"\n{job}\n')
    assert main(["batch", str(manifest)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert not (tmp_path / "out").exists()


def test_the_shipped_example_manifests_load():
    from pathlib import Path

    from usdgaze.batch.manifest import load_manifest

    folder = Path(__file__).resolve().parents[1] / "pipeline" / "manifests"
    manifests = sorted(folder.glob("*.toml"))
    assert len(manifests) >= 2
    for manifest in manifests:
        shots = load_manifest(manifest)  # every key checked, as before a run
        assert all(Path(s.values["input"]).is_file() for s in shots), manifest
    commands = {s.command for m in manifests for s in load_manifest(m)}
    assert commands == {"apply", "attend"}


def test_each_shot_in_a_log_names_itself_in_its_step_lines(tmp_path, monkeypatch, capsys):
    """Off a terminal (pytest's captured stderr) a batch shot's planner or simulation writes a plain line
    a minute while it runs (``batch.progress.step_lines``), named by its job: a farm task per shot
    says which shot is still simulating. The minute made 0 s here, so every step after a
    simulation's first writes one."""
    from usdgaze.batch import progress

    manifest, *_ = _tree(tmp_path)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    assert main(["batch", str(manifest)]) == 0
    lines = capsys.readouterr().err.splitlines()
    for job, what in (("look", "planning"), ("body", "simulation")):
        said = [line for line in lines if line.startswith(f"usdgaze: {job}: {what} 1: step ")]
        assert said and said[-1].split(" of ")[0].split()[-1] == said[-1].split(" of ")[1].split()[0], said[-3:]
