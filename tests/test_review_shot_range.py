"""``plot`` and ``preview`` of a shot cut from a longer take by its root layer's playback range
(startTimeCode..endTimeCode over a sublayered take, as an editor's shot file is): both drew the
whole take (the GIF 96 frames of 4 s for a 1.5 s shot, the plots from -1 s to 3 s), where the shot
plays only its range. Frames are counted with Pillow and the plotted times read back from the
figures the command saves."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pxr import Sdf

from usdgaze.console.main import main

from . import synthetic as syn

TCPS = 60.0
START, END = 60.0, 150.0  # the shot: 1 s into a 4 s take, 1.5 s long


def _shot(folder: Path, name: str = "shot.usda", rate: float = TCPS, start: float = START, end: float = END) -> Path:
    """A 240-frame take at 60 per second, and a shot layer at ``rate`` time codes per second that
    sublayers it (USD scales the take's time codes by ``rate / 60``) and plays ``start..end``."""
    if not (folder / "take.usda").exists():
        syn.make_rig(folder / "take.usda", frames=240, time_codes_per_second=TCPS, mesh=False)
    shot = Sdf.Layer.CreateNew(str(folder / name))
    shot.subLayerPaths.append("./take.usda")
    shot.timeCodesPerSecond = shot.framesPerSecond = rate
    shot.startTimeCode, shot.endTimeCode = start, end
    shot.pseudoRoot.SetInfo("upAxis", "Y")
    shot.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    shot.defaultPrim = "Character"
    shot.Save()
    return folder / name


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shot_range")
    shot = _shot(folder)
    layer = folder / "gaze.usdc"
    # One shift before the shot's range (time code 30, in the take), one inside it (0.5 s: code 90).
    assert main(["apply", str(shot), "--shift", "30:-25:0", "--shift", "0.5s:40:0", "--out", str(layer)]) == 0
    return shot, layer


def test_the_gif_and_the_sheet_cover_the_shots_range_not_the_take(made, tmp_path):
    shot, layer = made
    gif, sheet = tmp_path / "p.gif", tmp_path / "s.png"
    assert main(["preview", str(shot), "--layer", str(layer), "--out", str(gif), "--sheet", str(sheet),
                 "--fps", "24"]) == 0
    with Image.open(gif) as im:
        frames = im.n_frames
    # 0 to 1.5 s at 24 per second: 37 frames (the take's 0 to 3.98 s had 96).
    assert frames == int(np.floor((END - START) / TCPS * 24 + 1e-9)) + 1 == 37


def test_plots_draw_the_shots_seconds_only(made, tmp_path, monkeypatch):
    from usdgaze.review import plotting

    shot, layer = made
    seen: dict[str, list] = {}
    save = plotting.save_figure

    def record(fig, path, outputs, dpi=100):
        seen[Path(path).stem] = [(ax.get_title(), ax.get_xlim(), [line.get_xdata() for line in ax.get_lines()])
                                 for ax in fig.axes]
        save(fig, path, outputs, dpi)

    monkeypatch.setattr(plotting, "save_figure", record)
    assert main(["plot", str(shot), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0
    length = (END - START) / TCPS
    for stem in ("Character_gaze", "Character_eyes"):
        (_, xlim, lines), = seen[stem]
        xs = np.concatenate([np.asarray(x, dtype=float) for x in lines])
        assert xs.min() == pytest.approx(0.0, abs=1e-9) and xs.max() == pytest.approx(length, abs=1e-9), stem
        assert xlim[0] > -0.1 and xlim[1] < length + 0.1, (stem, xlim)  # no axis stretched to the take
    titles = [title for title, _, _ in seen["Character_cascade"]]
    # The shift at time code 30 began before the shot: its turn since then is not on it.
    assert len(titles) == 1 and "at 0.5 s to yaw 40" in titles[0], titles


def test_a_24_fps_shot_over_a_60_hz_take_gets_a_frame_per_shot_frame(tmp_path):
    """The take's samples lie at shot codes 0.4 apart, none on the shot's first and last frames (25
    and 61): the GIF had the take's 96 frames; drawn from the first sample in the range (25.2) to the
    last (60.8) it would have 36, one short of the 37 frames the shot plays."""
    shot = _shot(tmp_path, "shot24.usda", rate=24.0, start=25.0, end=61.0)
    layer, gif = tmp_path / "gaze.usdc", tmp_path / "p.gif"
    assert main(["apply", str(shot), "--shift", "0.5s:40:0", "--out", str(layer)]) == 0
    assert main(["preview", str(shot), "--layer", str(layer), "--out", str(gif), "--fps", "24"]) == 0
    with Image.open(gif) as im:
        assert im.n_frames == 61 - 25 + 1


def test_a_shot_where_the_character_is_hidden_throughout_is_drawn(tmp_path, capsys):
    """The take scales the character to nothing on time codes 40-44 (apply keeps those frames as the
    input's); a shot of just those frames has no head direction to set a named camera by, nor an eye
    angle: the preview stopped on a NaN camera (exit 1) and the eye plot printed numpy's warnings."""
    from pxr import Gf, Vt

    rig = syn.make_rig(tmp_path / "take.usda", frames=90, time_codes_per_second=30.0, mesh=False)
    take = Sdf.Layer.FindOrOpen(str(rig.path))
    prim = take.GetPrimAtPath(rig.skel_root)
    scale = Sdf.AttributeSpec(prim, "xformOp:scale", Sdf.ValueTypeNames.Float3)
    for t, s in ((0, 1.0), (39, 1.0), (40, 0.0), (44, 0.0), (45, 1.0)):
        take.SetTimeSample(scale.path, t, Gf.Vec3f(s, s, s))
    Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                      Sdf.VariabilityUniform).default = Vt.TokenArray(["xformOp:scale"])
    take.Save()
    shot = _shot(tmp_path, "hidden.usda", rate=30.0, start=40.0, end=44.0)
    layer, gif = tmp_path / "gaze.usdc", tmp_path / "p.gif"
    assert main(["apply", str(rig.path), "--shift", "0.5s:30:0", "--out", str(layer)]) == 0
    capsys.readouterr()
    with warnings.catch_warnings(record=True) as caught:  # a command-line run prints them on stderr
        warnings.simplefilter("always")
        assert main(["preview", str(shot), "--layer", str(layer), "--out", str(gif), "--fps", "24"]) == 0
        assert main(["plot", str(shot), "--layer", str(layer), "--out", str(tmp_path / "p")]) == 0
    assert capsys.readouterr().err == "" and not [str(w.message) for w in caught]
    with Image.open(gif) as im:
        assert im.n_frames == 4  # 4 time codes at 30 per second: 0 to 0.133 s at 24 per second
