"""``--sublayer-into`` a shot that already sublayers an earlier usdgaze override of the same character
says so: the new override hides that layer's animation, but its guides still show.

An audit found: a second ``apply --sublayer-into shot.usda --out g2.usda --no-guides`` after a first
one into ``g1.usda`` left ``[g2, g1, input]`` in the shot without a word, and the composed shot drew
g1's lines of sight (a 30 deg turn to the left) beside eyes that UsdSkel turns 50 deg to the right;
``validate`` found nothing.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from usdgaze.console.main import main

from . import measure
from . import synthetic as syn


def _warnings(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("usdgaze: warning:")]


def _shot(tmp_path, rig) -> str:
    shot = tmp_path / "shot.usda"
    shot.write_text(f"""#usda 1.0
(
    startTimeCode = {rig.start_time:g}
    endTimeCode = {rig.end_time:g}
    timeCodesPerSecond = {rig.time_codes_per_second:g}
    framesPerSecond = {rig.frames_per_second:g}
    upAxis = "Y"
    metersPerUnit = 1
    subLayers = [@./in.usda@]
)
""")
    return str(shot)


def _guide_against_eye_deg(shot: str, rig, frame: int) -> float:
    """Degrees between the left eye's line of sight by UsdSkel FK and the left guide curve's direction."""
    p = measure.posed(shot, rig.skeleton, times=[float(frame)])
    eye = p.axis(rig.leaf["eye_l"], measure.local_forward(p, rig.leaf["eye_l"], rig.forward))[0]
    stage = Usd.Stage.Open(shot)
    curve = UsdGeom.BasisCurves(stage.GetPrimAtPath(f"{rig.skeleton}/gazeGuides/leftEyeSight"))
    a, b = np.array(curve.GetPointsAttr().Get(float(frame)), dtype=float)
    guide = (b - a) / np.linalg.norm(b - a)
    return float(measure.angle_between(eye[None], guide[None])[0])


def test_an_earlier_override_in_the_shot_is_said_and_a_rerun_into_the_same_layer_is_not(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=60, mesh=False, walk_speed=0.0)
    shot = _shot(tmp_path, rig)
    first, second = tmp_path / "g1.usda", tmp_path / "g2.usda"
    for _ in range(2):  # a rerun into the same layer replaces it: nothing is left behind to say
        assert main(["apply", str(rig.path), "--shift", "0.2s:30:0", "--out", str(first), "--sublayer-into", shot]) == 0
        assert _warnings(capsys) == []
    assert _guide_against_eye_deg(shot, rig, 55) < 1.0  # its own guides follow its eyes

    assert main(["apply", str(rig.path), "--shift", "0.2s:-50:0", "--out", str(second), "--sublayer-into", shot,
                 "--no-guides"]) == 0
    said = _warnings(capsys)
    assert len(said) == 1 and str(first.resolve()) in said[0] and rig.animation in said[0], said
    assert list(Sdf.Layer.FindOrOpen(shot).subLayerPaths) == ["./g2.usda", "./g1.usda", "./in.usda"]
    # What the warning is about, measured: g1's guides are drawn where g2's eyes no longer look.
    assert _guide_against_eye_deg(shot, rig, 55) > 60.0  # the +30 deg guides beside -50 deg eyes
