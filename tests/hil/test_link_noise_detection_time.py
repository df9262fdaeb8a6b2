"""How long the link-noise watch takes to find the emulator's noisy encoder (50 counts rms):
a random time, because the noise is random. The analysis in docs/safety.md ("Noise vs.
motion": the rule on Gaussian noise, 5 million trials) gives its distribution - median 15
ticks, 3.3 % of faults past one window (20 ticks), 4e-7 past three (60) - and the soak's bound
for this fault is three windows (hil/bench/soak.py). Here the product's own watch, fed the same
noise (seeded), must show that distribution: a bound of one window would be wrong for about
one fault in thirty, which is what made the soak's verdict depend on its seed."""

from __future__ import annotations

import math

import numpy as np

from drivers.joint_bus import JointDevices, JointSample
from hil.bench.soak import KINDS, NOISE_DETECTION_WINDOWS
from hil.config import load_config
from hil.safety import Supervisor

CONFIG = load_config()
PERIOD_S = CONFIG.loop.period_s
COUNT_RAD = 2 * math.pi / 983_040
FAULT_COUNTS_RMS = 50.0  # sim_backend's noisy_encoder
NOMINAL_COUNTS_RMS = 0.5  # the read head's own flicker (sim_backend/canbus/encoder_node.py)
TRIALS = 3000


def _sample(link_angle_rad: float, k: int) -> JointSample:
    """A joint at rest whose link encoder reads `link_angle_rad` (the motor's own encoder, read
    by the actuator, does not see the link encoder's noise)."""
    one = np.ones(1)
    return JointSample(
        timestamp_s=k * PERIOD_S,
        motor_angle_rad=np.array([0.0]),
        link_angle_rad=np.array([link_angle_rad]),
        motor_velocity_rad_s=0 * one,
        motor_current_a=0 * one,
        actuator_fault=np.zeros(1, dtype=np.uint8),
        fault_code=np.zeros(1, dtype=np.int64),
        torque_enabled=one > 0,
        motor_valid=one > 0,
        link_valid=one > 0,
        link_age_s=0 * one,
        bus_errors=[],
    )


def _ticks_to_detect(rng: np.random.Generator, limit: int = 200) -> int:
    """Ticks from the first noisy reading (counted 1) to the link_noisy trip, inclusive."""
    safety = CONFIG.safety
    supervisor = Supervisor(
        safety, CONFIG.joint_names, (JointDevices("actuator 1", "link encoder node 5"),),
        np.array([-1.0]), np.array([1.0]), PERIOD_S, np.array([2000.0]),
    )  # fmt: skip
    supervisor.set_current_limits(np.array([10.0]))
    supervisor.torque_enabled(np.array([0.0]))
    clean = 3  # readings before the fault: the watch has its history
    for k in range(clean + limit):
        counts = rng.normal(0.0, NOMINAL_COUNTS_RMS)
        if k >= clean:
            counts += rng.normal(0.0, FAULT_COUNTS_RMS)
        supervisor.observe(k, k * PERIOD_S, _sample(math.floor(counts + 0.5) * COUNT_RAD, k))
        if supervisor.events:
            assert supervisor.events[0].cause == "link_noisy"
            return k - clean + 1
    return limit + 1


def test_the_noise_watch_finds_a_noisy_encoder_in_the_time_the_analysis_gives() -> None:
    rng = np.random.default_rng(2026)
    ticks = np.array([_ticks_to_detect(rng) for _ in range(TRIALS)])
    window = CONFIG.safety.link_noise_window_ticks
    assert np.median(ticks) == 15
    beyond_one_window = float(np.mean(ticks > window))
    assert 0.015 < beyond_one_window < 0.06, beyond_one_window  # the analysis: 3.3 %
    assert ticks.max() <= NOISE_DETECTION_WINDOWS * window


def test_the_soaks_bound_for_a_noisy_encoder_is_three_windows() -> None:
    (noisy,) = [kind for kind in KINDS if kind.name == "noisy_encoder"]
    assert NOISE_DETECTION_WINDOWS == 3
    assert noisy.bound_ticks(CONFIG) == 3 * CONFIG.safety.link_noise_window_ticks
