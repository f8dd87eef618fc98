"""The gaze displacement motion G = {P+, l, T, t_beta, beta} (Heck 5.1, 5.2.3) and its blending (5.2.2.2).

Every expected value here is computed in the test, independently of usdgaze's math: the piecewise
formula of section 5.2.3 is re-implemented as a plain scalar function (with the quintic ease the
module documents in place of the linear terms), and rotations are measured with
``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdgaze.gaze import motion
from usdgaze.gaze.motion import GazeMotions, blend, ease, normalized_time, profile, transition

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])

# Bounds of the quintic e(u) = 6u^5 - 15u^4 + 10u^3 on [0, 1], derived by hand:
# e'(u) = 30u^2(1-u)^2 peaks at u = 1/2 with 15/8; e''(u) = 60u(1-u)(1-2u) peaks at
# u = (3 -+ sqrt(3))/6 with |e''| = 10/sqrt(3).
EASE_D1 = 15.0 / 8.0
EASE_D2 = 10.0 / math.sqrt(3.0)


# -- independent references --------------------------------------------------------------------------


def quintic(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return 10 * u**3 - 15 * u**4 + 6 * u**5


def ref_profile(t: float, start: float, peak: float, beta: float) -> float:
    """Heck eq. of 5.2.3, scalar, with the documented edge cases (module docstring of usdgaze.gaze.motion)."""
    if t >= 1.0:
        return 1.0  # after the shift: P+
    if t < start:
        return 0.0  # identity before t_j
    if peak >= 1.0:
        beta = 0.0  # t_beta = 1: no time to settle, overshoot dropped
    if start >= peak:  # no overshoot phase: ease from identity at t_j to P+ at 1
        return quintic((t - start) / (1.0 - start)) if start < 1.0 else 0.0
    if t <= peak:
        return quintic((t - start) / (peak - start)) * (1.0 + beta)
    return 1.0 + (1.0 - quintic((t - peak) / (1.0 - peak))) * beta


def ref_scaled(q: np.ndarray, s: float) -> np.ndarray:
    """``q ** s`` by scipy: scale the rotation vector."""
    return Rotation.from_rotvec(Rotation.from_quat(q).as_rotvec() * s).as_quat()


def same_rotation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest component difference between quaternion arrays, modulo the q / -q sign."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    plus = np.abs(a - b).max(axis=-1)
    minus = np.abs(a + b).max(axis=-1)
    return float(np.minimum(plus, minus).max())


def random_quats(rng: np.random.Generator, n: int, max_deg: float = 120.0) -> np.ndarray:
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.radians(rng.uniform(1.0, max_deg, size=n))
    return Rotation.from_rotvec(axis * angle[:, None]).as_quat()


def one_motion(offsets: np.ndarray, duration=0.5, starts=(0.4, 0.3, 0.2, 0.1), peak=0.6, beta=0.1) -> GazeMotions:
    timing = np.array([duration, *starts, peak, beta], dtype=float)
    return GazeMotions(np.asarray(offsets, dtype=float), timing)


@pytest.fixture(scope="module")
def offsets() -> np.ndarray:
    """Five P+ offsets of 20-70 deg about distinct axes (kept below 180/(1+beta) so angles don't fold)."""
    rng = np.random.default_rng(11)
    axis = rng.normal(size=(5, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.radians([20.0, 35.0, 50.0, 60.0, 70.0])
    return Rotation.from_rotvec(axis * angle[:, None]).as_quat()


# -- the piecewise curve at its landmarks -----------------------------------------------------------


def test_identity_before_start_exactly(offsets):
    m = one_motion(offsets)
    starts = m.starts  # pelvis, lower, upper, neck, eyes(0)
    t = np.array([-0.5, -1e-9, 0.05, 0.099999, 0.15, 0.25, 0.35, 0.399999])
    q = m.displacement(t)  # (F, 5, 4)
    s = m.profiles(t)
    for j in range(5):
        before = t < starts[j]
        assert before.any()
        # exact: not approximately identity, identity
        assert np.all(s[before, j] == 0.0)
        assert np.all(q[before, j] == IDENTITY), (j, q[before, j])
    # just after its start every segment has left identity
    q_after = m.displacement(starts[:4] + 1e-3)
    for j in range(4):
        assert Rotation.from_quat(q_after[j, j]).magnitude() > 0.0


def test_overshoot_peak_and_goal(offsets):
    beta = 0.1
    m = one_motion(offsets, peak=0.6, beta=beta)
    goal_rotvec = Rotation.from_quat(offsets).as_rotvec()
    goal_angle = np.linalg.norm(goal_rotvec, axis=-1)
    axis = goal_rotvec / goal_angle[:, None]

    at_peak = Rotation.from_quat(m.displacement(np.array([0.6]))[0])
    peak_rotvec = at_peak.as_rotvec()
    peak_angle = np.linalg.norm(peak_rotvec, axis=-1)
    np.testing.assert_allclose(peak_angle, (1.0 + beta) * goal_angle, rtol=0, atol=1e-12)
    np.testing.assert_allclose(peak_rotvec / peak_angle[:, None], axis, rtol=0, atol=1e-12)
    # the peak is the largest angle of the whole curve
    t = np.linspace(-0.1, 1.3, 2801)
    angles = Rotation.from_quat(m.displacement(t).reshape(-1, 4)).magnitude().reshape(len(t), 5)
    assert np.all(angles <= peak_angle[None, :] + 1e-12)
    assert np.all(np.abs(t[np.argmax(angles, axis=0)] - 0.6) <= 0.5 * (t[1] - t[0]) + 1e-12)

    # exactly P+ at t = 1 and after
    after = np.array([1.0, 1.0 + 1e-12, 1.2, 7.0])
    assert np.all(m.profiles(after) == 1.0)
    q = m.displacement(after)
    for f in range(len(after)):
        assert same_rotation(q[f], offsets) < 1e-15
        np.testing.assert_allclose(Rotation.from_quat(q[f]).as_rotvec(), goal_rotvec, rtol=0, atol=1e-15)


# -- C1 continuity, measured -------------------------------------------------------------------------


def _second_derivative_bound(start: float, peak: float, beta: float) -> tuple[float, float]:
    """Sup of |s'| and |s''| of the eased profile, from the quintic's own bounds (no usdgaze)."""
    if peak >= 1.0:
        beta = 0.0
    if start >= peak:
        d = 1.0 - start
        return EASE_D1 / d, EASE_D2 / d**2
    rise, settle = peak - start, 1.0 - peak
    s1 = max(EASE_D1 * (1 + beta) / rise, EASE_D1 * beta / settle if settle > 0 else 0.0)
    s2 = max(EASE_D2 * (1 + beta) / rise**2, EASE_D2 * beta / settle**2 if settle > 0 else 0.0)
    return s1, s2


def _max_velocity_jump(values: np.ndarray, h: float) -> float:
    """max |v[i+1] - v[i]| of the forward-difference velocity v = diff(values)/h (over axis 0)."""
    v = np.diff(values, axis=0) / h
    return float(np.abs(np.diff(v, axis=0)).max())


def _sample_times(h: float, junctions: list[float], phase: float) -> np.ndarray:
    """A uniform grid over [-0.1, 1.1] plus five-point stencils centred at (and shifted off) each junction."""
    grid = np.arange(-0.1, 1.1 + h / 2, h) + phase * h
    return grid, [np.array([tj + phase * h + k * h for k in range(-2, 3)]) for tj in junctions]


@pytest.mark.parametrize(
    "starts, peak, beta",
    [
        ((0.4, 0.3, 0.2, 0.1), 0.6, 0.1),  # the normal cascade
        ((0.7, 0.65, 0.2, 0.1), 0.6, 0.15),  # pelvis and lower spine start after the peak
        ((0.4, 0.3, 0.2, 0.1), 0.6, 0.0),  # beta = 0
    ],
)
def test_c1_velocity_jumps_shrink_with_step(offsets, starts, peak, beta):
    """Finite-difference velocity of the angle and of the quaternion components has no jumps.

    For a C1 curve with bounded second derivative M, consecutive difference quotients differ by at
    most h*M; a kink (as in the paper's raw linear formula) would give a jump that does not shrink.
    """
    m = one_motion(offsets, starts=starts, peak=peak, beta=beta)
    all_starts = [*starts, 0.0]
    goal_angle = Rotation.from_quat(offsets).magnitude()
    for h in (4e-3, 2e-3, 1e-3, 5e-4):
        for phase in (0.0, 1.0 / 3.0):
            worst_angle, worst_quat = 0.0, 0.0
            for j in range(5):
                junctions = [all_starts[j], peak, 1.0]
                grid, stencils = _sample_times(h, junctions, phase)
                s1, s2 = _second_derivative_bound(all_starts[j], peak, beta)
                theta = goal_angle[j]
                # angle(t) = s(t) theta; quaternion components: sin(s theta/2) n and cos(s theta/2)
                m_angle = theta * s2
                m_quat = 0.5 * theta * s2 + (0.5 * theta * s1) ** 2
                for t in [grid, *stencils]:
                    q = m.displacement(t)[:, j]
                    ang = Rotation.from_quat(q).magnitude()
                    worst_angle = max(worst_angle, _max_velocity_jump(ang, h) / (h * m_angle))
                    worst_quat = max(worst_quat, _max_velocity_jump(q, h) / (h * m_quat))
            # within the O(h) bound (ratio <= 1, 1e-6 slack for round-off)
            assert worst_angle <= 1.0 + 1e-6, f"angle velocity jump {worst_angle:.4g} x bound at h={h}"
            assert worst_quat <= 1.0 + 1e-6, f"quaternion velocity jump {worst_quat:.4g} x bound at h={h}"

    # The absolute jump shrinks in proportion to h: halving h three times divides it by ~8.
    for phase in (0.0, 1.0 / 3.0):
        coarse = _abs_jump(m, 4e-3, phase, peak, all_starts)
        fine = _abs_jump(m, 5e-4, phase, peak, all_starts)
        assert fine < coarse / 4.0, (coarse, fine)


def _abs_jump(m: GazeMotions, h: float, phase: float, peak: float, starts: list[float]) -> float:
    worst = 0.0
    for j in range(5):
        grid, stencils = _sample_times(h, [starts[j], peak, 1.0], phase)
        for t in [grid, *stencils]:
            worst = max(worst, _max_velocity_jump(Rotation.from_quat(m.displacement(t)[:, j]).magnitude(), h))
    return worst


def test_c1_statistic_detects_a_kink(offsets):
    """The same statistic on the paper's raw linear formula does NOT shrink: the test above can fail."""

    def linear(t, start, peak, beta):
        if t >= 1.0:
            return 1.0
        if t < start:
            return 0.0
        if t <= peak:
            return (t - start) / (peak - start) * (1 + beta)
        return 1.0 + (1.0 - (t - peak) / (1.0 - peak)) * beta

    jumps = []
    for h in (4e-3, 1e-3, 2.5e-4):
        t = 0.6 + h * np.arange(-3, 4)  # stencil across the peak
        ang = np.array([linear(x, 0.1, 0.6, 0.1) for x in t]) * 1.0
        jumps.append(_max_velocity_jump(ang, h))
    # a jump of |s'(peak-) - s'(peak+)| = 1.1/0.5 + 0.1/0.4 = 2.45 at every step size
    np.testing.assert_allclose(jumps, 2.45, rtol=1e-6)


def test_c1_jump_is_first_order_in_h(offsets):
    """Each halving of h halves the measured velocity jump (first order): no hidden kink anywhere."""
    m = one_motion(offsets)
    starts = [0.4, 0.3, 0.2, 0.1, 0.0]
    absolute = {h: _abs_jump(m, h, 0.0, 0.6, starts) for h in (4e-3, 2e-3, 1e-3, 5e-4)}
    ratios = [absolute[a] / absolute[b] for a, b in ((4e-3, 2e-3), (2e-3, 1e-3), (1e-3, 5e-4))]
    # first-order in h: each halving roughly halves the jump
    assert all(1.6 < r < 2.4 for r in ratios), (absolute, ratios)


# -- documented edge cases ---------------------------------------------------------------------------


def test_start_at_or_after_peak_eases_monotonically_without_overshoot(offsets):
    t = np.linspace(-0.2, 1.2, 1401)
    for start in (0.6, 0.75, 0.95):
        s = profile(t, start, 0.6, 0.2)
        assert s.max() == 1.0  # no overshoot
        assert np.all(np.diff(s) >= 0.0)  # monotone
        assert np.all(s[t < start] == 0.0)
        assert np.all(s[t >= 1.0] == 1.0)
        # and it is an ease: zero slope at both ends (measured)
        h = 1e-6
        assert profile(start + h, start, 0.6, 0.2) / h < 1e-6
        assert (1.0 - profile(1.0 - h, start, 0.6, 0.2)) / h < 1e-6
        expected = np.array([ref_profile(x, start, 0.6, 0.2) for x in t])
        np.testing.assert_allclose(s, expected, rtol=0, atol=1e-14)


def test_beta_zero_reaches_goal_at_peak_and_holds(offsets):
    m = one_motion(offsets, peak=0.6, beta=0.0)
    t = np.linspace(0.6, 1.5, 91)
    assert np.all(m.profiles(t) == 1.0)
    q = m.displacement(t)
    for f in range(len(t)):
        assert same_rotation(q[f], offsets) < 1e-15
    s = m.profiles(np.linspace(0, 1, 1001))
    assert s.max() == 1.0


def test_peak_at_one_drops_overshoot(offsets):
    t = np.linspace(-0.2, 1.2, 1401)
    s = profile(t, 0.2, 1.0, 0.3)
    assert s.max() == 1.0
    assert np.all(np.diff(s) >= 0.0)
    assert np.all(s[t >= 1.0] == 1.0)
    np.testing.assert_allclose(s, [ref_profile(x, 0.2, 1.0, 0.3) for x in t], rtol=0, atol=1e-14)


def test_zero_duration_is_a_cut(offsets):
    m = one_motion(offsets, duration=0.0)
    elapsed = np.array([-1.0, -1e-9, 0.0, 1e-9, 0.5, 3.0])
    t = normalized_time(elapsed, m.duration)
    q = m.displacement(t)
    assert np.all(q[:2] == IDENTITY)
    for f in range(2, len(elapsed)):
        assert same_rotation(q[f], offsets) < 1e-15
    # with a duration, elapsed / l
    np.testing.assert_allclose(normalized_time(np.array([0.0, 0.25, 0.5]), 0.5), [0.0, 0.5, 1.0], rtol=0, atol=0)


def test_ease_endpoints_and_monotone():
    u = np.linspace(-0.5, 1.5, 2001)
    e = ease(u)
    assert np.all(e[u <= 0] == 0.0) and np.all(e[u >= 1] == 1.0)
    assert np.all(np.diff(e) >= 0.0)
    np.testing.assert_allclose(e, [quintic(x) for x in u], rtol=0, atol=1e-14)


# -- vectorized evaluation vs a per-element scipy reference ----------------------------------------------


def test_vectorized_frames_by_joints_matches_scipy_reference():
    rng = np.random.default_rng(3)
    n, frames = 7, 120
    offsets = random_quats(rng, n * 5, max_deg=150.0).reshape(n, 5, 4)
    offsets[rng.uniform(size=(n, 5)) < 0.3] *= -1.0  # either hemisphere in
    timing = np.column_stack(
        [
            rng.uniform(0.2, 1.5, n),
            rng.uniform(0.0, 0.5, (n, 4)),
            rng.uniform(0.4, 0.9, n),
            rng.uniform(0.0, 0.3, n),
        ]
    )
    timing[1, 1:3] = [0.95, 0.9]  # starts after the peak
    timing[2, 5] = 1.0  # peak at 1
    timing[3, 6] = 0.0  # beta 0
    m = GazeMotions(offsets, timing)
    t = rng.uniform(-0.2, 1.2, size=(n, frames))
    t[:, :6] = [0.0, 1.0, 0.5, 0.6, 0.9, 0.95]
    got = m.displacement(t)
    assert got.shape == (n, frames, 5, 4)

    worst = 0.0
    for i in range(n):
        starts = [*timing[i, 1:5], 0.0]
        for f in range(frames):
            for j in range(5):
                s = ref_profile(t[i, f], starts[j], timing[i, 5], timing[i, 6])
                worst = max(worst, same_rotation(got[i, f, j], ref_scaled(offsets[i, j], s)))
    assert worst < 1e-12, worst

    # a single motion broadcast over a time vector agrees with the batch row
    for i in (0, 2):
        np.testing.assert_allclose(m[i].displacement(t[i]), got[i], rtol=0, atol=1e-15)


# -- blending --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def three():
    rng = np.random.default_rng(5)
    offsets = random_quats(rng, 15, max_deg=100.0).reshape(3, 5, 4)
    offsets[0, 1] *= -1.0  # given on the w < 0 hemisphere
    offsets[2, 4] *= -1.0
    timing = np.column_stack(
        [rng.uniform(0.2, 1.0, 3), rng.uniform(0.0, 0.5, (3, 4)), rng.uniform(0.5, 0.9, 3), rng.uniform(0.0, 0.3, 3)]
    )
    return offsets, timing, GazeMotions(offsets, timing)


def test_blend_is_normalized_lerp(three):
    offsets, timing, motions = three
    w = np.array([0.2, 1.0, 0.3])
    got = blend(motions, w)
    # independent lerp: put every quaternion on the w >= 0 hemisphere, weighted sum, normalize
    aligned = np.where(offsets[..., 3:4] < 0, -offsets, offsets)
    wn = w / w.sum()
    expected = np.tensordot(wn, aligned, axes=1)
    expected /= np.linalg.norm(expected, axis=-1, keepdims=True)
    assert same_rotation(got.offsets, expected) < 1e-15
    np.testing.assert_allclose(got.timing, wn @ timing, rtol=0, atol=1e-15)
    # weights are normalized: scaling them changes nothing
    np.testing.assert_allclose(blend(motions, 7.5 * w).offsets, got.offsets, rtol=0, atol=1e-15)
    np.testing.assert_allclose(blend(motions, 7.5 * w).timing, got.timing, rtol=0, atol=1e-15)
    # without hemisphere alignment the lerp would be a different (wrong) rotation: alignment matters
    naive = np.tensordot(wn, offsets, axes=1)
    naive /= np.linalg.norm(naive, axis=-1, keepdims=True)
    assert same_rotation(naive[1], expected[1]) > 1e-3


def test_blend_batched_weights(three):
    _, _, motions = three
    w = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.5], [1.0, 1.0, 1.0]])
    got = blend(motions, w)
    assert got.offsets.shape == (4, 5, 4) and got.timing.shape == (4, 7)
    for i in range(3):  # a one-hot blend is the example itself
        np.testing.assert_allclose(got.offsets[i], motions.offsets[i], rtol=0, atol=1e-15)
        np.testing.assert_allclose(got.timing[i], motions.timing[i], rtol=0, atol=1e-15)
    np.testing.assert_allclose(got.timing[3], motions.timing.mean(axis=0), rtol=0, atol=1e-15)


def test_blend_rejects_bad_weights(three):
    _, _, motions = three
    with pytest.raises(ValueError):
        blend(motions, np.array([0.5, -0.1, 0.6]))
    with pytest.raises(ValueError):
        blend(motions, np.zeros(3))


def test_blending_identical_motions_returns_them(three):
    offsets, timing, _ = three
    same = GazeMotions(np.repeat(offsets[1:2], 4, axis=0), np.repeat(timing[1:2], 4, axis=0))
    rng = np.random.default_rng(0)
    for _ in range(5):
        got = blend(same, rng.uniform(0.01, 1.0, 4))
        assert same_rotation(got.offsets, offsets[1]) < 1e-15
        np.testing.assert_allclose(got.timing, timing[1], rtol=0, atol=1e-15)


# -- transition --------------------------------------------------------------------------------------


def test_transition_endpoints_and_overshoot_along_geodesic():
    rng = np.random.default_rng(9)
    start = random_quats(rng, 5, 90.0)
    target = random_quats(rng, 5, 90.0)
    assert same_rotation(transition(start, target, np.zeros(5)), start) < 1e-14
    assert same_rotation(transition(start, target, np.ones(5)), target) < 1e-14

    beta = 0.15
    over = transition(start, target, np.full(5, 1.0 + beta))
    rs, rt, ro = Rotation.from_quat(start), Rotation.from_quat(target), Rotation.from_quat(over)
    span = (rs.inv() * rt).magnitude()
    np.testing.assert_allclose((rs.inv() * ro).magnitude(), (1 + beta) * span, rtol=0, atol=1e-12)
    np.testing.assert_allclose((rt.inv() * ro).magnitude(), beta * span, rtol=0, atol=1e-12)
    # same axis as the start -> target path: on the geodesic, beyond the target
    axis_path = (rs.inv() * rt).as_rotvec() / span[:, None]
    axis_over = (rs.inv() * ro).as_rotvec() / ((1 + beta) * span)[:, None]
    np.testing.assert_allclose(axis_over, axis_path, rtol=0, atol=1e-12)
    # identity start: the paper's q^s
    np.testing.assert_allclose(
        Rotation.from_quat(transition(np.tile(IDENTITY, (5, 1)), target, np.full(5, 1.0 + beta))).as_rotvec(),
        rt.as_rotvec() * (1 + beta),
        rtol=0,
        atol=1e-12,
    )


# -- aim_eyes / achieved_gaze (the measuring stick of the map tests) ------------------------------------


def test_achieved_gaze_measures_composite_direction():
    rng = np.random.default_rng(21)
    body = random_quats(rng, 40, 40.0).reshape(10, 4, 4)
    yaw = rng.uniform(-170, 170, 10)
    pitch = rng.uniform(-60, 60, 10)
    eyes = motion.aim_eyes(body, yaw, pitch)
    offsets = np.concatenate([body, eyes[:, None]], axis=1)
    # independent: compose with scipy (parent first), rotate +Z, read azimuth/elevation
    composite = Rotation.from_quat(offsets[:, 0])
    for j in range(1, 5):
        composite = composite * Rotation.from_quat(offsets[:, j])
    d = composite.apply([0.0, 0.0, 1.0])
    np.testing.assert_allclose(np.degrees(np.arctan2(d[:, 0], d[:, 2])), yaw, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(np.arcsin(d[:, 1])), pitch, rtol=0, atol=1e-9)
    np.testing.assert_allclose(motion.achieved_gaze(offsets, yaw), np.column_stack([yaw, pitch]), rtol=0, atol=1e-9)
    # Listing's law: the eye rotation has no component about the head's forward axis
    eye_rotvec = Rotation.from_quat(eyes).as_rotvec()
    assert np.abs(eye_rotvec[:, 2]).max() < 1e-12


@pytest.mark.parametrize("n", [2, 3, 4])
def test_dot_and_length_match_numpy_bit_for_bit(n):
    """rot.dot / rot.length replace np.sum(a * b, axis=-1) and np.linalg.norm(v, axis=-1) on the pass's
    hot path: the same bits, strided views and broadcasting included."""
    from usdgaze.core import rotations as rot

    rng = np.random.default_rng(n)
    for shape in [(n,), (7, n), (1247, n), (2, 300, n), (0, n), (31, 5, n)]:
        a = rng.normal(size=shape) * rng.uniform(1e-3, 1e3, size=shape)
        b = rng.normal(size=shape)
        for x, y in [(a, b), (a[::2], b[::2]), (a, b[..., :1] * np.ones(n))]:
            assert np.array_equal(rot.dot(x, y), np.sum(x * y, axis=-1))
            assert np.array_equal(rot.dot(x, y, keepdims=True), np.sum(x * y, axis=-1, keepdims=True))
            assert np.array_equal(rot.length(x), np.linalg.norm(x, axis=-1))
            assert np.array_equal(rot.length(x, keepdims=True), np.linalg.norm(x, axis=-1, keepdims=True))
    v = rng.normal(size=(100, n))
    assert np.array_equal(rot.dot(v, v[0]), np.sum(v * v[0], axis=-1))  # one vector against many
