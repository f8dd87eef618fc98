"""Each body's joint kind (free, ball, hinge, weld), hinge axes and ranges, and motor strengths, by its
segment role and the reference motion (pure numpy)."""

from __future__ import annotations

import numpy as np

from usdgaze.core import rotations as rot
from usdgaze.physics import segments as seg

STILL_DEG = 0.5  # a joint turned less than this on every frame is held still
# Flexion axis = sign * (bone direction x forward): a turn about bone x forward moves the bone's tip
# forward, which flexes an elbow and hyperextends a knee (the signs were the other way round until
# 2026-12-07: every knee and elbow could bend 150 deg backwards and 5 deg past the reference forwards).
_HINGES = {"shank": -1.0, "forearm": 1.0}


def hinges(kind: list[str], roles, bparent, children, rmat, seg_vec, forward):
    """Knees, elbows and toes become hinges (``kind`` is updated): their axes in the body frame and
    every body's range in degrees."""
    n = len(kind)
    axis = np.zeros((n, 3))
    range_deg = np.zeros((n, 2))
    for b in range(1, n):
        range_deg[b] = (0.0, seg.RANGE_DEG.get(roles[b], seg.RANGE_DEG["other"]))
        top = roles[bparent[b]] != roles[b]  # a split bone's first part is the hinge; the others twist
        if roles[b] in _HINGES and top and np.any(seg_vec[b]) and kind[b] == "ball" and forward is not None:
            bone = rmat[b] @ seg_vec[b]
            a = np.cross(bone / np.linalg.norm(bone), forward) * _HINGES[roles[b]]
            if np.linalg.norm(a) > 0.2:
                kind[b] = "hinge"
                a /= np.linalg.norm(a)
                axis[b] = rmat[b].T @ a
                # From 5 deg past straight, measured from the straight limb, not from the rest pose (CMU's
                # rest knees are bent 48 deg), to 5 deg more flexed than at rest: the reference widens it
                # (``fit_to_reference``). Not to an anatomical 150 deg: with that the planner let a knee
                # buckle where it dodged an obstacle (the pelvis under 80% at 0.30 s).
                bent = _flexion(rmat[bparent[b]] @ seg_vec[bparent[b]], bone, a)
                range_deg[b] = (-5.0 - bent, 5.0)
        elif is_toe(roles, bparent, b) and kind[b] == "ball" and forward is not None:
            # The toes bend at the metatarsophalangeal joints: one flexion axis, across the foot.
            kind[b] = "hinge"
            left = np.cross([0.0, 0.0, 1.0], forward)
            axis[b] = rmat[b].T @ (left / np.linalg.norm(left))
            range_deg[b] = (-40.0, 60.0)
    return axis, range_deg


def _flexion(parent_bone: np.ndarray, bone: np.ndarray, axis: np.ndarray) -> float:
    """Degrees a hinge is flexed at rest: ``bone``'s turn from ``parent_bone``'s direction about ``axis``
    (0 where the parent has no segment to measure from)."""
    if not np.any(parent_bone):
        return 0.0
    return float(np.degrees(np.arctan2(np.cross(parent_bone, bone) @ axis, parent_bone @ bone)))


def is_toe(roles: list[str], bparent: np.ndarray, b: int) -> bool:
    return roles[b] == "foot" and roles[bparent[b]] == "foot"


def strengths(roles: list[str], bparent: np.ndarray) -> np.ndarray:
    """Motor strength per body (N m per unit control) from its role. Unnamed joints on the chain from
    the base to the head are the spine, which carries the trunk (they share its mass too) and gets
    the trunk's strength; toes get the toe flexors'."""
    out = np.array([seg.STRENGTH.get(r, seg.STRENGTH["other"]) for r in roles])
    heads = [b for b, r in enumerate(roles) if r == "head"]
    b = int(bparent[heads[0]]) if heads else -1
    while b > 0:
        if roles[b] == "other":
            out[b] = seg.STRENGTH["trunk"]
        b = int(bparent[b])
    for b in range(1, len(roles)):
        if is_toe(roles, bparent, b):
            out[b] = seg.STRENGTH["toe"]
    return out


def welded(name: str, roles: list[str], bparent: np.ndarray, b: int, children) -> bool:
    """End sites and fingers (below the hand) are welded to their parents, as are the eyes (the eye
    model moves them, not the physics; see ``build``): they carry mass but no degrees of freedom."""
    if seg.is_end_joint(name) and not children[b]:
        return True
    return roles[b] == "hand" and roles[bparent[b]] == "hand"


def fit_to_reference(ref: np.ndarray, rel: np.ndarray, kind: list[str], axis: np.ndarray, rng: np.ndarray,
                      weldable: set[int], seg_vec: np.ndarray, bparent: np.ndarray) -> None:
    """Hinge axes along the reference's dominant swing (its turn about the bone itself, a forearm's
    pronation keyed on the elbow, left out); ranges widened to what the motion uses; the ``weldable``
    bodies the reference holds at rest welded, but not a child of a hinge that loses more than that of
    the reference's turn: it takes the rest (``retarget.to_qpos``)."""
    weldable = set(weldable)
    for b in range(1, len(kind)):
        if kind[b] not in ("ball", "hinge"):
            continue
        q = rot.multiply(rot.conjugate(rel[b])[None], ref[:, b])
        rv = rot.to_rotvec(q)
        ang = np.degrees(np.linalg.norm(rv, axis=1))
        if ang.max() < STILL_DEG and b in weldable:
            # A joint the motion holds at rest throughout (CMU's hip and collar joints) is welded:
            # no degrees of freedom the controller would have to hold still.
            kind[b] = "weld"
            continue
        if kind[b] == "ball":
            rng[b, 1] = min(180.0, max(rng[b, 1], float(ang.max()) + 10.0))
            continue
        along = seg_vec[b] / (np.linalg.norm(seg_vec[b]) or 1.0)
        swing = rv - np.outer(rv @ along, along)  # a hinge about the bone would be a twist, not an elbow
        if np.degrees(np.linalg.norm(swing, axis=1)).max() > 10.0:
            _, _, vt = np.linalg.svd(swing, full_matrices=False)
            a = vt[0] * np.sign(vt[0] @ axis[b] or 1.0)
            axis[b] = a / np.linalg.norm(a)
        theta = np.degrees(rv @ axis[b])
        rng[b] = (min(rng[b, 0], float(theta.min()) - 5.0), max(rng[b, 1], float(theta.max()) + 5.0))
        if np.degrees(np.linalg.norm(rv - np.outer(rv @ axis[b], axis[b]), axis=1)).max() > STILL_DEG:
            weldable -= set(np.flatnonzero(bparent == b).tolist())
