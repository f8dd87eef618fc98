"""The geometry of example parameters a map build needs, with the built-in maps' answers kept here.

Building a map samples random blends inside the Delaunay triangles of its examples' (yaw, pitch)
and between each example and one of its k nearest. scipy.spatial computes both (Qhull, a k-d
tree); importing it costs ~0.2 s, more than building the whole map, so the answers for the
built-in examples are stored here and scipy is imported only for other maps. The stored answers
are scipy's exactly, order included (triangle order and the order of equidistant neighbours on a
regular grid steer the seeded random blends); tests recompute them with scipy. Regenerate with
``python -m usdgaze.gaze.triangulation``.
"""

from __future__ import annotations

import hashlib

import numpy as np

_KNOWN: dict[str, tuple[str, str]] = {
    # built-in default map, 55 examples
    "bd38e79b8665d1611a4be588b3d4c9fc79c9e0edadb1d566ea5dfde22059fd5a:6": ((
        "2,6,7 1,6,2 5,6,0 6,1,0 15,11,10 11,15,16 7,11,12 6,11,7 11,5,10 11,6,5 30,26,25 26,30,31 8,2,7 "
        "8,3,2 8,9,4 3,8,4 43,44,39 38,43,39 13,7,12 13,8,7 9,13,14 8,13,9 17,11,16 11,17,12 17,13,12 "
        "13,17,18 13,19,14 19,13,18 40,36,35 41,36,40 36,30,35 30,36,31 41,46,42 46,47,42 45,46,40 "
        "46,41,40 46,51,52 46,52,47 51,46,50 46,45,50 47,48,42 48,43,42 48,49,44 43,48,44 53,48,52 "
        "52,48,47 48,53,54 49,48,54 24,23,29 23,28,29 19,23,24 23,19,18 33,34,29 28,33,29 34,33,39 "
        "33,38,39 15,21,16 20,21,15 26,21,25 21,20,25 32,26,31 26,32,27 32,33,28 32,28,27 17,22,18 "
        "22,23,18 22,17,16 21,22,16 23,22,28 28,22,27 22,21,26 22,26,27 33,37,38 32,37,33 36,37,31 "
        "37,32,31 37,43,38 43,37,42 37,36,41 37,41,42 "
    ), (
        "0,1,2,5,6,3 1,2,0,3,6,7 2,3,1,0,4,7 3,2,4,1,8,7 4,3,2,9,8,1 5,6,7,10,0,11 6,7,5,8,11,1 "
        "7,6,8,5,9,2 8,7,9,6,13,3 9,8,7,14,4,13 10,11,12,15,5,6 11,12,10,13,6,16 12,11,13,14,10,17 "
        "13,12,14,11,8,18 14,13,12,19,9,8 15,16,17,20,10,21 16,17,15,18,21,11 17,18,16,15,19,12 "
        "18,17,19,16,23,13 19,18,17,24,14,13 20,21,22,25,15,26 21,22,20,23,26,16 22,21,23,20,24,17 "
        "23,22,24,21,28,18 24,23,22,29,19,28 25,26,27,30,20,21 26,27,25,28,21,31 27,28,26,29,25,32 "
        "28,27,29,26,23,33 29,28,27,24,34,23 30,31,32,35,25,26 31,32,30,33,36,26 32,33,31,30,34,37 "
        "33,32,34,31,38,28 34,33,32,39,29,38 35,36,37,40,30,31 36,37,35,38,41,31 37,38,36,35,39,32 "
        "38,37,39,36,43,33 39,38,37,44,34,43 40,41,42,45,35,46 41,42,40,43,36,46 42,41,43,44,40,47 "
        "43,42,44,41,38,48 44,43,42,49,39,48 45,46,47,40,50,41 46,47,45,48,51,41 47,46,48,45,49,42 "
        "48,47,49,46,53,43 49,48,47,54,44,53 50,51,52,45,46,53 51,52,50,53,46,47 52,51,53,50,54,47 "
        "53,52,54,51,48,47 54,53,52,49,48,51 "
    )),
    # Heck 5.2.1's 33 targets (the default's pitch -12/0/12 rows)
    "cfc233f7f6562e08fcac5c129230f27c50e4031e64d6689a0b11ac871130d63e:6": ((
        "3,1,0 1,3,4 4,3,7 3,6,7 5,1,4 1,5,2 5,4,7 8,5,7 31,27,30 27,31,28 25,21,24 21,25,22 27,25,24 "
        "25,27,28 8,10,11 10,8,7 6,10,7 9,10,6 17,19,20 19,17,16 19,23,20 23,19,22 13,9,12 13,10,9 "
        "13,14,11 10,13,11 13,12,15 13,15,16 13,17,14 17,13,16 18,19,16 15,18,16 18,21,22 19,18,22 "
        "31,29,28 29,31,32 25,26,22 26,23,22 26,25,28 29,26,28 "
    ), (
        "0,1,2,3,4,5 1,2,0,4,5,3 2,1,0,5,4,3 3,4,5,6,0,1 4,5,3,7,1,6 5,4,3,8,2,7 6,7,8,9,3,4 7,8,6,10,4,9 "
        "8,7,6,11,5,4 9,10,11,12,6,7 10,11,9,13,7,8 11,10,9,8,14,7 12,13,14,15,9,16 13,14,12,10,16,11 "
        "14,13,12,17,11,16 15,16,17,18,12,19 16,17,15,13,19,18 17,16,15,14,20,19 18,19,20,15,21,22 "
        "19,18,20,16,22,17 20,19,18,23,17,22 21,22,23,24,18,19 22,21,23,25,19,20 23,22,21,26,20,19 "
        "24,25,26,21,27,22 25,26,24,22,28,29 26,25,24,29,23,22 27,28,29,30,24,25 28,29,27,25,31,24 "
        "29,28,27,32,26,31 30,31,32,27,28,29 31,30,32,28,27,29 32,31,30,29,28,27 "
    )),
}


def params_key(params: np.ndarray, k: int) -> str:
    """Content key of an ``(E, 2)`` parameter array and a neighbour count."""
    digest = hashlib.sha256(np.ascontiguousarray(params, dtype=float).tobytes()).hexdigest()
    return f"{digest}:{int(k)}"


def computed(params: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """scipy's answer: Qhull's Delaunay triangles ``(T, 3)`` (none where the points span no area)
    and each example's ``k`` nearest examples ``(E, k)``, itself first."""
    from scipy.spatial import Delaunay, QhullError, cKDTree  # imported where used: ~0.2 s

    try:
        triangles = Delaunay(params).simplices.astype(np.intp)
    except (QhullError, ValueError):
        triangles = np.zeros((0, 3), dtype=np.intp)
    _, near = cKDTree(params).query(params, k=k)
    return triangles, np.asarray(near, dtype=np.intp).reshape(len(params), k)


def _ints(text: str, width: int) -> np.ndarray:
    return np.array([int(i) for i in text.replace(",", " ").split()], dtype=np.intp).reshape(-1, width)


def example_geometry(params: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Delaunay triangles and ``k`` nearest examples of ``params``: stored for the built-in maps,
    else computed with scipy (see :func:`computed`)."""
    known = _KNOWN.get(params_key(params, k))
    if known is None:
        return computed(params, k)
    triangles, near = known
    return _ints(triangles, 3), _ints(near, k)


def _rows(values: np.ndarray) -> str:
    import textwrap

    body = " ".join(",".join(str(int(i)) for i in row) for row in values)
    return "\n".join(f'        "{w} "' for w in textwrap.wrap(body, 96))


def _table(named: dict[str, tuple[np.ndarray, int]]) -> str:
    """Source lines of ``_KNOWN`` for the named parameter arrays and neighbour counts."""
    out = []
    for label, (params, k) in named.items():
        triangles, near = computed(params, k)
        out.append(f'    # {label}\n    "{params_key(params, k)}": ((\n{_rows(triangles)}\n    ), (\n'
                   f'{_rows(near)}\n    )),')
    return "\n".join(out)


def builtin() -> dict[str, tuple[np.ndarray, int]]:
    """What is stored: the built-in map's parameters and Heck 5.2.1's 33 targets, with its blend size."""
    from usdgaze.gaze import defaults

    definition = defaults.default_definition()
    full, k = definition.params, int(min(max(definition.settings.blend_size, 2), len(definition.params)))
    grid = full[np.isin(full[:, 1], [-12.0, 0.0, 12.0])]
    return {"built-in default map, 55 examples": (full, k),
            "Heck 5.2.1's 33 targets (the default's pitch -12/0/12 rows)": (grid, min(k, len(grid)))}


if __name__ == "__main__":
    print(_table(builtin()))
