"""Extraction (Heck 5.2.2.2): landmark frames, P+ and the eyes, overshoot peak, start detection."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdgaze.gaze import motion
from usdgaze.core import rotations as rot
from usdgaze.ingest.extract import ExtractionError, extract, first_above, onset_fit, overshoot_peak, pose_offsets
from usdgaze.ingest.frames import FrameError, character_frame, fit_frames, square_frames, triangle_frames
from usdgaze.ingest.settings import BuildSettings


def _rigid(shape: np.ndarray, rotations: Rotation, shift: np.ndarray) -> np.ndarray:
    return np.stack([rotations[i].apply(shape) for i in range(len(rotations))]) + shift[:, None, :]


@pytest.mark.parametrize("kind", ["triangle", "square"])
def test_landmark_frames_turn_with_the_markers(kind):
    rng = np.random.default_rng(2)
    shape = (np.array([[60.0, 0, 0], [-60.0, 0, 0], [0, 100.0, 10.0]]) if kind == "triangle"
             else np.array([[80.0, 0, 70], [80.0, 5, -70], [-80.0, 5, -70], [-80.0, 0, 70]]))
    turns = Rotation.random(12, random_state=3)
    points = _rigid(shape, turns, rng.normal(0, 500, (12, 3)))
    frames = triangle_frames(points) if kind == "triangle" else square_frames(points)
    fitted = fit_frames(points, frames)
    truth = (turns * turns[0].inv()).as_quat()  # motion relative to the first frame
    for q in (frames, fitted):
        measured = rot.multiply(q, rot.conjugate(q[:1]))
        np.testing.assert_allclose(np.degrees(rot.angle(rot.relative(measured, truth))), 0.0, atol=1e-9)


def test_square_frame_axes_follow_the_listed_order():
    # left-front, left-back, right-back, right-front of a head facing +X with +Y its left, Z up
    square = np.array([[[50.0, 40, 0], [-50.0, 40, 0], [-50.0, -40, 0], [50.0, -40, 0]]])
    q = square_frames(square)[0]
    np.testing.assert_allclose(rot.rotate(q, rot.FORWARD), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rot.rotate(q, rot.LEFT), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rot.rotate(q, rot.UP), [0, 0, 1], atol=1e-12)


def test_degenerate_markers_and_vertical_forward_are_errors():
    with pytest.raises(FrameError, match="degenerate"):
        triangle_frames(np.array([[[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]]]))
    with pytest.raises(FrameError, match="vertical"):
        character_frame(np.array([0.0, 0.0, 3.0]), np.array([0.0, 0.0, 1.0]))


def test_character_frame_takes_only_the_heading():
    q = character_frame(np.array([0.0, 2.0, -0.5]), np.array([0.0, 0.0, 1.0]))  # forward +Y pitched down
    np.testing.assert_allclose(rot.rotate(q, rot.FORWARD), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rot.rotate(q, rot.UP), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(rot.rotate(q, rot.LEFT), [-1, 0, 0], atol=1e-12)


def test_pose_offsets_undo_forward_kinematics_in_a_turned_lab():
    """Globals built from known local offsets, in a lab whose character frame is turned, give them back."""
    rng = np.random.default_rng(5)
    local = rot.from_rotvec(rng.normal(0.0, 0.4, (4, 3)))
    lab = rot.frame_rotation(np.array([0.0, 1, 0]), np.array([0.0, 0, 1]), np.array([1.0, 0, 0]))
    rest = rot.from_rotvec(rng.normal(0.0, 1.0, (4, 3)))  # landmark frames are not the character's axes
    chain = local.copy()
    for j in range(1, 4):
        chain[j] = rot.multiply(chain[j - 1], local[j])
    first = rest
    last = rot.multiply(rot.conjugate_into(lab, chain), rest)
    offsets = pose_offsets(first, last, lab, 50.0, -10.0)
    np.testing.assert_allclose(np.degrees(rot.angle(rot.relative(offsets[:4], local))), 0.0, atol=1e-9)
    np.testing.assert_allclose(motion.achieved_gaze(offsets, 50.0), [50.0, -10.0], atol=1e-9)


def test_overshoot_peak_is_the_first_forward_then_back_flip():
    v = np.array([-1.0, 1.0, -0.5, 3.0, 6.0, 8.0, 5.0, 2.0, -1.0, -2.0, -2.0, -1.0, 0.5, -0.5, 0.0])
    # the flips at 1 and 2 are onset jitter (not preceded by forward motion); 8 is the peak
    assert overshoot_peak(v, 3) == 8
    assert overshoot_peak(np.array([0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 0.0]), 3) is None  # no reversal


def test_first_above_with_hold():
    s = np.array([0.0, 20.0, 5.0, 19.0, 21.0, 25.0, 30.0])
    assert first_above(s, 18.0) == 1
    assert first_above(s, 18.0, hold=3) == 3
    assert first_above(s, 40.0) == -1


def test_extract_noise_free_single_segment_motion():
    """One segment (the neck) turns 40 deg with a known profile: timing read straight off the curve."""
    rate, frames, onset = 60.0, 160, 30
    m = motion.GazeMotions(
        np.concatenate([rot.identity((3,)), rot.from_axis_angle(rot.UP, np.radians(40.0))[None], rot.IDENTITY[None]])[None],
        np.array([[1.5, 0.0, 0.0, 0.0, 0.1, 0.5, 0.1]]),
    )[0]
    t = (np.arange(frames) - onset) / (1.5 * rate)
    d = m.displacement(t)[:, :4]
    chain = d.copy()
    for j in range(1, 4):
        chain[:, j] = rot.multiply(chain[:, j - 1], d[:, j])
    settings = BuildSettings(start_hold_s=0.0)
    ex = extract(chain, (onset, frames - 1), rot.IDENTITY, rate, 30.0, 0.0, settings)
    np.testing.assert_allclose(np.degrees(rot.angle(rot.relative(ex.offsets[:4], m.offsets[:4]))), 0.0, atol=1e-6)
    assert ex.start_frames[:3].tolist() == [-1, -1, -1] and ex.detected_frames[:3].tolist() == [-1, -1, -1]
    # the neck's speed 40 * |s'(t)| crosses 18 deg/s (checked on a dense grid of the profile)...
    tt = np.linspace(0, 1, 100001)
    speed = 40.0 * np.gradient(m.profiles(tt)[:, 3], tt) / 1.5
    crossing = tt[np.argmax(speed > 18.0)] * 1.5 * rate + onset
    assert abs(onset + ex.detected_frames[3] - crossing) <= 1.0
    # ...4 frames after the model's t_j = 0.1 (9 frames into the crop), where the refinement puts the start
    t_j = 0.1 * 1.5 * rate
    assert crossing - onset - t_j > 3.5
    assert ex.start_frames[3] == pytest.approx(t_j, abs=0.25)
    assert ex.timing[4] == pytest.approx(ex.start_frames[3] / (frames - 1 - onset))
    # without the refinement the start is the paper's bare threshold crossing
    bare_settings = BuildSettings(start_hold_s=0.0, start_refine=False)
    bare = extract(chain, (onset, frames - 1), rot.IDENTITY, rate, 30.0, 0.0, bare_settings)
    np.testing.assert_array_equal(bare.start_frames, ex.detected_frames)
    assert bare.timing[4] == pytest.approx(ex.detected_frames[3] / (frames - 1 - onset))
    # differencing over +-k frames puts the flip a little late when the rise is faster than the settle
    assert 0.0 <= ex.peak_frame - 0.5 * 1.5 * rate <= 2.0
    assert ex.timing[motion.BETA] == pytest.approx(0.1, abs=1e-3)
    assert ex.timing[motion.DURATION] == pytest.approx((frames - 1 - onset) / rate)
    with pytest.raises(ExtractionError, match="crop"):
        extract(chain, (10, 10), rot.IDENTITY, rate, 0.0, 0.0)


def test_onset_fit_inverts_the_ease_in():
    """Known rises (t_j, t_peak, A): the fit finds t_j from the late threshold detections, also when
    the given peak is a few frames late (a plateau's noisy maximum), and keeps the start within
    [0, detection]."""
    frames = np.arange(80.0)
    t_j = np.array([12.3, 17.8, -2.0, 20.0])  # the third began before the crop, the fourth never crosses
    t_peak = np.array([40.0, 41.0, 40.0, 40.0])
    amplitude = np.array([30.0, 6.0, 20.0, 0.5])
    theta = amplitude * motion.ease((frames[:, None] - t_j) / (t_peak - t_j))
    theta[:, 2] -= theta[0, 2]  # angles are from the first cropped pose
    detected = np.array([16, 24, 3, -1])
    for late in (0.0, 2.5):
        starts = onset_fit(theta, detected, np.full(4, 40.0 + late), amplitude)
        np.testing.assert_allclose(starts[:2], t_j[:2], atol=0.1)
        assert 0.0 <= starts[2] <= 0.25 and starts[3] == -1
    # noise-like wiggles before the rise do not pull the start past the detection or below 0
    noisy = theta + np.random.default_rng(0).normal(0.0, 0.2, theta.shape)
    starts = onset_fit(noisy, detected, np.full(4, 41.0), amplitude)
    assert np.all((starts[:3] >= 0) & (starts[:3] <= detected[:3]))
    np.testing.assert_allclose(starts[0], t_j[0], atol=1.0)
    # nothing to fit: no detection, the peak not after the detection, no amplitude
    unchanged = [16.0, 24.0, 3.0, -1.0]
    np.testing.assert_array_equal(onset_fit(theta, detected, detected.astype(float), amplitude), unchanged)
    np.testing.assert_array_equal(onset_fit(theta, detected, np.full(4, 40.0), np.zeros(4)), unchanged)


def test_a_body_turning_away_from_the_target_is_flagged():
    """A +180 (left) target whose head turned 150 deg to the right: the sheet or the subject is wrong."""
    frames = 40
    turn = rot.from_axis_angle(rot.UP, np.radians(np.linspace(0.0, -150.0, frames)))
    chain = np.repeat(rot.identity((frames, 1)), 4, axis=1)
    chain[:, 3] = turn
    ex = extract(chain, (0, frames - 1), rot.IDENTITY, 60.0, 180.0, 0.0)
    assert any("the head turned -146 deg, the other way from the target yaw +180" in w for w in ex.warnings)
    ex = extract(chain, (0, frames - 1), rot.IDENTITY, 60.0, -180.0, 0.0)
    assert not any("other way" in w for w in ex.warnings)
