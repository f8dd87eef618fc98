"""The physics pass's report of a shot (:mod:`usdgaze.passes.physics`): :class:`ShotReport`, the
problems a simulation is judged by, in words (a fall or a blow-up, a foot sunk below the ground, a
turn away from the reference's heading, a stone missed, an obstacle touched), and the per-step
measures written to the layer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from usdgaze.physics import feasible, mpc

STONE_TOLERANCE_M = 0.05
CATCH_REACH_M = 0.10  # a palm this near the ball caught it (the bar); farther is said, not judged a problem
FOOT_TOLERANCE_M = 0.02  # a foot deeper than this below the ground is a problem (the bar)
HEADING_TOLERANCE_DEG = 30.0  # the body turned further than this from the reference's heading: a problem


@dataclass
class ShotReport:
    skeleton: str
    animation: str
    frames: int
    simulated_s: float
    fell: bool
    fell_at_s: float | None
    min_pelvis_ratio: float
    mean_joint_error_deg: float
    max_foot_below_ground_m: float
    pushes: int
    wall_s: float
    problems: list[str] = field(default_factory=list)
    diverged: bool = False  # cut short by MuJoCo's step blowing up (``fell`` too: the shot failed)
    iterations: int = 1  # the solver's iterations a step of the simulation kept
    window_s: float = 0.6  # its planner window (a shot with stepping stones has theirs: ``shot_options``)
    timestep_s: float = 0.02  # its step h (a shot with a ball to catch or obstacles has theirs: ``shot_options``)
    # A retried shot (``physics._simulate_shot``): the problems of the attempt not kept, each with its iterations.
    other_attempt: list[str] = field(default_factory=list)
    # Problems another simulation cannot mend (a ball never within reach in time, a foot the shot ends
    # before it must land): not simulated again.
    unmendable: list[str] = field(default_factory=list)
    # What in the reference itself no simulated body can follow (``physics.feasible``): said, not retried.
    reference_notes: list[str] = field(default_factory=list)
    # How far the root strayed from the reference's across the ground (a push, a step to a stone or
    # round an obstacle moves it on purpose; a body sliding on its toes, by accident).
    max_root_drift_m: float = 0.0
    # How deep the simulation's soft ground let a foot sink; the written feet (``max_foot_below_ground_m``)
    # were lifted out of it by their legs unless ``--raw-contacts`` (``mpc.Options.ground_feet``).
    contact_depth_m: float = 0.0
    warnings: list[str] = field(default_factory=list)  # of the input stage (``layers.composed_override_notes``)
    # What each task did, met or not, in words (``task_outcomes``): a shot with no problem said nothing of it.
    tasks: list[str] = field(default_factory=list)


def foot_problems(result: mpc.Result) -> list[str]:
    """A foot deeper than ``FOOT_TOLERANCE_M`` below the ground (soft contacts give under a hard
    landing or a loaded toe): the deepest, when, and on how many steps."""
    depth = result.foot_below_ground_m
    deep = int(np.sum(depth > FOOT_TOLERANCE_M))
    if not deep:
        return []
    k = int(np.argmax(depth))
    return [f"a foot {100 * depth[k]:.1f} cm below the ground at {result.seconds[k]:.2f} s "
            f"(over {100 * FOOT_TOLERANCE_M:.0f} cm on {deep} step(s))"]


def heading_problems(result: mpc.Result) -> list[str]:
    """The body turned about the vertical away from the reference's heading by more than
    ``HEADING_TOLERANCE_DEG`` (a spin the joint errors, measured joint by joint, do not see)."""
    turned = result.heading_error_deg
    if not len(turned) or turned.max() <= HEADING_TOLERANCE_DEG:
        return []
    k = int(np.argmax(turned))
    return [f"turned {turned[k]:.0f} deg away from the reference's heading by {result.seconds[k]:.2f} s "
            f"(over {HEADING_TOLERANCE_DEG:.0f} deg on {int(np.sum(turned > HEADING_TOLERANCE_DEG))} step(s))"]


def stone_contacts(distances) -> list[tuple[int, int, float]]:
    """Each contact of a foot on a stone in its per-step ``stoneDistanceM`` (finite while on one):
    its steps ``[a, b)`` and its mean distance to the stone's centre (m)."""
    distances = np.asarray(distances, dtype=float)
    edges = np.flatnonzero(np.diff(np.r_[0, np.isfinite(distances).astype(int), 0]))
    return [(int(a), int(b), float(np.mean(distances[a:b]))) for a, b in zip(edges[::2], edges[1::2])]


def task_problems(result: mpc.Result) -> list[str]:
    """What a task failed to do, in words: stones missed (a contact's mean distance over 5 cm, or no
    touchdown near the reference's: ``StoneTask.problems``) and obstacles touched (first time and the
    deepest overlap)."""
    out = []
    for key, values in result.task_terms.items():
        if key.endswith(".stoneDistanceM"):
            for a, b, miss in stone_contacts(values):
                if miss > STONE_TOLERANCE_M:
                    foot = key.split(".")[1]
                    out.append(f"{foot} {miss * 100:.1f} cm from its stone over {result.seconds[a]:.2f}-{result.seconds[b - 1]:.2f} s")
        if key.endswith(".clearanceM"):
            hit = np.flatnonzero(np.nan_to_num(values, nan=np.inf) < 0)
            if len(hit):
                out.append(f"touched an obstacle at {result.seconds[hit[0]]:.2f} s (overlap up to {-np.nanmin(values) * 100:.1f} cm)")
    return out + result.task_problems


def task_outcomes(result: mpc.Result) -> list[str]:
    """Each task's result in words, from its per-step measures: the palm's nearest approach to a ball,
    the stones' contacts (how many, the farthest from its stone), the obstacles' smallest gap."""
    out, seconds = [], result.seconds
    for key, values in result.task_terms.items():
        task, _, measure = key.rpartition(".")
        values = np.asarray(values, dtype=float)
        if not np.isfinite(values).any():
            continue
        k = int(np.nanargmin(values))
        if measure == "handToBallM":
            said = "caught" if values[k] <= CATCH_REACH_M else f"not caught (over {100 * CATCH_REACH_M:.0f} cm)"
            out.append(f"{task}: the palm {100 * values[k]:.1f} cm from the ball at its nearest, {seconds[k]:.2f} s: {said}")
        elif measure == "clearanceM":
            out.append(f"{task}: smallest gap to an obstacle {100 * values[k]:.1f} cm at {seconds[k]:.2f} s"
                       + (" (touched)" if values[k] < 0 else ""))
        elif measure == "stoneDistanceM":
            misses = [miss for _, _, miss in stone_contacts(values)]
            out.append(f"{task}: {len(misses)} contact(s) on stones, mean distance to the stone's centre at most "
                       f"{100 * max(misses):.1f} cm")
    return out


def shot_summary(clip, result: mpc.Result, frames: int, pushes: int, wall: float) -> tuple[ShotReport, dict]:
    """The shot's report (a fall said plainly) and its per-step measures for the layer."""
    problems = []
    if result.diverged:
        problems.append(f"the simulation diverged at {result.fell_at:.2f} s (MuJoCo's step became unstable)")
    elif result.fell:
        problems.append(f"fell at {result.fell_at:.2f} s (pelvis below {mpc.FALL_RATIO:.0%} of the reference)")
    problems += heading_problems(result) + foot_problems(result) + task_problems(result)
    report = ShotReport(skeleton=clip.skeleton, animation=clip.animation, frames=frames,
                        simulated_s=float(result.seconds[-1] - result.seconds[0]), fell=result.fell,
                        fell_at_s=result.fell_at, min_pelvis_ratio=float(result.pelvis_ratio.min()),
                        mean_joint_error_deg=float(result.joint_error_deg.mean()),
                        max_foot_below_ground_m=float(result.foot_below_ground_m.max()), pushes=pushes,
                        wall_s=wall, problems=problems, diverged=result.diverged,
                        max_root_drift_m=float(result.root_drift_m.max()),
                        contact_depth_m=float(result.sank_m.max()), unmendable=list(result.task_unmendable),
                        reference_notes=result.reference_notes + feasible.scale_notes(clip.scales, clip.anim_joints),
                        tasks=task_outcomes(result))
    terms = {"seconds": result.seconds.tolist(), "pelvisRatio": result.pelvis_ratio.tolist(),
             "jointErrorDeg": result.joint_error_deg.tolist(), "footBelowGroundM": result.foot_below_ground_m.tolist(),
             "contactDepthM": result.sank_m.tolist(),
             "headingErrorDeg": result.heading_error_deg.tolist(), "rootDriftM": result.root_drift_m.tolist()}
    terms.update({key: [float(v) for v in values] for key, values in result.task_terms.items()})  # NaN: no value
    return report, terms
