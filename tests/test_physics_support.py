"""The planner's guess of the reference's torques carries the body's weight on its feet
(``usdgaze.physics.support``).

The guess is MuJoCo's inverse dynamics of the target with no ground, then the weight, which that
leaves on the root (no motor carries it), shared among the feet near the ground. Measured here by
simulation, not by the guess's own algebra: the CMU character standing (131_01's last frames), its
guessed controls applied open loop with MuJoCo's contacts on. The contact-free inverse alone, as
the test computes it with MuJoCo directly (what the planner used before), moves the limbs but holds
up only each joint's own subtree, so the standing body sinks at hips and knees.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from usdgaze.physics import build, mpc, retarget

from . import stages

H = 0.02
STEPS = 15  # 0.3 s: open loop, any standing guess drifts after a while


@pytest.fixture(scope="module")
def standing():
    clip = build.load_clip(stages.CMU / "cmu_131_01.usdc")
    model, ref = build.body_model(clip)
    still = np.repeat(retarget.to_qpos(model, ref)[stages.STAND_FROM][None], STEPS + 1, axis=0)
    shot = mpc.prepare(model, still, H * np.arange(STEPS + 1), mpc.Options(h=H))
    return shot


def _contact_free(shot) -> np.ndarray:
    """The guess without the support: ``mj_inverse`` with MuJoCo's contacts disabled, the root's residual
    dropped, over the gear, clipped (the standing target: no acceleration)."""
    import mujoco

    mj = copy.copy(shot.plan.mj)
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    d = mujoco.MjData(mj)
    d.qpos[:], d.qvel[:], d.qacc[:] = shot.target[0], 0.0, 0.0
    mujoco.mj_inverse(mj, d)
    gear = np.abs(mj.actuator_gear[:, :3]).max(axis=1)
    return np.clip(d.qfrc_inverse[6:] / gear, -1.0, 1.0)


def _pelvis_heights(shot, controls: np.ndarray) -> np.ndarray:
    """The simulated root's height at each step, the controls applied open loop from the target's first state."""
    sim = shot.sim
    x = sim.to_state(shot.target[0], np.zeros(sim.mj.nv))
    heights = []
    for k in range(STEPS):
        x = sim.step_body(x, controls[k], k)
        heights.append(sim.qpos_of(x)[2])
    return np.array(heights)


def test_the_guess_holds_a_standing_body_up_where_the_contact_free_inverse_lets_it_sink(standing):
    shot = standing
    start = shot.target[0, 2]
    held = _pelvis_heights(shot, shot.tail[:STEPS])
    free = _pelvis_heights(shot, np.repeat(_contact_free(shot)[None], STEPS, axis=0))
    # the guess, open loop: the pelvis within 2.5 cm of where it started over 0.3 s (measured 1.8 cm)
    assert np.abs(held - start).max() <= 0.025, held - start
    # without the support the body sinks (measured 35 cm): the legs' torques held up only the legs
    assert start - free.min() >= 0.15, start - free


def test_the_support_loads_the_legs_not_the_arms(standing):
    """The support changes the legs' torques (hips, knees, ankles) and leaves the arms' and the head's as
    the contact-free inverse made them: the feet's reaction acts on the legs' chain to the root only."""
    shot = standing
    free = _contact_free(shot)
    changed = np.abs(shot.tail[0] - free) > 1e-9
    m = shot.model
    legs = set(m.feet) | set(m.toes)
    for b in list(legs):
        while b >= 0:
            legs.add(b)
            b = int(m.body_parent[b])
    mj = shot.plan.mj
    bodies = mj.jnt_bodyid[mj.actuator_trnid[:, 0]] - 1  # the model's body each motor turns
    on_legs = np.isin(bodies, list(legs))
    assert changed[on_legs].any() and not changed[~on_legs].any(), (bodies[changed], sorted(legs))
