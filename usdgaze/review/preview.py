"""``usdgaze preview``: the base and the gaze animation drawn headless, as a GIF or MP4 and a PNG
contact sheet. Poses come from :mod:`usdgaze.review.composed` (FK of all frames at once); each
output frame is a handful of Pillow draw calls on a paletted image, so a 10 s shot takes seconds."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdgaze.errors import UsdGazeError
from usdgaze.passes.hidden import held_world
from usdgaze.review import analysis, render

CAMERAS = ("front", "side", "top")
LAYOUTS = ("side-by-side", "overlay")
_ANIMATIONS = {".gif", ".mp4"}


@dataclass
class PreviewOptions:
    camera: str = "front"
    """front, side, top, or the path of a UsdGeom.Camera prim on the stage."""
    layout: str = "side-by-side"
    fps: float = 24.0
    size: int = 360
    """Panel height (and width) in pixels."""
    sheet_count: int = 12
    sheet_columns: int = 4


GIF_MAX_FPS = 50.0
"""A GIF's frame delays are whole centiseconds, and players hold one under 2 for 10: 50 frames per
second at most (at 240 the delays were 0, and it played at about 10)."""


def check_output(path: str | os.PathLike, kind: str, fps: float | None = None, flag: str = "--out") -> Path:
    """An animation (.gif/.mp4, at ``fps``) or a contact sheet (.png) path, or a one-line error naming
    ``flag``, the option that gave it."""
    p = Path(path)
    try:
        import PIL  # noqa: F401
    except ImportError:
        raise UsdGazeError(f"{p}: preview needs Pillow: pip install 'usdgaze[preview]'") from None
    allowed = _ANIMATIONS if kind == "animation" else {".png"}
    if p.suffix.lower() not in allowed:
        want = ".gif or .mp4 (or .png for a contact sheet)" if kind == "animation" else ".png"
        raise UsdGazeError(f"{flag} {p}: must end in {want}")
    if p.suffix.lower() == ".gif" and fps is not None and fps > GIF_MAX_FPS:
        raise UsdGazeError(f"{flag} {p}: --fps {fps:g}: a GIF holds at most {GIF_MAX_FPS:g} frames per second; "
                           "give a lower --fps, or write an .mp4")
    if p.suffix.lower() == ".mp4":
        try:
            import imageio  # noqa: F401
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise UsdGazeError(f"{flag} {p}: MP4 needs imageio-ffmpeg: pip install 'usdgaze[video]' (or write a .gif)") from None
    return p


SHEET_MAX_PIXELS = 178_956_970
"""The largest contact sheet written: Pillow refuses to open a bigger image (twice its
``MAX_IMAGE_PIXELS``, as a decompression bomb), and --sheet-count 200 at --size 2048 (1.7 gigapixels)
had stopped on a MemoryError (exit 1)."""


def check_sheet(opts: PreviewOptions) -> None:
    """A contact sheet of ``opts`` that image readers open, or a one-line error (before any work)."""
    count = max(1, opts.sheet_count)
    cols = max(1, min(opts.sheet_columns, count))
    width = cols * opts.size * (2 if opts.layout == "side-by-side" else 1)
    height = -(-count // cols) * (opts.size + render.LABEL_H)
    if width * height > SHEET_MAX_PIXELS:
        raise UsdGazeError(f"--sheet-count {opts.sheet_count} at --size {opts.size}: a {width} x {height} pixel contact "
                           f"sheet ({width * height / 1e6:.0f} megapixels), more than image readers open "
                           f"({SHEET_MAX_PIXELS / 1e6:.0f}); give fewer frames or a smaller --size")


# -- scene ----------------------------------------------------------------------------------------

def _objects(review, seconds: np.ndarray) -> dict[str, np.ndarray]:
    """An attend run's objects at the given seconds (drawn like look-at targets)."""
    out = {}
    for a in review.attention:
        for path, pos in a.objects.items():
            out[path] = np.stack([np.interp(seconds, a.seconds, pos[:, k]) for k in range(3)], axis=1)
    return out


def _figures(review, which: str, times: np.ndarray, rows: list[np.ndarray]) -> list[render.Figure]:
    """Each character's figure at the output ``times`` (seconds), posed from its own ``rows``."""
    out = []
    objects = _objects(review, times)
    for c, own in zip(review.characters, rows):
        posed = c.base if which == "base" else c.gaze
        units_per_m = _units_per_m(c)
        origin, direction = analysis.sight_or_head(c, posed)
        # The pass's point of sight lies at the fixation distance in the stage's own units; measured by
        # the figure's height (a head at 1.5 m) it was drawn 15% short on the CMU actor.
        reach = (review.fixation_m or 2.0) / c.meters_per_unit
        pos = posed.positions[own]
        bones = _bones(c, posed, units_per_m)
        out.append(render.Figure(
            positions=pos, bones=bones, head=c.chain.head,
            head_forward=analysis.head_direction(c, posed)[own],
            sight_origin=origin[own], sight_end=origin[own] + reach * direction[own],
            body=render.BASE_BODY if which == "base" else render.GAZE_BODY,
            sight=render.BASE_SIGHT if which == "base" else render.GAZE_SIGHT,
            caption="base" if which == "base" else "gaze", focus=c.chain.pelvis,
            targets={**{look.label: look.positions[own] for look in c.looks}, **objects},
        ))
    return out


MAX_BONE_M = 0.6
"""Longer "bones" are root motion (a ground-level root joint under a walking pelvis) or props, not
body segments (an adult's thigh is ~0.45 m): they are not drawn."""


def _bones(c, posed, units_per_m: float) -> list[tuple[int, int]]:
    """(child, parent) pairs drawn as capsules: body segments, not eyes, not root-motion links."""
    pos = posed.positions
    out = []
    for j, p in enumerate(c.parents):
        if p < 0 or j in (c.eyes or ()):
            continue
        if np.linalg.norm(pos[:, j] - pos[:, p], axis=-1).max() <= MAX_BONE_M * units_per_m:
            out.append((j, int(p)))
    return out


def _units_per_m(c) -> float:
    """Stage units per metre as the figure stands: the head joint's rest height is ~1.5 m on an adult.

    A figure that does not stand (laid down or tilted by its parent's transform) has no height above
    the floor to go by (~0: no bone was drawn and preview failed): the head's reach to the farthest
    joint stands for it where the height is under half of that."""
    s2w = held_world(c.skel_to_world)[0]  # as it stands where it is seen (not scaled to nothing)
    rest = np.einsum("ij,kjl->kil", s2w, c.neutral_world)[:, :3, 3]
    offsets = rest[c.chain.head] - rest
    height, reach = float((offsets @ c.up).max()), float(np.linalg.norm(offsets, axis=1).max())
    return max(height if height >= 0.5 * reach else reach, 1e-9) / 1.5


def _camera(review, opts: PreviewOptions, stage, figs, seconds: np.ndarray, width: int, height: int):
    if opts.camera in CAMERAS:
        return render.named_camera(opts.camera, figs, review.characters[0].up, width, height)
    return prim_camera(stage, opts.camera, seconds, width, height)


def prim_camera(stage, path: str, seconds: np.ndarray, width: int, height: int) -> render.Camera:
    """A UsdGeom.Camera of the stage, sampled at the output times (fitted to the panel's width)."""
    from pxr import Sdf, Usd, UsdGeom

    from usdgaze.usd.stage import without_usd_warnings

    if not Sdf.Path.IsValidPathString(path) or not Sdf.Path(path).IsAbsolutePath():
        raise UsdGazeError(f"--camera '{path}': expected front, side, top or the absolute path of a Camera prim")
    prim = stage.GetPrimAtPath(path)
    if not prim or not prim.IsA(UsdGeom.Camera):
        raise UsdGazeError(f"--camera {path}: no Camera prim there")
    cam = UsdGeom.Camera(prim)
    tcps, start = stage.GetTimeCodesPerSecond(), stage.GetStartTimeCode()
    views, projs = [], []
    ratio = 1.0
    with without_usd_warnings():  # a camera that is no transform (NaN) is said below, in one line
        for t in seconds:  # one Gf.Camera per output frame, not per sample
            gf = cam.GetCamera(Usd.TimeCode(start + t * tcps))
            ratio = 1.0 / gf.aspectRatio if gf.aspectRatio > 0 else 1.0
            frustum = gf.frustum
            views.append(np.array(frustum.ComputeViewMatrix()).T)
            projs.append(np.array(frustum.ComputeProjectionMatrix()).T)
    views, projs = np.stack(views), np.stack(projs)
    bad = ~(np.isfinite(views).all(axis=(1, 2)) & np.isfinite(projs).all(axis=(1, 2)))
    if bad.any():
        raise UsdGazeError(f"--camera {path}: its transform or lens is not finite (NaN or infinity) at time code "
                           f"{start + seconds[np.argmax(bad)] * tcps:g}")
    return render.Camera(width, height, views, projection=projs, aperture_ratio=ratio)


# -- drawing --------------------------------------------------------------------------------------

class Palette:
    """The fixed palette every frame is drawn in: named colours plus shading ramps of the bodies."""

    def __init__(self) -> None:
        self.colours: list[tuple[int, int, int]] = []
        self.index: dict[tuple[int, int, int], int] = {}
        for c in (render.BACKGROUND, render.GRID, render.TEXT, render.BASE_SIGHT, render.GAZE_SIGHT,
                  render.NOSE, render.TARGET):
            self.add(c)
        for body in (render.BASE_BODY, render.GAZE_BODY):
            for k in range(render.SHADES + 1):
                self.add(render.shade(body, k / render.SHADES))

    def add(self, c) -> int:
        if c not in self.index:
            self.index[c] = len(self.colours)
            self.colours.append(c)
        return self.index[c]

    def flat(self) -> list[int]:
        return [v for c in self.colours for v in c] + [0] * (3 * (256 - len(self.colours)))


class _PaletteDraw:
    """ImageDraw on a paletted image that takes RGB fills (snapped onto the palette's shading levels)."""

    def __init__(self, image, palette: Palette) -> None:
        from PIL import ImageDraw

        self._d = ImageDraw.Draw(image)
        self._p = palette

    def _i(self, colour):
        if colour is None:
            return None
        return self._p.index.get(colour) if colour in self._p.index else self._p.add(colour)

    # A shape with a point off the picture (behind a camera: NaN, see render.Camera.project) is not drawn.
    def line(self, xy, fill=None, width=1, joint=None):
        if np.isfinite(xy).all():
            self._d.line(xy, fill=self._i(fill), width=width, joint=joint)

    def ellipse(self, xy, fill=None, outline=None, width=1):
        if np.isfinite(xy).all():
            self._d.ellipse(xy, fill=self._i(fill), outline=self._i(outline), width=width)

    def rectangle(self, xy, fill=None, outline=None, width=1):
        if np.isfinite(xy).all():
            self._d.rectangle(xy, fill=self._i(fill), outline=self._i(outline), width=width)

    def text(self, xy, text, fill=None):
        self._d.text(xy, text, fill=self._i(fill))


class Scene:
    """Everything projected once; :meth:`frame` draws one output frame."""

    def __init__(self, review, opts: PreviewOptions, stage, seconds: np.ndarray, rows: list[np.ndarray],
                 size: int) -> None:
        """``rows``: per character, its sample row for each output time in ``seconds``."""
        self.seconds, self.size, self.opts = seconds, size, opts
        base, gaze = _figures(review, "base", seconds, rows), _figures(review, "gaze", seconds, rows)
        self.panels = [base, gaze] if opts.layout == "side-by-side" else [base + gaze]
        cam = _camera(review, opts, stage, base + gaze, seconds, size, size)
        c = review.characters[0]
        upm = _units_per_m(c)
        self.radius = max(1.5, 0.045 * upm * (cam.scale or size / (2.5 * upm)))
        self.head_radius = 2.6 * self.radius
        nose = 0.25 * upm
        self.projected = [[render.project(f, cam, nose) for f in panel] for panel in self.panels]
        grid = render.floor_lines(base + gaze, c.up, spacing=0.5 * upm)
        f = len(seconds)
        self.grid = cam.project(np.broadcast_to(grid.reshape(1, -1, 3), (f, grid.shape[0] * 2, 3))).reshape(f, -1, 2, 3)
        self.palette = Palette()
        self.width = size * len(self.panels)
        self.height = size + render.LABEL_H

    def frame(self, i: int):
        """Output frame ``i``: one paletted image, each panel drawn on its own (clipped to it)."""
        from PIL import Image

        image = Image.new("P", (self.width, self.height), 0)
        image.putpalette(self.palette.flat())
        for k, (panel, projected) in enumerate(zip(self.panels, self.projected)):
            sub = Image.new("P", (self.size, self.height), 0)
            draw = _PaletteDraw(sub, self.palette)
            dy = render.LABEL_H
            for a, b in self.grid[i]:
                draw.line([(a[0], a[1] + dy), (b[0], b[1] + dy)], fill=render.GRID)
            for fig, pr in zip(panel, projected):
                render.draw_figure(draw, fig, pr, i, 0, dy, self.radius, self.head_radius)
            caption = " + ".join(sorted({f.caption for f in panel}))
            draw.text((6, 5), f"{caption}   {self.seconds[i]:6.2f} s", fill=render.TEXT)
            if k:
                draw.line([(0, 0), (0, self.height)], fill=render.GRID)
            image.paste(sub, (k * self.size, 0))
        return image


def sample_rows(seconds: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Output times at ``fps`` over the clip and, for each, the nearest sample's row."""
    if not 1.0 <= fps <= 240.0:  # NaN included; more frames than that only fill memory
        raise UsdGazeError(f"--fps {fps:g}: expected 1 to 240 frames per second")
    times = np.arange(seconds[0], seconds[-1] + 1e-9, 1.0 / fps)
    return times, nearest_rows(seconds, times)


def nearest_rows(seconds: np.ndarray, times: np.ndarray) -> np.ndarray:
    """For each of ``times``, the row of the nearest of ``seconds`` (held before and after the clip)."""
    rows = np.clip(np.searchsorted(seconds, times), 0, len(seconds) - 1)
    earlier = np.clip(rows - 1, 0, len(seconds) - 1)
    return np.where(np.abs(seconds[earlier] - times) <= np.abs(seconds[rows] - times), earlier, rows)


def _span(review) -> np.ndarray:
    """The shot's playback range where the review has one (its frames, whether a sample lies on them
    or not: a 60 Hz take in a 24 fps shot), else the first and last second any character is sampled
    at: characters of several lengths (or sample rates) are all drawn over the whole shot, each from
    its own samples."""
    if review.playback is not None:
        return np.array(review.playback, dtype=float)
    return np.array([min(float(c.seconds[0]) for c in review.characters),
                     max(float(c.seconds[-1]) for c in review.characters)])


def build_scene(review, opts: PreviewOptions, stage, times: np.ndarray | None = None) -> Scene:
    """The scene at ``opts.fps`` (or at the given times, in seconds from the stage start)."""
    if opts.layout not in LAYOUTS:
        raise UsdGazeError(f"--layout {opts.layout}: expected one of {', '.join(LAYOUTS)}")
    if times is None:
        times, _ = sample_rows(_span(review), opts.fps)
        rows = [nearest_rows(c.seconds, times) for c in review.characters]
    else:
        times = np.asarray(times, dtype=float)
        rows = [np.clip(np.searchsorted(c.seconds, times - 1e-9), 0, len(c.seconds) - 1) for c in review.characters]
    return Scene(review, opts, stage, times, rows, opts.size)


def contact_sheet(review, opts: PreviewOptions, stage):
    """``sheet_count`` frames evenly over the clip, in a grid, as one RGB image."""
    from PIL import Image

    span = _span(review)
    times = np.linspace(span[0], span[1], max(1, opts.sheet_count))
    scene = build_scene(review, opts, stage, times)
    cols = max(1, min(opts.sheet_columns, len(times)))
    rows = int(np.ceil(len(times) / cols))
    sheet = Image.new("RGB", (cols * scene.width, rows * scene.height), render.BACKGROUND)
    from PIL import ImageDraw

    draw = ImageDraw.Draw(sheet)
    for i in range(len(times)):
        x, y = (i % cols) * scene.width, (i // cols) * scene.height
        sheet.paste(scene.frame(i).convert("RGB"), (x, y))
        draw.rectangle((x, y, x + scene.width - 1, y + scene.height - 1), outline=render.FRAME)
    return sheet, scene


def write_animation(scene: Scene, path: Path, outputs) -> int:
    """Stage the GIF or MP4 of every frame of ``scene``, drawn one at a time as the writer takes them
    (a long shot's frames never all in memory); returns the frame count."""
    fps = scene.opts.fps
    failed: list[Exception] = []

    def drawn():
        for i in range(len(scene.seconds)):
            try:
                frame = scene.frame(i)
            except Exception as exc:  # a bug in drawing, not a write failure: raised below as itself
                failed.append(exc)
                return
            yield frame

    frames = drawn()
    if path.suffix.lower() == ".gif":
        from usdgaze.review.gif import write_gif

        def write(temp: str) -> None:
            with open(temp, "wb") as out:
                write_gif(out, frames, 1000.0 / fps)
    else:
        def write(temp: str) -> None:
            import imageio.v2 as imageio

            with imageio.get_writer(temp, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                    quality=7, macro_block_size=1, ffmpeg_log_level="error") as w:
                for frame in frames:
                    w.append_data(_even(np.asarray(frame.convert("RGB"))))
    outputs.stage_with(path, write)
    if failed:
        raise failed[0]
    return len(scene.seconds)


def _even(rgb: np.ndarray) -> np.ndarray:
    """The frame with an odd width or height made even by repeating its last column or row: H.264's
    4:2:0 colour needs even sizes (an odd --size failed in ffmpeg)."""
    h, w = rgb.shape[:2]
    return np.pad(rgb, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge") if h % 2 or w % 2 else rgb


def write_png(image, path: Path, outputs) -> None:
    outputs.stage_with(path, lambda temp: image.save(temp, format="PNG", optimize=False))
