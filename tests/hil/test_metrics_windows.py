"""A metric whose window the run did not cover is null with the reason, not a number from a
few samples: `hil run impact --duration 1` ends 25 ms after the push, so its first peak (looked
for over 0.5 s after the push), settling time and ringing are not measured; a contact run that
ends before the reference reaches the block has no contact force to average."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.config import load_config
from hil.experiments import CONTACT, IMPACT
from hil.experiments.impact import FINAL_WINDOW_S, FIRST_PEAK_WINDOW_S, joint_impact_metrics
from hil.experiments.steady_state import SlowModeFitError, fit_slow_mode
from hil.output.records import UNMEASURED
from tests.support.rig import run_in_process

PERIOD_S = 0.005


def _ringing(end_s: float, push_s: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A link that rings after a push at `push_s`: 0.02 rad, 5 Hz, decaying in 0.2 s."""
    time = np.arange(0.0, end_s + PERIOD_S / 2, PERIOD_S)
    after = np.clip(time - push_s, 0.0, None)
    link = np.where(
        time >= push_s, 0.02 * np.sin(2 * np.pi * 5 * after) * np.exp(-after / 0.2), 0.0
    )
    return time, link, np.zeros_like(time)


def test_a_run_ending_just_after_the_push_measures_nothing_of_it_and_says_why() -> None:
    metrics = joint_impact_metrics(*_ringing(1.025), push_start_s=1.0)
    for key in ("first_peak_rad", "settling_time_s", "oscillations", "quasi_static_error_rad"):
        assert metrics[key] is None, key
        assert "after the push" in metrics[UNMEASURED][key], metrics[UNMEASURED]


def test_the_first_peak_needs_its_window_and_the_settling_its_final_value_after_it() -> None:
    end = 1.0 + FIRST_PEAK_WINDOW_S  # the peak's window, not the final value's
    metrics = joint_impact_metrics(*_ringing(end), push_start_s=1.0)
    # d/dt [sin(10 pi t) exp(-t / 0.2)] = 0 at tan(10 pi t) = 2 pi: t = 45.0 ms, where the
    # link is 0.02 sin(1.4130) exp(-0.225) = 0.01577 rad (on the 5 ms grid: 45 ms exactly)
    assert metrics["first_peak_rad"] == pytest.approx(0.01577, abs=2e-5)
    assert metrics["settling_time_s"] is None and "settling_time_s" in metrics[UNMEASURED]
    covered = joint_impact_metrics(*_ringing(end + FINAL_WINDOW_S), push_start_s=1.0)
    assert covered["settling_time_s"] is not None and covered["oscillations"] >= 2
    assert {"first_peak_rad", "settling_time_s", "oscillations"}.isdisjoint(
        covered.get(UNMEASURED, {})
    )


def test_a_dead_encoder_leaves_the_first_peak_unmeasured_not_nan() -> None:
    time, link, reference = _ringing(3.0)
    link[time >= 0.5] = np.nan
    metrics = joint_impact_metrics(time, link, reference, push_start_s=1.0)
    assert metrics["first_peak_rad"] is None
    assert "no valid link reading" in metrics[UNMEASURED]["first_peak_rad"]


def test_the_slow_mode_fit_of_a_run_that_ends_before_its_window_says_so_in_order() -> None:
    time, link, reference = _ringing(1.22)
    with pytest.raises(SlowModeFitError) as caught:
        fit_slow_mode(time, link, reference, 4.0)
    message = str(caught.value)
    assert "[4.0, 1.22]" not in message and "ends at 1.22 s" in message, message


def test_hil_runs_impact_of_one_second_reports_its_first_peak_as_not_measured(
    tmp_path: Path,
) -> None:
    result, _run = run_in_process(load_config(), IMPACT, "pid", tmp_path, duration_s=1.0)
    assert result.metrics["first_peak_rad"] is None
    assert "first_peak_rad" in result.metrics[UNMEASURED]


def test_a_contact_run_that_never_reaches_the_block_has_no_contact_force_to_average(
    tmp_path: Path,
) -> None:
    result, _run = run_in_process(load_config(), CONTACT, "pid", tmp_path, duration_s=1.5)
    assert result.metrics["contact_time_s"] is None
    assert result.metrics["mean_contact_force_n"] is None
    assert "block" in result.metrics[UNMEASURED]["mean_contact_force_n"]
