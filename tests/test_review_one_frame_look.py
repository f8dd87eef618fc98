"""``plot`` of a one-frame animation given a look-at (a still pose aimed at a target): the target panel
set its time axis from the frame to itself, and matplotlib printed its "identical low and high xlims"
warning (two lines on stderr) on a run that succeeded."""

from __future__ import annotations

import warnings

from usdgaze.console.main import main

from . import synthetic as syn


def test_a_one_frame_look_is_plotted_without_warnings(tmp_path, capsys):
    rig = syn.make_rig(tmp_path / "in.usda", frames=1, time_codes_per_second=24, mesh=False)
    layer, plots = tmp_path / "gaze.usdc", tmp_path / "plots"
    assert main(["apply", str(rig.path), "--look-at", "1,1.6,3@0", "--out", str(layer)]) == 0
    capsys.readouterr()
    with warnings.catch_warnings(record=True) as caught:  # a command-line run prints them on stderr
        warnings.simplefilter("always")
        assert main(["plot", str(rig.path), "--layer", str(layer), "--out", str(plots)]) == 0
    assert [str(w.message) for w in caught] == [] and capsys.readouterr().err == ""
    assert (plots / "Character_targets.png").is_file()
