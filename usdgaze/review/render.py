"""Headless drawing of posed skeletons: cameras project every frame at once (numpy), Pillow draws.

A figure is drawn as depth-sorted, shaded capsules (a dark rim, a lit core, nearer is lighter), the
head as a disc with a short nose along where the head looks, and the line of sight from the eyes to
the point of sight. Lines of sight and noses are drawn last, in fixed colours, so a reader (or a test)
can find them in the picture.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

BACKGROUND = (246, 245, 242)
GRID = (214, 212, 206)
TEXT = (40, 40, 40)
FRAME = (150, 150, 150)
"""Contact sheet tile borders."""
BASE_BODY = (120, 128, 140)
GAZE_BODY = (196, 120, 64)
BASE_SIGHT = (40, 90, 200)
GAZE_SIGHT = (220, 30, 30)
NOSE = (20, 150, 60)
TARGET = (150, 40, 170)
LABEL_H = 22
"""Height of the caption band above each panel, in pixels."""


@dataclass
class Figure:
    """What one panel draws for every frame (stage space)."""

    positions: np.ndarray
    """Joints ``(F, J, 3)``."""
    bones: list[tuple[int, int]]
    """(child, parent) joint pairs."""
    head: int
    head_forward: np.ndarray
    """``(F, 3)`` unit."""
    sight_origin: np.ndarray
    sight_end: np.ndarray
    """Line of sight from the eyes to the point of sight ``(F, 3)``."""
    body: tuple[int, int, int]
    sight: tuple[int, int, int]
    caption: str
    focus: int = 0
    """The joint the named cameras follow (the pelvis)."""
    targets: dict[str, np.ndarray] = field(default_factory=dict)
    """Optional named points ``(F, 3)`` (look-at targets, objects)."""


@dataclass
class Camera:
    """Per-frame projection to panel pixels: ``(x, y, depth)``, depth growing away from the viewer."""

    width: int
    height: int
    view: np.ndarray
    """``(F, 4, 4)`` column-vector world -> camera (x right, y up, -z forward)."""
    scale: float | None = None
    """Orthographic pixels per unit (named cameras)."""
    projection: np.ndarray | None = None
    """``(F, 4, 4)`` column-vector camera -> clip (camera prims), fitted to the panel's width."""
    aperture_ratio: float = 1.0
    """Vertical over horizontal aperture of a camera prim (NDC y spans the vertical one)."""

    def project(self, points: np.ndarray) -> np.ndarray:
        """``(F, N, 3)`` stage points -> ``(F, N, 3)`` pixel x, pixel y, depth."""
        p = np.einsum("fij,fnj->fni", self.view[:, :3, :3], points) + self.view[:, None, :3, 3]
        depth = -p[..., 2]
        if self.projection is None:
            x, y = p[..., 0] * self.scale, p[..., 1] * self.scale
        else:
            clip = np.einsum("fij,fnj->fni", self.projection[:, :, :3], p) + self.projection[:, None, :, 3]
            # A point behind the camera (or on its plane) has no place in the picture: NaN, not drawn
            # (divided by its negative w, it was drawn mirrored, upside down).
            w = np.where(clip[..., 3] > 1e-9, clip[..., 3], np.nan)
            x, y = clip[..., 0] / w * (self.width / 2), clip[..., 1] / w * (self.width / 2) * self.aperture_ratio
        return np.stack([self.width / 2 + x, self.height / 2 - y, depth], axis=-1)


def _basis(kind: str, forward: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, screen up, view direction) of a named camera around a character facing ``forward``."""
    fwd = forward - (forward @ up) * up
    fwd = fwd / np.linalg.norm(fwd)
    left = np.cross(up, fwd)
    if kind == "top":
        d, u = -up, fwd
    else:
        d = -fwd if kind == "front" else left  # side: from the character's right, facing right
        tilt = np.radians(12.0)  # a little from above, so the floor shows as a plane
        d = np.cos(tilt) * d - np.sin(tilt) * up
        u = up - (up @ d) * d
        u = u / np.linalg.norm(u)
    r = np.cross(d, u)
    return r, u, d


def _first_forward(figures: list[Figure], up: np.ndarray) -> np.ndarray:
    """The first figure's head direction on its first frame with one: a character scaled to nothing
    (hidden) has none. Where every figure is hidden on every frame (a shot cut from a take where the
    character is), a horizontal axis of the stage: a NaN camera had stopped the preview (exit 1)."""
    for fig in figures:
        seen = np.flatnonzero(np.linalg.norm(fig.head_forward, axis=-1) > 0.5)  # unit, not 0 or NaN
        if len(seen):
            return fig.head_forward[seen[0]]
    return np.array([0.0, 0.0, 1.0]) if abs(up[2]) < 0.9 else np.array([0.0, 1.0, 0.0])


def named_camera(kind: str, figures: list[Figure], up: np.ndarray, width: int, height: int,
                 margin: float = 0.06) -> Camera:
    """An orthographic front/side/top camera that follows the figures' pelvis over the floor and
    frames everything any figure draws, on every frame, at one scale."""
    f = figures[0].positions.shape[0]
    r, u, d = _basis(kind, _first_forward(figures, up), up)
    root = np.mean([fig.positions[:, fig.focus] for fig in figures], axis=0)
    # A figure with no bone drawn (none short enough) is framed by its joints.
    drawn = [fig.positions[:, sorted({j for bone in fig.bones for j in bone}) or slice(None)] for fig in figures]
    heights = np.concatenate([d.reshape(-1, 3) @ up for d in drawn])
    mid = 0.5 * (heights.min() + heights.max())
    centre = root - np.outer(root @ up, up) + mid * up
    # Frame the bodies and the near part of the lines of sight; a long one may leave the panel.
    near = [fig.sight_origin + 0.35 * (fig.sight_end - fig.sight_origin) for fig in figures]
    pts = np.concatenate([np.concatenate([d, n[:, None]], axis=1) for d, n in zip(drawn, near)], axis=1) - centre[:, None]
    ex, ey = np.abs(pts @ r).max(), np.abs(pts @ u).max()
    scale = min(width * (0.5 - margin) / max(ex, 1e-9), height * (0.5 - margin) / max(ey, 1e-9))
    rot = np.stack([r, u, -d])  # rows: camera axes in stage space
    view = np.tile(np.eye(4), (f, 1, 1))
    view[:, :3, :3] = rot
    view[:, :3, 3] = -(centre @ rot.T)
    return Camera(width, height, view, scale=scale)


def floor_lines(figures: list[Figure], up: np.ndarray, spacing: float) -> np.ndarray:
    """Floor grid segments ``(L, 2, 3)`` covering where the figures go, at the lowest joint's height."""
    pts = np.concatenate([fig.positions.reshape(-1, 3) for fig in figures])
    e1 = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = e1 - (e1 @ up) * up
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    floor = (pts @ up).min()
    a, b = pts @ e1, pts @ e2
    reach = 2.0 * spacing
    ga = np.arange(np.floor((a.min() - reach) / spacing), np.ceil((a.max() + reach) / spacing) + 1) * spacing
    gb = np.arange(np.floor((b.min() - reach) / spacing), np.ceil((b.max() + reach) / spacing) + 1) * spacing
    base = floor * up
    lines = [(base + x * e1 + gb[0] * e2, base + x * e1 + gb[-1] * e2) for x in ga]
    lines += [(base + ga[0] * e1 + y * e2, base + ga[-1] * e1 + y * e2) for y in gb]
    return np.array(lines)


SHADES = 16
"""Shading levels per body colour: a fixed, small palette (GIF frames need no quantizing)."""


def shade(colour, t: float) -> tuple[int, int, int]:
    """``colour`` lit by ``t`` in [0, 1] (0: far and dark, 1: near and light), in SHADES steps."""
    t = round(min(max(float(t), 0.0), 1.0) * SHADES) / SHADES
    k = 0.55 + 0.45 * t
    return tuple(int(min(255, c * k + (255 - c) * 0.25 * t)) for c in colour)


@dataclass
class Projected:
    """A figure projected for every frame: pixel coordinates and per-bone draw order."""

    joints: np.ndarray
    nose: np.ndarray
    sight: np.ndarray
    targets: dict[str, np.ndarray]
    order: np.ndarray
    """``(F, B)`` bone indices far to near."""
    light: np.ndarray
    """``(F, B)`` in [0, 1]."""


def project(fig: Figure, cam: Camera, nose_length: float) -> Projected:
    """Everything one figure draws, projected for all frames at once."""
    joints = cam.project(fig.positions)
    head = fig.positions[:, fig.head]
    nose = cam.project(np.stack([head, head + nose_length * fig.head_forward], axis=1))
    sight = cam.project(np.stack([fig.sight_origin, fig.sight_end], axis=1))
    targets = {k: cam.project(v[:, None])[:, 0] for k, v in fig.targets.items()}
    child = np.array([c for c, _ in fig.bones], dtype=int)
    parent = np.array([p for _, p in fig.bones], dtype=int)
    depth = 0.5 * (joints[:, child, 2] + joints[:, parent, 2])
    order = np.argsort(-depth, axis=1, kind="stable")
    lo, hi = depth.min(), depth.max()
    light = 1.0 - (depth - lo) / max(hi - lo, 1e-9)
    return Projected(joints, nose, sight, targets, order, light)


def draw_figure(draw, fig: Figure, pr: Projected, f: int, dx: int, dy: int, radius: float,
                head_radius: float) -> None:
    """Draw frame ``f`` of a projected figure with its panel origin at (dx, dy)."""
    j = pr.joints[f]
    w = max(2, int(round(2 * radius)))
    for b in pr.order[f]:
        c, p = fig.bones[b]
        xy = [(j[c, 0] + dx, j[c, 1] + dy), (j[p, 0] + dx, j[p, 1] + dy)]
        lit = float(pr.light[f, b])
        draw.line(xy, fill=shade(fig.body, 0.2 * lit), width=w + 2, joint="curve")
        draw.line(xy, fill=shade(fig.body, lit), width=max(1, w - 2), joint="curve")
        for x, y in xy:  # round caps: capsules, not boxes
            draw.ellipse((x - w / 2, y - w / 2, x + w / 2, y + w / 2), fill=shade(fig.body, lit))
    hx, hy = j[fig.head, 0] + dx, j[fig.head, 1] + dy
    draw.ellipse((hx - head_radius, hy - head_radius, hx + head_radius, hy + head_radius),
                 fill=shade(fig.body, 1.0), outline=shade(fig.body, 0.1), width=2)
    for name, t in pr.targets.items():
        x, y = t[f, 0] + dx, t[f, 1] + dy
        draw.rectangle((x - 5, y - 5, x + 5, y + 5), outline=TARGET, width=2)
    s = pr.sight[f]
    draw.line([(s[0, 0] + dx, s[0, 1] + dy), (s[1, 0] + dx, s[1, 1] + dy)], fill=fig.sight, width=3)
    draw.ellipse((s[1, 0] + dx - 4, s[1, 1] + dy - 4, s[1, 0] + dx + 4, s[1, 1] + dy + 4), fill=fig.sight)
    n = pr.nose[f]
    draw.line([(n[0, 0] + dx, n[0, 1] + dy), (n[1, 0] + dx, n[1, 1] + dy)], fill=NOSE, width=3)
    draw.ellipse((n[1, 0] + dx - 3, n[1, 1] + dy - 3, n[1, 0] + dx + 3, n[1, 1] + dy + 3), fill=NOSE)
