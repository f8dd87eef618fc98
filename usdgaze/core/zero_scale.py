"""Zero scales: the transforms that have no inverse (a character or a joint scaled to nothing, as
animators hide one), and the time codes they hold on, for messages (pure numpy)."""

from __future__ import annotations

import numpy as np

_RELATIVE = 1e-9
"""|det| at most this share of what a uniform scaling of the same size has: no inverse. Relative, so
a SkelRoot scaled 1e-9 (a valid, if tiny, character) is not one; an axis scaled to 0 is."""


def singular(linear: np.ndarray) -> np.ndarray:
    """Per matrix of ``linear (..., 3, 3)``: whether it has no usable inverse."""
    det = np.abs(np.linalg.det(linear))
    uniform = np.linalg.norm(linear, axis=(-2, -1)) ** 3 / 5.196  # |det| of a uniform scaling, for that norm
    return det <= _RELATIVE * np.maximum(uniform, 1e-300)


def singular_scales(scales: np.ndarray) -> np.ndarray:
    """Per scale of ``scales (..., 3)`` (a joint's diagonal scale, as UsdSkel writes it): whether the
    joint is scaled to nothing along an axis; the same measure as :func:`singular`."""
    s = np.abs(np.asarray(scales, dtype=float))
    return np.prod(s, axis=-1) <= _RELATIVE * np.maximum(np.sum(s * s, axis=-1) ** 1.5 / 5.196, 1e-300)


def time_code_spans(times: np.ndarray, rows: np.ndarray, most: int = 4) -> str:
    """The time codes of the frames ``rows`` (a mask over ``times``) as runs of consecutive frames:
    ``40 to 44, 60``."""
    edges = np.diff(np.concatenate([[0], rows.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    text = [f"{times[a]:g}" if a == b else f"{times[a]:g} to {times[b]:g}" for a, b in zip(starts[:most], ends[:most])]
    return ", ".join(text) + (f", ... ({len(starts)} spans)" if len(starts) > most else "")
