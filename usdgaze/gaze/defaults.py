"""The built-in gaze map: the paper's target grid, filled from published human head-eye data.

Heck captured one subject on 33 targets: yaw every 36 deg from -180 to 180 (the two 180s are a right
and a left turn) and pitch -12/0/+12 (section 5.2.1; pitch was limited by the capture room, not by
people). We keep that grid and add two rows at pitch -30 and +30 (55 examples), because looking
at the floor or up at a shelf is everyday animation work, and the vertical eye range (elevation
27.7 deg, depression 47.1 deg; Eom et al. 2019, from Serway et al. 2018 / Shin et al. 2016) and
the Freedman & Sparks vertical-share observation below say how such shifts split between eye and head.
Rows beyond +-30 would need trunk flexion data we do not have, so the map extrapolates there.

Every number below carries its source. "assumed" marks a number the literature we rely on does not
pin down; it is a design choice that a studio's own capture (``usdgaze build-map``) replaces.
"""

from __future__ import annotations

import numpy as np

from usdgaze.gaze import motion
from usdgaze.core import rotations as rot
from usdgaze.gaze.definition import GazeMapDefinition, SynthesisSettings
from usdgaze.gaze.motion import GazeMotions

# -- the target grid -----------------------------------------------------------------------------
YAWS = np.arange(-180.0, 180.0 + 1e-9, 36.0)  # Heck 5.2.1: 11 meridians, 36 deg apart
PITCHES = np.array([-30.0, -12.0, 0.0, 12.0, 30.0])  # Heck 5.2.1: -12/0/+12; +-30: see module doc

# -- horizontal split ------------------------------------------------------------------------------
EYE_ONLY_LIMIT = 20.0  # Freedman & Sparks 1997: head contributes ~nothing to shifts < 20 deg
EYE_PLATEAU = 35.0  # Freedman & Sparks 1997: the eye component levels off near 35 deg
HEAD_YAW_MAX = 75.0  # cervical axial rotation ~70-80 deg per side in adults (e.g. Youdas et al. 1992);
#                      beyond it the trunk takes the rest, as in single-step shifts up to 160 deg (Guitton & Volle 1987)
TRUNK_SPLIT = {  # assumed from regional axial mobility: lumbar spine ~10 deg, thoracic ~35 deg
    "pelvis": 0.40,  # (White & Panjabi 1990), the hips turning the pelvis for the rest
    "lowerSpine": 0.15,
    "upperSpine": 0.45,
}

# -- vertical split --------------------------------------------------------------------------------
EYE_ELEVATION_RANGE = 27.7  # Eom et al. 2019 (from Serway et al. 2018 / Shin et al. 2016)
EYE_UP_LIMIT = 25.0  # that range less the 10% head-shift overshoot (27.7 / 1.1 = 25.2)
EYE_DOWN_PLATEAU = 35.0  # Pejsa et al. 2016: eye range 35 deg up/down (depression limit 47.1, Eom)
# Freedman & Sparks 1997: the more vertical the shift, the larger the eye share. Upward, the eyes carry
# the whole shift up to their (overshoot-safe) limit and the head takes the rest; downward, the eyes
# are eye-only to 20 deg like horizontally but level off at the larger depression range. No trunk pitch:
# the +-30 deg rows stay below the ~40 deg where the trunk joins (McCluskey & Cullen 2007).

# -- timing ------------------------------------------------------------------------------------------
SACCADE_BASE_S = 0.025  # saccade main sequence: duration ~ 25 ms + 2.4 ms/deg
SACCADE_PER_DEG_S = 0.0024
HEAD_LATENCY_S = 0.050  # head starts ~20-50 ms after the eyes; LEAP (Pejsa 2016): 50 - 20*predictability ms, unpredictable targets
UPPER_SPINE_LATENCY_S = 0.080  # order eyes -> head -> trunk (Freedman & Sparks; McCluskey & Cullen 2007);
LOWER_SPINE_LATENCY_S = 0.110  # the 30 ms steps down the spine are assumed
PELVIS_LATENCY_S = 0.140
HEAD_SPEED_DEG_S = 75.0  # LEAP base speeds (Pejsa et al. 2016): head 75 deg/s
TRUNK_SPEED_DEG_S = 40.0  # LEAP: torso 40 deg/s
PEAK_TIME = 0.6  # assumed: Kim et al. 2007 see a fast gross shift then a slower correction; the
#                  correction gets the last 40% of the shift
MIN_DURATION_S = 0.25  # assumed: shortest shift including its settle (a 10 deg saccade is ~50 ms)
EYE_ONLY_OVERSHOOT = 0.05  # most saccades show a small dynamic overshoot; 5% assumed
HEAD_OVERSHOOT = 0.10  # Kim et al. 2007: gaze usually overshoots when the head joins; 10% assumed
MOVING_DEG = 0.5  # a segment turning less than this does not set the duration


def trunk_minimum(amplitude: np.ndarray) -> np.ndarray:
    """Minimum torso rotation (deg) for a gaze shift of ``amplitude`` deg (Pejsa et al. 2015/2016)."""
    a = np.asarray(amplitude, dtype=float)
    return np.where(
        a < 20.0, 0.0, np.where(a <= 40.0, 0.078 * a - 1.558, 0.43 * np.exp(0.029 * a) + 0.186)
    )


def _eye_share(amplitude: np.ndarray, plateau: float) -> np.ndarray:
    """Eye amplitude: all of the shift up to 20 deg, then easing toward ``plateau``.

    The exponential's length is ``span`` so that the slope is 1 at 20 deg (no kink): with the
    horizontal plateau it is EYE_APPROACH.
    """
    a = np.abs(amplitude)
    span = plateau - EYE_ONLY_LIMIT
    tail = plateau - span * np.exp(-(a - EYE_ONLY_LIMIT) / span)
    return np.sign(amplitude) * np.where(a <= EYE_ONLY_LIMIT, a, tail)


def split(yaw: np.ndarray, pitch: np.ndarray) -> dict[str, np.ndarray]:
    """Segment amplitudes (deg) of a gaze shift: trunk yaw per segment, head yaw/pitch, eye yaw/pitch."""
    yaw = np.asarray(yaw, dtype=float)
    pitch = np.asarray(pitch, dtype=float)
    h = np.abs(yaw)
    eye_yaw = _eye_share(h, EYE_PLATEAU)
    trunk = trunk_minimum(h)
    head_yaw = np.minimum(np.maximum(h - eye_yaw - trunk, 0.0), HEAD_YAW_MAX)
    trunk = np.maximum(h - eye_yaw - head_yaw, 0.0)
    eye_pitch = np.where(pitch >= 0.0, np.minimum(pitch, EYE_UP_LIMIT), _eye_share(pitch, EYE_DOWN_PLATEAU))
    sign = np.sign(yaw)
    out = {name: sign * share * trunk for name, share in TRUNK_SPLIT.items()}
    out["headYaw"] = sign * head_yaw
    out["headPitch"] = pitch - eye_pitch
    out["eyeYaw"] = sign * eye_yaw
    out["eyePitch"] = eye_pitch
    return out


def _overshoot(offsets: np.ndarray) -> np.ndarray:
    """beta: small for eye-only shifts, full once the head turns 20 deg or more."""
    head_moves = np.clip(np.degrees(rot.angle(offsets[:, 3])) / EYE_ONLY_LIMIT, 0.0, 1.0)
    return EYE_ONLY_OVERSHOOT + (HEAD_OVERSHOOT - EYE_ONLY_OVERSHOOT) * head_moves


def example_motions(yaw: np.ndarray, pitch: np.ndarray) -> GazeMotions:
    """Gaze displacement motions for gaze changes (yaw, pitch) from the rules above."""
    yaw = np.asarray(yaw, dtype=float).ravel()
    pitch = np.asarray(pitch, dtype=float).ravel()
    parts = split(yaw, pitch)
    n = len(yaw)
    offsets = np.empty((n, 5, 4))
    for j, name in enumerate(("pelvis", "lowerSpine", "upperSpine")):
        offsets[:, j] = rot.from_axis_angle(rot.UP, np.radians(parts[name]))
    head_pitch = parts["headPitch"].copy()
    for _ in range(3):
        offsets[:, 3] = rot.yaw_pitch_rotation(parts["headYaw"], head_pitch)
        # The eyes make up the exact target (Heck 5.2.2.2 step 3), without torsion (Listing's law).
        offsets[:, 4] = motion.aim_eyes(offsets[:, :4], yaw, pitch)
        # An oblique upward target can still lift the eyes past their elevation range at the
        # overshoot peak; the head takes that excess.
        beta = _overshoot(offsets)
        peak = rot.rotate(rot.power(offsets[:, 4], 1.0 + beta), rot.FORWARD)
        excess = np.degrees(np.arcsin(np.clip(peak[:, 1], -1.0, 1.0))) - (EYE_ELEVATION_RANGE - 0.2)
        if not np.any(excess > 0):
            break
        head_pitch = head_pitch + np.maximum(excess, 0.0) / (1.0 + beta)

    amp = np.degrees(rot.angle(offsets))  # (n, 5) per-segment rotation angles
    eye_time = SACCADE_BASE_S + SACCADE_PER_DEG_S * amp[:, 4]
    latencies = np.array([PELVIS_LATENCY_S, LOWER_SPINE_LATENCY_S, UPPER_SPINE_LATENCY_S, HEAD_LATENCY_S])
    speeds = np.array([TRUNK_SPEED_DEG_S] * 3 + [HEAD_SPEED_DEG_S])
    segment_time = np.where(amp[:, :4] > MOVING_DEG, latencies + amp[:, :4] / speeds, 0.0)
    gross = np.maximum(eye_time, segment_time.max(axis=1))
    duration = np.maximum(MIN_DURATION_S, gross / PEAK_TIME)

    beta = _overshoot(offsets)
    timing = np.column_stack(
        [duration, latencies[None, :] / duration[:, None], np.full(n, PEAK_TIME), beta]
    )
    return GazeMotions(offsets, timing)


_BUILT_IN: tuple[np.ndarray, GazeMotions] | None = None


def _built_in_examples() -> tuple[np.ndarray, GazeMotions]:
    """The 55 examples, computed once per process (a few ms each time, for every shot) and read-only."""
    global _BUILT_IN
    if _BUILT_IN is None:
        yaw, pitch = np.meshgrid(YAWS, PITCHES, indexing="ij")
        params = np.column_stack([yaw.ravel(), pitch.ravel()])
        motions = example_motions(params[:, 0], params[:, 1])
        for array in (params, motions.offsets, motions.timing):
            array.setflags(write=False)
        _BUILT_IN = params, motions
    return _BUILT_IN


def default_definition(settings: SynthesisSettings | None = None) -> GazeMapDefinition:
    """The built-in map: 55 examples on the 11 x 5 grid (yaw-major, pitch ascending)."""
    params, motions = _built_in_examples()
    return GazeMapDefinition(params, motions, settings or SynthesisSettings())
