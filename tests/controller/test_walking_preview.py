"""ZMP reference and Kajita's preview control on the ideal cart-table.

The gains are checked against independent computations (a different formulation of the same
optimal control problem, a scipy-free Riccati iteration, the closed loop's poles), the closed loop
against the exact bounded solution of the cart-table's ZMP equation for a step, and the
generator's own ZMP error in the paper's slow and dynamic walking is measured.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from controller.walking import (
    CartTableParams,
    FootstepPlanError,
    PreviewWeights,
    Side,
    StepTiming,
    WalkingParams,
    WalkingPattern,
    WalkTimeline,
    ZmpReferenceParams,
    ZmpTransition,
    design_preview_controller,
    straight_walk_plan,
    track_zmp_reference,
    zmp_reference,
)
from controller.walking.preview_control import preview_feedforward, servo_system

DT = 0.005
MODEL = CartTableParams(com_height_m=0.8, gravity_mps2=9.81, dt_s=DT)
HORIZON_S = 1.6
N_PREVIEW = 320
W = 0.127794
SLOW = StepTiming(0.8, 3.2, 1.6, 1.0)  # Kim et al., ICRA 2018, Sec. IV-C
DYNAMIC = StepTiming(0.8, 0.3, 1.6, 1.0)


@pytest.fixture(scope="module")
def gains():
    return design_preview_controller(MODEL, PreviewWeights(), HORIZON_S)


# --- ZMP reference ----------------------------------------------------------------------------


def test_zmp_reference_is_piecewise_per_support():
    plan = straight_walk_plan(3, 0.2, DYNAMIC)  # right swings first: stance left
    timeline = WalkTimeline(plan, DT)
    ref = zmp_reference(timeline, ZmpReferenceParams())
    assert np.allclose(ref[:320], [0.0, 0.0])  # initial rest: between the feet
    ss = [s for s in timeline.segments if s.kind.value == "single_support"]
    stance = [(0.0, W), (0.2, -W), (0.4, W)]  # left at 0, right at 0.2, left at 0.4
    for seg, point in zip(ss, stance, strict=True):
        assert np.allclose(ref[seg.start_tick : seg.end_tick], point)
    assert np.allclose(ref[-200:], [0.4, 0.0])  # final rest: between the closed feet
    # Linear transitions: each tick moves by (distance / DS ticks) at most.
    steps = np.linalg.norm(np.diff(ref, axis=0), axis=1)
    assert steps.max() == pytest.approx(math.hypot(0.2, 2 * W) / 60, rel=1e-9)


def test_zmp_reference_inward_and_forward_offsets():
    plan = straight_walk_plan(2, 0.2, DYNAMIC)
    timeline = WalkTimeline(plan, DT)
    ref = zmp_reference(timeline, ZmpReferenceParams(forward_offset_m=0.01, inward_offset_m=0.02))
    first_ss = next(s for s in timeline.segments if s.kind.value == "single_support")
    # Stance on the left foot: inward is -y.
    assert np.allclose(ref[first_ss.start_tick], [0.01, W - 0.02])


def test_smooth_transition_is_the_cubic_with_zero_slope_at_both_ends():
    plan = straight_walk_plan(2, 0.2, DYNAMIC)
    timeline = WalkTimeline(plan, DT)
    ref = zmp_reference(timeline, ZmpReferenceParams(transition=ZmpTransition.SMOOTH))
    ds = timeline.segments[1]  # from between the feet (0, 0) onto the left foot (0, W)
    s = np.arange(ds.n_ticks) / ds.n_ticks
    expected_y = W * (3 * s**2 - 2 * s**3)
    assert np.allclose(ref[ds.start_tick : ds.end_tick, 1], expected_y, rtol=0, atol=1e-15)
    assert ref[ds.end_tick, 1] == W


# --- the gains against independent computations -----------------------------------------------


def test_first_preview_gain_is_minus_the_integral_gain(gains):
    assert gains.preview_gains[0] == -gains.integral_gain
    assert gains.horizon_ticks == N_PREVIEW


def test_closed_loop_poles_inside_unit_circle(gains):
    radius = np.abs(np.linalg.eigvals(gains.closed_loop_matrix)).max()
    assert radius < 0.99


def test_riccati_solution_matches_a_plain_riccati_iteration(gains):
    """P by iterating the Riccati difference equation from P = Q to its fixed point (no scipy)."""
    at, bt, _, _ = servo_system(MODEL)
    q = np.diag([1.0, 0.0, 0.0, 0.0])
    r = 1e-6
    p = q.copy()
    for _ in range(20000):
        k = (bt.T @ p @ at) / (r + (bt.T @ p @ bt).item())
        p_next = q + at.T @ p @ at - at.T @ p @ bt @ k
        if np.abs(p_next - p).max() < 1e-13 * np.abs(p_next).max():
            break
        p = p_next
    assert np.abs(p_next - gains.riccati_solution).max() < 1e-8 * np.abs(p_next).max()


def test_preview_gains_equal_the_optimal_gains_of_the_reference_augmented_system(gains):
    """A different formulation of the same problem: append the future reference increments
    dref(k+1..k+NL) to the servo state as a shift register and solve one (4 + NL)-state DARE.
    Its optimal feedback on dref(k+j) must be Kajita's Gp(j), on [e, dx] Kajita's [Gi, Gx]."""
    at, bt, _, _ = servo_system(MODEL)
    n = 4 + N_PREVIEW
    a = np.zeros((n, n))
    a[:4, :4] = at
    a[0, 4] = -1.0  # e(k+1) = ... - dref(k+1)
    a[4 + np.arange(N_PREVIEW - 1), 5 + np.arange(N_PREVIEW - 1)] = 1.0  # shift
    b = np.zeros((n, 1))
    b[:4] = bt
    q = np.zeros((n, n))
    q[0, 0] = 1.0
    r = np.array([[1e-6]])
    p = scipy.linalg.solve_discrete_are(a, b, q, r)
    k = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a).ravel()
    assert k[0] == pytest.approx(gains.integral_gain, rel=1e-8)
    assert np.allclose(k[1:4], gains.state_gain, rtol=1e-8)
    scale = np.abs(gains.preview_gains).max()
    assert np.abs(k[4:] - gains.preview_gains).max() < 1e-8 * scale


def test_preview_horizon_covers_the_decay_of_the_gains(gains):
    """At rest, u = 0 needs Gx[0] + sum Gp = 0 for the infinite preview; what the 1.6 s horizon
    truncates is under 1 % of Gx[0], and the last gain is under 1 % of the largest."""
    residual = gains.state_gain[0] + gains.preview_gains.sum()
    assert abs(residual) < 0.01 * gains.state_gain[0]
    assert abs(gains.preview_gains[-1]) < 0.01 * np.abs(gains.preview_gains).max()


def test_preview_feedforward_sums_the_right_window(gains):
    rng = np.random.default_rng(1)
    ref = rng.normal(size=(500, 2))
    ff = preview_feedforward(gains, ref)
    padded = np.vstack((ref, np.repeat(ref[-1:], N_PREVIEW, axis=0)))
    for k in (0, 17, 250, 499):
        expected = gains.preview_gains @ padded[k + 1 : k + 1 + N_PREVIEW]
        assert np.allclose(ff[k], expected, rtol=1e-12, atol=1e-9)


# --- the closed loop against analysis ----------------------------------------------------------


def test_step_response_matches_the_bounded_cart_table_solution(gains):
    """ZMP reference step of h at ts. The bounded solution of p - Tc^2 p'' = r (Tc^2 = zc/g) is
    p = (h/2) e^((t-ts)/Tc) before the step and h - (h/2) e^(-(t-ts)/Tc) after it: the ideal
    preview controller puts the CoM half-way at the step. Integral action: zero final error."""
    h, start = 0.1, 640
    n = start + 1000
    ref = np.zeros((n, 1))
    ref[start:] = h
    cart = track_zmp_reference(gains, ref)
    t = (np.arange(n) - start) * DT
    tc = math.sqrt(0.8 / 9.81)
    ideal = np.where(t < 0, 0.5 * h * np.exp(t / tc), h - 0.5 * h * np.exp(-t / tc))
    assert np.abs(cart.position_m[:, 0] - ideal).max() < 1e-3  # measured 0.43 mm
    assert cart.position_m[start, 0] == pytest.approx(h / 2, abs=1e-3)
    assert abs(cart.zmp_m[-1, 0] - h) < 1e-8
    assert abs(cart.position_m[-1, 0] - h) < 1e-5
    assert abs(cart.velocity_mps[-1, 0]) < 1e-4


def test_trajectory_is_the_cart_table_driven_by_the_jerk(gains):
    plan = straight_walk_plan(2, 0.2, DYNAMIC)
    ref = zmp_reference(WalkTimeline(plan, DT), ZmpReferenceParams())
    cart = track_zmp_reference(gains, ref)
    zc_over_g = 0.8 / 9.81
    assert np.allclose(cart.zmp_m, cart.position_m - zc_over_g * cart.acceleration_mps2)
    p, v, a, j = cart.position_m, cart.velocity_mps, cart.acceleration_mps2, cart.jerk_mps3
    assert np.allclose(p[1:], p[:-1] + v[:-1] * DT + a[:-1] * DT**2 / 2 + j[:-1] * DT**3 / 6)
    assert np.allclose(a[1:], a[:-1] + j[:-1] * DT)


def test_starts_at_rest_over_any_initial_reference(gains):
    """Rest away from the origin: the integral's initial value makes it an equilibrium."""
    ref = np.tile([0.7, -0.3], (400, 1))
    cart = track_zmp_reference(gains, ref)
    assert np.abs(cart.position_m - [0.7, -0.3]).max() < 1e-12
    assert np.abs(cart.jerk_mps3).max() < 1e-9


# --- the generator's own ZMP error in the paper's walks ----------------------------------------


def _rms_and_max_mm(pattern: WalkingPattern) -> tuple[np.ndarray, np.ndarray]:
    error = pattern.generator_zmp_error_m()
    return np.sqrt(np.mean(error**2, axis=0)) * 1e3, np.abs(error).max(axis=0) * 1e3


def test_generator_zmp_error_slow_walking_is_sub_millimetre():
    pattern = WalkingPattern(straight_walk_plan(6, 0.2, SLOW))
    rms, peak = _rms_and_max_mm(pattern)
    # Measured (smooth transitions): RMS 0.11 (x) / 0.14 (y) mm, max 0.20 / 0.25 mm.
    assert np.all(rms < 0.3) and np.all(peak < 1.0)


def test_generator_zmp_error_dynamic_walking_is_a_few_millimetres_at_most():
    pattern = WalkingPattern(straight_walk_plan(10, 0.2, DYNAMIC))
    rms, peak = _rms_and_max_mm(pattern)
    # Measured (smooth transitions): RMS 0.42 (x) / 0.53 (y) mm, max 1.0 / 1.3 mm.
    assert np.all(rms < 1.0) and np.all(peak < 3.0)


def test_linear_transitions_track_within_the_same_bounds():
    params = WalkingParams(zmp=ZmpReferenceParams(transition=ZmpTransition.LINEAR))
    rms, peak = _rms_and_max_mm(WalkingPattern(straight_walk_plan(10, 0.2, DYNAMIC), params))
    # Measured: RMS 0.42 / 0.53 mm, max 1.9 / 2.8 mm (the kinks cost the peaks).
    assert np.all(rms < 1.0) and np.all(peak < 3.0)


def test_a_rest_shorter_than_the_preview_is_refused_and_would_cost_centimetres(gains):
    short = StepTiming(0.8, 0.3, 1.0, 1.0)
    plan = straight_walk_plan(6, 0.2, short)
    with pytest.raises(FootstepPlanError, match="preview horizon"):
        WalkingPattern(plan)
    # What the check prevents: the preview sees the first weight shift before tick 0.
    ref = zmp_reference(WalkTimeline(plan, DT), ZmpReferenceParams())
    error = track_zmp_reference(gains, ref).zmp_m - ref
    assert np.abs(error[:, 1]).max() > 0.01  # measured 66 mm (lateral)


def test_mirror_plan_mirrors_the_com():
    right_first = WalkingPattern(straight_walk_plan(4, 0.2, DYNAMIC))
    left_first = WalkingPattern(straight_walk_plan(4, 0.2, DYNAMIC, first_swing=Side.LEFT))
    assert np.allclose(
        left_first.com_position_m[:, 1], -right_first.com_position_m[:, 1], atol=1e-12
    )
    assert np.allclose(left_first.com_position_m[:, 0], right_first.com_position_m[:, 0])


@pytest.mark.parametrize("inward", [0.02, 0.04])  # the lab's 2018 and master shifts
def test_the_inward_shift_moves_each_stance_point_by_exactly_its_amount(inward):
    """In every single support the reference moves towards the other foot by the shift, not a
    tick's worth more; the rests (between the feet) do not move."""
    plan = straight_walk_plan(4, 0.2, DYNAMIC)
    timeline = WalkTimeline(plan, DT)
    plain = zmp_reference(timeline, ZmpReferenceParams())
    shifted = zmp_reference(timeline, ZmpReferenceParams(inward_offset_m=inward))
    for seg in timeline.segments:
        rows = slice(seg.start_tick, seg.end_tick)
        if seg.kind.value == "single_support":
            towards_other = -seg.landing_side.other.lateral_sign  # stance foot -> other foot
            assert np.array_equal(shifted[rows, 0], plain[rows, 0])
            moved = shifted[rows, 1] - plain[rows, 1]
            assert np.allclose(moved, towards_other * inward, atol=1e-15)
        elif seg.kind.value != "double_support":
            assert np.array_equal(shifted[rows], plain[rows])


def test_the_labs_split_moves_to_the_middle_holds_and_moves_on():
    """The lab's step split (walking_controller.cpp `onestepZmp`): in the double support
    between a left and a right stance, the first 0.1 s move linearly from the left point to
    the middle of the feet, reaching it on their last tick, the middle holds, the last 0.1 s
    move to the right point; the walk's first double support holds the middle and then moves,
    its last moves and then holds."""
    plan = straight_walk_plan(3, 0.2, DYNAMIC)
    timeline = WalkTimeline(plan, DT)
    params = ZmpReferenceParams(transition=ZmpTransition.LAB_SPLIT, inward_offset_m=0.02)
    ref = zmp_reference(timeline, params)
    moves = 20  # 0.1 s
    ramp = (np.arange(moves) + 1.0) / moves
    left, right = np.array([0.0, W - 0.02]), np.array([0.2, -(W - 0.02)])
    segments = timeline.segments
    between = segments[3]  # after the first swing (the right foot lands at x = 0.2)
    assert between.kind.value == "double_support" and between.n_ticks == 60
    rows = ref[between.start_tick : between.end_tick]
    middle = np.array([0.1, 0.0])  # the sole points' middle (the shifts cancel)
    assert np.allclose(rows[:moves], left + ramp[:, None] * (middle - left), atol=1e-15)
    assert np.allclose(rows[moves:-moves], middle, atol=1e-15)
    assert np.allclose(rows[-moves:], middle + ramp[:, None] * (right - middle), atol=1e-15)
    first = ref[segments[1].start_tick : segments[1].end_tick]
    assert np.allclose(first[:-moves], [0.0, 0.0]) and np.allclose(first[-1], left)
    last = ref[segments[-2].start_tick : segments[-2].end_tick]
    assert np.allclose(last[moves - 1 :], [0.4, 0.0], atol=1e-15)
    short = StepTiming(0.8, 0.15, 1.6, 1.0)  # no room for two 0.1 s moves
    with pytest.raises(FootstepPlanError, match="two moves"):
        zmp_reference(WalkTimeline(straight_walk_plan(2, 0.2, short), DT), params)
