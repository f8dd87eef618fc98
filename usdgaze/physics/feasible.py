"""What in a reference motion a physical body cannot do, said before anyone blames the controller.

A stance foot does not slide. Keyframed or procedural walks often skate (the body glides while the
legs swing, the feet never planted), and a simulated body can follow that only by sliding on its
soles, which friction forbids: it lags, turns about the vertical or falls. On the CMU walks the
lower toe, on the ground, moves at a median 0.15-0.17 m/s and over 1 m/s on 0-2.5% of those steps
(a toe-off); on the synthetic skating walk at a median 1.13 m/s, over 1 m/s on 57% (docs/physics.md).
"""

from __future__ import annotations

import numpy as np

GROUND_BAND_M = 0.03  # the lower toe this close to its lowest height counts as on the ground
SLIDE_SPEED = 1.0  # m/s: a planted toe rolls and settles, it does not move this fast
SLIDE_SHARE = 0.2  # of the steps a toe is on the ground


def toe_paths(dyn, qpos: np.ndarray) -> np.ndarray:
    """World positions ``(K, feet, 3)`` of each foot chain's last body at the ``qpos`` states."""
    import mujoco

    from usdgaze.physics.stones import feet

    toes = [toe for _, _, toe in feet(dyn)]
    d = mujoco.MjData(dyn.mj)
    out = np.empty((len(qpos), len(toes), 3))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(dyn.mj, d)
        out[k] = d.xpos[toes]
    return out


def sliding_stance(toes: np.ndarray, h: float) -> str | None:
    """Why the reference's feet cannot be followed (they slide while on the ground), or None.

    ``toes``: :func:`toe_paths` at steps of ``h`` seconds. At each step the lower toe is the stance
    foot's; where it is on the ground its speed over the ground plane is judged."""
    if toes.shape[1] == 0 or len(toes) < 3:
        return None
    speed = np.linalg.norm(np.gradient(toes[..., :2], h, axis=0), axis=-1)
    lower = np.argmin(toes[..., 2], axis=1)
    k = np.arange(len(toes))
    height, stance_speed = toes[k, lower, 2], speed[k, lower]
    down = height < toes[..., 2].min() + GROUND_BAND_M
    if not down.any():
        return None
    fast = stance_speed[down] > SLIDE_SPEED
    if fast.mean() <= SLIDE_SHARE:
        return None
    return (f"the reference's feet slide: its lower toe moves over {SLIDE_SPEED:g} m/s on {fast.mean():.0%} of "
            f"the steps it is on the ground (median {np.median(stance_speed[down]):.2f} m/s), which a body "
            "standing on its soles cannot follow")


def scale_notes(scales: np.ndarray, joints: list[str]) -> list[str]:
    """A reference whose joint scales ``(F, J, 3)`` change over the shot: the body is built at one set
    of proportions and the layer keeps the input's scales, so what plays back is not what was simulated
    (thighs scaled 1.5 put the played-back feet 57 cm into the ground where the simulation stood)."""
    scales = np.asarray(scales, dtype=np.float32)
    varying = np.flatnonzero(np.ptp(scales, axis=0).max(axis=-1) > 1e-3) if len(scales) > 1 else []
    if not len(varying):
        return []
    names = [str(joints[j]).rsplit("/", 1)[-1] for j in varying[:3]]
    more = f" and {len(varying) - 3} more" if len(varying) > 3 else ""
    return [f"joint scales are animated ({', '.join(names)}{more}): the physics body keeps its rest proportions "
            "and the layer the input's scales, so the played-back body is not the simulated one"]


OFF_GROUND_M = 0.10
"""A reference whose feet never come nearer the ground (up = 0) than this stands on something else."""


def never_on_ground(mj, model, qpos: np.ndarray, seconds: np.ndarray) -> str | None:
    """Why the reference ``qpos`` (model coordinates, one row a frame) cannot stand on the simulated
    ground, or None: its feet, with the model's soles, stay above ``OFF_GROUND_M`` on every frame (a
    character on a raised floor or a platform, a rig placed up in the set). Simulated, it drops onto
    the stage's up = 0 plane and falls (a character 1 m up fell at 0.30 s, the report blaming the
    controller)."""
    from usdgaze.physics.measures import foot_geoms, lowest_zs

    geoms = foot_geoms(mj, model)
    if not len(geoms) or not len(qpos):
        return None
    low = lowest_zs(mj, qpos, geoms)
    k = int(np.argmin(low))
    if low[k] <= OFF_GROUND_M:
        return None
    return (f"the reference's feet are never nearer the ground than {100 * low[k]:.1f} cm (at {seconds[k]:.2f} s); "
            "the simulated ground is the stage's up = 0 plane, so the body would drop onto it: a raised floor is "
            "not modelled; move the character (and its objects) down onto the ground")
