"""The body model's collision shapes: a capsule per bone (a sphere for the head), a sole under each
foot, their radii, and how far below its joint a body's shapes reach."""

from __future__ import annotations

import numpy as np

# MuJoCo's geom type codes (``mujoco.mjtGeom``), here so the modules that read a compiled model need not
# import mujoco; tests/test_physics_model.py checks them against it.
SPHERE, CAPSULE = 2, 3


def half_lengths(mj, geoms: np.ndarray) -> np.ndarray:
    """Half-lengths of the given sphere and capsule geoms of the compiled model ``mj`` (0 for a sphere)."""
    return np.where(mj.geom_type[geoms] == CAPSULE, mj.geom_size[geoms, 1], 0.0)


def radii(mass: np.ndarray, lengths: np.ndarray, roles: list[str], height: float) -> np.ndarray:
    """Capsule radii: a cylinder of water of the segment's mass and length (0.6 of that for the trunk's
    and other pieces), the feet 2.5 cm at 1.75 m of height."""
    radius = np.clip(np.sqrt(mass / (1000.0 * np.pi * np.maximum(lengths, 0.05))), 0.015, 0.14) * (
        np.array([0.6 if r in ("trunk", "other") else 1.0 for r in roles]))
    radius[[b for b, r in enumerate(roles) if r == "foot"]] = 0.025 * height / 1.75
    return radius


def geoms(offset, children, seg_vec, roles, rmat, feet, attached=frozenset()) -> list[list[tuple]]:
    """Per body, its shapes in its own frame: ``("capsule", from + to)`` along each bone to a child (or
    along its own segment at a leaf), ``("sphere", centre)`` for a leaf head; none for an attached body."""
    out = []
    for b in range(len(roles)):
        if b in attached:
            out.append([])
            continue
        g = [("capsule", np.concatenate([np.zeros(3), offset[c]])) for c in children[b]
             if np.linalg.norm(offset[c]) > 0.01 and c not in attached]
        if not g and np.linalg.norm(seg_vec[b]) > 0:  # an end site (zero) has no shape
            g = [("capsule", np.concatenate([np.zeros(3), seg_vec[b]]))] if roles[b] != "head" else \
                [("sphere", 0.5 * seg_vec[b])]
        # A sole from below the heel to the toes; a toe joint on its ankle (a zero-length bone) gave a
        # capsule of no length, which MuJoCo refuses: the foot's segment, which runs past it, then.
        toe = offset[children[b][0]] if children[b] else np.zeros(3)
        toe = toe if np.linalg.norm(toe) > 0.01 else seg_vec[b]
        if b in feet and children[b] and np.linalg.norm(toe) > 0.01:
            down = rmat[b].T @ np.array([0, 0, -1.0])
            drop = max(float(toe @ down), 0.0)
            forward = toe - (toe @ down) * down
            heel = down * drop - 0.25 * forward
            g.append(("capsule", np.concatenate([heel, heel + 0.9 * forward])))
        out.append(g)
    return out


def lowest(pos, rmat, geoms, radius, b) -> float:
    """The lowest point of body ``b``'s joint and shapes at rest (model z)."""
    z = [pos[b, 2]]
    for kind, v in geoms[b]:
        pts = v.reshape(-1, 3) if kind == "capsule" else v[None]
        z.extend((pos[b] + pts @ rmat[b].T)[:, 2] - radius[b])
    return float(min(z))
