"""An attend run's inspection prims (:mod:`usdgaze.usd.attendio` writes them under ``/UsdGazeAttend``)
read back as arrays: per character ``gaze:attend:character`` (its SkelRoot), ``gaze:attend:pointOfSight``
(point3f per frame), per object child ``gaze:attend:object`` (its path), ``gaze:attend:estimate`` and
``gaze:attend:uncertainty`` (float per frame, NaN while not tracked)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from usdgaze.errors import UsdGazeError
from usdgaze.usd.attendio import CHARACTER, ROOT as ATTEND_ROOT


@dataclass
class Attention:
    """An attend run's inspection prims for one character (``/UsdGazeAttend/<character>``)."""

    name: str
    seconds: np.ndarray
    point_of_sight: np.ndarray
    """``(F, 3)`` stage units."""
    objects: dict[str, np.ndarray]
    """Object prim path -> world position ``(F, 3)`` (the estimate where the prim cannot be sampled)."""
    uncertainty: dict[str, np.ndarray]
    """Object prim path -> the belief's position uncertainty ``(F,)`` (NaN while not tracked)."""
    character: str | None = None
    """The SkelRoot path the scope records (None: a layer written before scopes recorded it)."""

    def rows(self, lo: int, hi: int) -> Attention:
        """This record cut to its frames ``lo:hi``."""
        return replace(self, seconds=self.seconds[lo:hi], point_of_sight=self.point_of_sight[lo:hi],
                       objects={k: v[lo:hi] for k, v in self.objects.items()},
                       uncertainty={k: v[lo:hi] for k, v in self.uncertainty.items()})



def _series(attr) -> tuple[np.ndarray, np.ndarray]:
    times = np.array(attr.GetTimeSamples(), dtype=float)
    values = np.array([attr.Get(float(t)) for t in times], dtype=float)
    return times, values


def read_attention(stage, source: str) -> list[Attention]:
    """The attend run's point of sight and per-object uncertainty, if the stage holds them."""
    from usdgaze.usd.targets import sample_target

    scope = stage.GetPrimAtPath(ATTEND_ROOT)
    if not scope:
        return []
    tcps, start = stage.GetTimeCodesPerSecond(), stage.GetStartTimeCode()
    out = []
    for character in scope.GetChildren():
        sight = character.GetAttribute("gaze:attend:pointOfSight")
        if not sight or not sight.GetNumTimeSamples():
            continue
        times, points = _series(sight)
        objects, uncertainty = {}, {}
        for child in character.GetChildren():
            obj = child.GetAttribute("gaze:attend:object")
            unc = child.GetAttribute("gaze:attend:uncertainty")
            if not obj or not unc:
                continue
            path = str(obj.Get())
            uncertainty[path] = np.interp(times, *_series(unc))
            try:
                objects[path] = sample_target(stage, path, times, source)
            except UsdGazeError:  # no such prim here: where the belief put it
                est_t, est = _series(child.GetAttribute("gaze:attend:estimate"))
                objects[path] = np.stack([np.interp(times, est_t, est[:, k]) for k in range(3)], axis=1)
        if objects:
            owner = character.GetAttribute(CHARACTER)
            path = owner.Get() if owner and owner.HasAuthoredValue() else None
            out.append(Attention(character.GetName(), (times - start) / tcps, points, objects, uncertainty,
                                 None if path is None else str(path)))
    return out
