"""The streaming GIF writer: read back by Pillow, every shown frame is the frame given, pixel for
pixel (each with its own palette), an identical frame lengthens the one before, a frame that changes
in a corner is stored as that corner, and frames are written as they come (not all held first)."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image, ImageSequence

from usdgaze.review.gif import write_gif


def _frames() -> list[Image.Image]:
    rng = np.random.default_rng(4)
    out = []
    for k in range(4):
        rgb = rng.integers(0, 256, size=(30, 40, 3), dtype=np.uint8)
        out.append(Image.fromarray(rgb).quantize(colors=16 + 40 * k))  # four palettes of their own
    out.insert(2, out[1].copy())  # the same picture twice
    corner = np.asarray(out[-1].convert("RGB")).copy()
    corner[2:7, 30:38] = (255, 0, 0)
    out.append(Image.fromarray(corner).quantize(colors=200))  # only a corner changes
    return out


def test_every_shown_frame_is_the_frame_given():
    frames = _frames()
    out = io.BytesIO()
    assert write_gif(out, iter(frames), 40) == 6
    gif = Image.open(io.BytesIO(out.getvalue()))
    shown = [(np.asarray(f.convert("RGB")), f.info.get("duration")) for f in ImageSequence.Iterator(gif)]
    wanted = [frames[0], frames[1], frames[3], frames[4], frames[5]]  # frame 2 merged into frame 1
    assert len(shown) == len(wanted)
    for (pixels, _), frame in zip(shown, wanted):
        assert np.array_equal(pixels, np.asarray(frame.convert("RGB")))
    assert [d for _, d in shown] == [40, 80, 40, 40, 40]
    assert gif.info.get("loop") == 0


def test_a_frame_changing_in_a_corner_is_stored_as_that_corner():
    frames = _frames()
    whole, cropped = io.BytesIO(), io.BytesIO()
    write_gif(whole, iter(frames[:5]), 40)
    write_gif(cropped, iter(frames), 40)
    # The last frame adds a few hundred bytes, not a whole frame's (about 1 kB here at least).
    one_frame = io.BytesIO()
    frames[5].save(one_frame, format="GIF")
    assert len(cropped.getvalue()) - len(whole.getvalue()) < 0.5 * len(one_frame.getvalue())


def test_frames_are_written_as_they_come():
    out = io.BytesIO()
    written = []

    def frames():
        for frame in _frames():
            written.append(len(out.getvalue()))
            yield frame

    write_gif(out, frames(), 40)
    # When the fourth frame is drawn, the first two are already in the file.
    assert written[0] == 0 and written[3] > written[1] > 0


def test_frame_delays_keep_the_clock():
    """Delays are whole centiseconds: 24 fps's 4.17 rounded every frame played 4% fast; each delay is
    now where the clock should be after its frame, rounded, less where it was."""
    rng = np.random.default_rng(5)
    frames = [Image.fromarray(rng.integers(0, 256, size=(8, 8, 3), dtype=np.uint8)) for _ in range(48)]
    out = io.BytesIO()
    write_gif(out, iter(frames), 1000.0 / 24)
    delays = [f.info["duration"] for f in ImageSequence.Iterator(Image.open(io.BytesIO(out.getvalue())))]
    assert len(delays) == 48 and set(delays) == {40, 50}
    assert np.all(np.abs(np.cumsum(delays) - 1000.0 / 24 * np.arange(1, 49)) <= 5.0)  # never off by more than half a cs
    assert sum(delays) == 2000
