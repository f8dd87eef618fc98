"""Binding hints a user gives without editing the input: ``--bind ROLE=JOINT[+JOINT...]`` and
``--forward X,Y,Z``, on the command line or in a batch manifest. One parser for both, so a hint
means the same and fails the same wherever it is written.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from usdgaze.errors import UsdGazeError
from usdgaze.gaze.definition import ROLES


@dataclass(frozen=True)
class BindHints:
    """Explicit role bindings and character forward, as given (joints by path or by their own name)."""

    bindings: tuple[tuple[str, tuple[str, ...]], ...] = ()
    forward: tuple[float, float, float] | None = None
    """Character forward in skeleton space."""
    bind_label: str = "--bind"
    forward_label: str = "--forward"

    def as_dict(self) -> dict[str, tuple[str, ...]]:
        return dict(self.bindings)

    def __bool__(self) -> bool:
        return bool(self.bindings) or self.forward is not None


def _bind_item(text, label: str) -> tuple[str, tuple[str, ...]]:
    if not isinstance(text, str):
        raise UsdGazeError(f"{label} {text!r}: expected a \"ROLE=JOINT[+JOINT...]\" string")
    role, sep, joints = text.partition("=")
    role, parts = role.strip(), [p.strip() for p in joints.split("+")]
    if not sep or not role or not all(parts):
        raise UsdGazeError(f"{label} '{text}': expected ROLE=JOINT[+JOINT...], e.g. head=j7 or neck=j5+j6")
    return role, tuple(parts)


def _forward(value, label: str) -> tuple[float, float, float]:
    if isinstance(value, str):
        items = value.split(",")
    elif isinstance(value, (list, tuple)):
        items = list(value)
    else:
        raise UsdGazeError(f"{label} {value!r}: expected X,Y,Z (skeleton space), e.g. 0,0,1")
    try:
        vec = tuple(float(v) for v in items)
    except (TypeError, ValueError):
        vec = ()
    if isinstance(value, (list, tuple)) and any(isinstance(v, (bool, str)) for v in value):
        vec = ()
    if len(vec) != 3 or not all(math.isfinite(v) for v in vec):
        raise UsdGazeError(f"{label} {value!r}: expected three finite numbers X,Y,Z (skeleton space), e.g. 0,0,1")
    if not any(vec):
        raise UsdGazeError(f"{label} {value!r}: the zero vector is no direction")
    big = max(abs(v) for v in vec)  # scaled first: 1e300 or 1e-320 would overflow or vanish when squared
    scaled = [v / big for v in vec]
    norm = math.sqrt(sum(v * v for v in scaled))
    return tuple(v / norm for v in scaled)  # type: ignore[return-value]


def parse_hints(bind: Iterable[str] | Mapping[str, object] | None = None, forward=None,
                bind_label: str = "--bind", forward_label: str = "--forward") -> BindHints:
    """Check and normalise binding hints.

    ``bind``: ``ROLE=JOINT[+JOINT...]`` strings (repeatable flag, manifest list), or a mapping
    role -> joint or list of joints (manifest table). ``forward``: ``"X,Y,Z"`` or three numbers.
    Labels name the flag or manifest key in messages. Raises :class:`UsdGazeError` (exit 2).
    """
    items: list[tuple[str, tuple[str, ...]]] = []
    if isinstance(bind, Mapping):
        for role, joints in bind.items():
            joints = [joints] if isinstance(joints, str) else joints
            if not isinstance(joints, (list, tuple)) or not joints or not all(isinstance(j, str) and j.strip() for j in joints):
                raise UsdGazeError(f"{bind_label}.{role}: expected a joint name or a list of joint names")
            items.append((str(role), tuple(j.strip() for j in joints)))
    elif bind is not None:
        if isinstance(bind, str):
            bind = [bind]
        if not isinstance(bind, (list, tuple)):
            raise UsdGazeError(f"{bind_label} {bind!r}: expected ROLE=JOINT strings or a table of role = joint(s)")
        items = [_bind_item(t, bind_label) for t in bind]
    seen = set()
    for role, _ in items:
        if role not in ROLES:
            raise UsdGazeError(f"{bind_label} {role}=...: unknown role '{role}' (roles: {', '.join(ROLES)})")
        if role in seen:
            raise UsdGazeError(f"{bind_label} {role}=...: role given twice; join its joints with '+'")
        seen.add(role)
    vec = _forward(forward, forward_label) if forward is not None else None
    return BindHints(tuple(items), vec, bind_label, forward_label)


def to_record(hints: BindHints) -> dict:
    """The hints as a layer's ``customLayerData["usdgaze"]`` keys (none when there are none), so that
    the review tools bind the chain the way the pass did."""
    record: dict = {}
    if hints.bindings:
        record["bind"] = [f"{role}={'+'.join(joints)}" for role, joints in hints.bindings]
    if hints.forward is not None:
        record["forward"] = [float(v) for v in hints.forward]
    return record


def _listed(value):
    """A recorded array (``Vt.StringArray``, ``Vt.DoubleArray``) as a list; anything else as it is, for
    :func:`parse_hints` to refuse in one line (``list(7)`` of a hand-edited record was exit 1)."""
    if value is None or isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__"):
        return value
    return list(value)


def from_record(record: Mapping, where: str) -> BindHints:
    """The hints an override layer recorded (see :func:`to_record`)."""
    bind, forward = (_listed(record.get(k)) for k in ("bind", "forward"))
    return parse_hints(bind, forward,
                       bind_label=f"{where}: customLayerData usdgaze.bind",
                       forward_label=f"{where}: customLayerData usdgaze.forward")
