"""The marker-set description (TOML): which markers make which landmark, and the lab's up axis.

Heck 5.2.1.1 marks the spine with three triangles, the head with a square (plus a top marker) and the
base of the spine with one reference marker. They drive the P+ segments as follows::

    lower_back  (triangle)  -> pelvis
    upper_back  (triangle)  -> lowerSpine
    neck_base   (triangle)  -> upperSpine
    head        (square)    -> neck  (the head relative to the neck base)
    (no markers)            -> eyes  (inferred from the known target)

A triangle lists 3 markers in any fixed order; a landmark may also be a square of 4 markers listed
left-front, left-back, right-back, right-front (the head must be one). ``head_top`` is optional and
only checks that the square is not listed mirrored. Labels match with or without a ``Subject:``
prefix (``T1`` matches ``Daphnee:T1``).

An optional ``[skeleton]`` table binds joints for UsdSkel example clips (see :mod:`.skelclips`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from usdgaze.errors import UsdGazeError
from usdgaze.files.tomlio import load_toml

LANDMARKS = ("lower_back", "upper_back", "neck_base", "head")
"""Marker landmarks in P+ segment order: pelvis, lowerSpine, upperSpine, neck."""

SKELETON_ROLES = ("pelvis", "lowerSpine", "upperSpine", "neck", "head")
"""Joint roles a ``[skeleton]`` table may bind; the extraction reads the last pelvis, lower-spine and
upper-spine joints and the head (the head relative to the upper spine is the P+ neck segment)."""

AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


class MarkerSetError(UsdGazeError):
    """The marker set is malformed or names markers a capture lacks."""


def parse_axis(value: str, where: str) -> np.ndarray:
    """``"Z"`` / ``"-Y"`` -> unit vector."""
    text = str(value).strip().upper()
    sign = -1.0 if text.startswith("-") else 1.0
    name = text.lstrip("+-")
    if name not in AXES:
        raise MarkerSetError(f"{where}: up_axis '{value}' is not one of X, Y, Z (optionally signed)")
    return sign * np.array(AXES[name])


@dataclass(frozen=True)
class SkeletonBinding:
    """How to find the example skeleton's chain: joint names or paths per role, optional overrides."""

    joints: dict[str, str] = field(default_factory=dict)
    forward: tuple[float, float, float] | None = None
    up_axis: str | None = None
    skeleton: str | None = None


@dataclass(frozen=True)
class MarkerSet:
    """Landmarks (label tuples), the head top and base-of-spine labels, and the lab up axis."""

    landmarks: dict[str, tuple[str, ...]]
    base_of_spine: str | None = None
    head_top: str | None = None
    up_axis: str = "Z"
    subject: str | None = None
    skeleton: SkeletonBinding = field(default_factory=SkeletonBinding)
    source: str = "<marker set>"

    @property
    def up(self) -> np.ndarray:
        return parse_axis(self.up_axis, self.source)

    def labels(self) -> list[str]:
        """Every label the set names, landmarks first, in a fixed order."""
        out = [label for name in LANDMARKS if name in self.landmarks for label in self.landmarks[name]]
        out += [x for x in (self.head_top, self.base_of_spine) if x]
        return out

    def require_complete(self) -> None:
        """Building a map needs all four landmarks and the base-of-spine marker."""
        missing = [name for name in LANDMARKS if name not in self.landmarks]
        if missing:
            raise MarkerSetError(f"{self.source}: [markers] lacks {', '.join(missing)} (a map needs all four landmarks)")
        if not self.base_of_spine:
            raise MarkerSetError(f"{self.source}: [markers] lacks base_of_spine (the reference of root stabilization)")


def skeleton_binding(table: dict, where: str) -> SkeletonBinding:
    """Parse a ``[skeleton]`` table (used by marker sets and TOML sheets)."""
    if not isinstance(table, dict):
        raise MarkerSetError(f"{where}: [skeleton] must be a table")
    aliases = {"lower_spine": "lowerSpine", "upper_spine": "upperSpine"}
    joints: dict[str, str] = {}
    for key, value in table.items():
        role = aliases.get(key, key)
        if role in SKELETON_ROLES:
            joints[role] = str(value)
        elif key not in ("forward", "up_axis", "path"):
            raise MarkerSetError(
                f"{where}: unknown key skeleton.{key} (expected pelvis, lower_spine, upper_spine, neck, head, forward, up_axis, path)"
            )
    forward = table.get("forward")
    if forward is not None:
        if not (isinstance(forward, list) and len(forward) == 3):
            raise MarkerSetError(f"{where}: [skeleton] forward must be a list of 3 numbers")
        forward = tuple(float(x) for x in forward)
    up = table.get("up_axis")
    if up is not None:
        parse_axis(up, where)
    return SkeletonBinding(joints=joints, forward=forward, up_axis=up, skeleton=table.get("path"))


def load_markerset(path: str | Path) -> MarkerSet:
    """Read a marker-set TOML file (see ``pipeline/examples/markerset.toml``)."""
    where = str(path)
    data = load_toml(path, MarkerSetError)
    table = data.get("markers", {})
    if not isinstance(table, dict):
        raise MarkerSetError(f"{where}: [markers] must be a table")
    landmarks: dict[str, tuple[str, ...]] = {}
    for name in LANDMARKS:
        value = table.get(name)
        if value is None:
            continue
        if not (isinstance(value, list) and all(isinstance(v, str) for v in value)):
            raise MarkerSetError(f"{where}: markers.{name} must be a list of marker labels")
        if name == "head" and len(value) != 4:
            raise MarkerSetError(f"{where}: markers.head must list the 4 square markers (left-front, left-back, right-back, right-front)")
        if len(value) not in (3, 4):
            raise MarkerSetError(f"{where}: markers.{name} lists {len(value)} markers; a triangle needs 3, a square 4")
        if len(set(value)) != len(value):
            raise MarkerSetError(f"{where}: markers.{name} names a marker twice")
        landmarks[name] = tuple(value)
    unknown = sorted(set(table) - set(LANDMARKS) - {"base_of_spine", "head_top"})
    if unknown:
        raise MarkerSetError(f"{where}: unknown key markers.{unknown[0]} (expected {', '.join(LANDMARKS)}, head_top, base_of_spine)")
    up_axis = str(data.get("up_axis", "Z"))
    parse_axis(up_axis, where)
    return MarkerSet(
        landmarks=landmarks,
        base_of_spine=table.get("base_of_spine"),
        head_top=table.get("head_top"),
        up_axis=up_axis,
        subject=data.get("subject") or None,
        skeleton=skeleton_binding(data.get("skeleton", {}), where),
        source=where,
    )


def _bare(label: str) -> str:
    return label.rsplit(":", 1)[-1].strip().lower()


def resolve_labels(wanted: list[str], labels: tuple[str, ...], subject: str | None, where: str) -> list[int]:
    """Indices of ``wanted`` marker labels in a capture's ``labels``.

    An exact match wins; otherwise a label matches ignoring a ``Subject:`` prefix (``subject`` picks one
    when several subjects carry the same label).
    """
    exact = {label: i for i, label in enumerate(labels)}
    by_bare: dict[str, list[int]] = {}
    for i, label in enumerate(labels):
        by_bare.setdefault(_bare(label), []).append(i)
    out = []
    for name in wanted:
        if name in exact:
            twice = [i for i, label in enumerate(labels) if label == name]
            if len(twice) > 1:  # exact lookup would take the last one without a word
                raise MarkerSetError(f"{where}: marker '{name}' is ambiguous ({', '.join(labels[i] for i in twice)}); "
                                     f"the file labels {len(twice)} trajectories alike")
            out.append(exact[name])
            continue
        hits = by_bare.get(_bare(name), [])
        if len(hits) > 1 and subject:
            hits = [i for i in hits if labels[i].lower().startswith(subject.lower() + ":")]
        if not hits:
            raise MarkerSetError(f"{where}: marker '{name}' is not in the file ({len(labels)} labels, e.g. {', '.join(labels[:4])})")
        if len(hits) > 1:
            raise MarkerSetError(f"{where}: marker '{name}' is ambiguous ({', '.join(labels[i] for i in hits)}); set subject in the marker set")
        out.append(hits[0])
    return out
