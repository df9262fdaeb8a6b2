"""The emulated H54 firmware's overload rule, directly (sim_backend/servo.py; `H54Firmware`).

The rule (documented there): a timer counts up while |current| >= overload_current_fraction x
the current cap and counts DOWN at the same rate below it (never below 0); when it reaches
overload_trip_time_s the firmware raises the Overload bit (0x20), which with the default
Shutdown mask turns torque off until a REBOOT. The expected trip instants below are worked out
by hand from that rule, for a 1 ms step.
"""

from __future__ import annotations

import pytest

from sim_backend.dynamixel.device import H54Device
from sim_backend.firmware import H54Firmware
from sim_backend.servo import AMPERE_PER_CURRENT_UNIT, OVERLOAD_BIT, H54ServoParams

DT_S = 0.001
PARAMS = H54ServoParams()  # 0.9 of the cap for 1.5 s
CAP_A = 620 * AMPERE_PER_CURRENT_UNIT  # Torque Limit (30) default 620 x 16.11328 mA = 9.99 A
ABOVE_A = 0.95 * CAP_A  # over the 0.9 threshold
BELOW_A = 0.80 * CAP_A  # under it


def firmware() -> tuple[H54Device, H54Firmware]:
    device = H54Device(1)
    device.set_item("Torque Enable", 1)
    return device, H54Firmware(device, PARAMS)


def step(fw: H54Firmware, current_a: float) -> None:
    fw.report(current_a * PARAMS.torque_constant_nm_per_a, 0.0, 0.0, DT_S)


def run(fw: H54Firmware, device: H54Device, currents: list[float]) -> int | None:
    """Index of the step at which the Overload bit appeared, or None."""
    for index, current_a in enumerate(currents):
        step(fw, current_a)
        if device.hardware_error_status & OVERLOAD_BIT:
            return index
    return None


def test_the_threshold_and_cap_are_what_the_rule_says() -> None:
    _, fw = firmware()
    assert fw.current_cap_a() == pytest.approx(9.99, abs=0.01)
    assert PARAMS.overload_current_fraction == 0.9 and PARAMS.overload_trip_time_s == 1.5


def test_a_steady_overload_trips_after_the_trip_time_and_shuts_down() -> None:
    device, fw = firmware()
    tripped = run(fw, device, [ABOVE_A] * 2000)
    # the timer reaches 1.5 s on the 1500th step (index 1499), or one later by rounding
    assert tripped in (1499, 1500)
    assert device.hardware_error_status == OVERLOAD_BIT
    assert not device.torque_enabled and device.in_shutdown  # Shutdown 58 includes Overload


def test_below_the_threshold_the_timer_counts_down_at_the_same_rate() -> None:
    device, fw = firmware()
    assert run(fw, device, [ABOVE_A] * 1000 + [BELOW_A] * 400) is None
    assert fw.overload_timer_s == pytest.approx(0.6, abs=2 * DT_S)  # 1.0 up, 0.4 down
    # 0.9 s more above the threshold completes the 1.5 s: not 1.5 s (a reset), not 0.5 s
    # (no count-down), not anything else (another rate)
    tripped = run(fw, device, [ABOVE_A] * 2000)
    assert tripped is not None and abs(tripped + 1 - 900) <= 2


def test_the_timer_never_goes_below_zero() -> None:
    device, fw = firmware()
    run(fw, device, [BELOW_A] * 500)  # a long time below: the timer stays at 0
    assert fw.overload_timer_s == 0.0
    tripped = run(fw, device, [ABOVE_A] * 2000)
    assert tripped in (1499, 1500)  # no credit was banked below the threshold


def test_a_current_dithering_around_the_threshold_trips_at_the_net_time() -> None:
    """3 steps above, 1 below, repeated: +2 ms per 4 ms cycle. After k cycles the timer is
    2k ms and peaks at 2k + 3 ms within the next; 2k + 3 >= 1500 first for k = 749, i.e. at
    step 4 x 749 + 3 = 2999 (index 2998), 3.0 s after the start. A timer that reset when the
    current dipped would never trip; one that did not count down would trip at 2.0 s."""
    device, fw = firmware()
    pattern = [ABOVE_A, ABOVE_A, ABOVE_A, BELOW_A]
    tripped = run(fw, device, pattern * 1000)
    assert tripped is not None, "the dithering current never tripped the overload"
    assert abs(tripped - 2998) <= 4  # one cycle of rounding either way


def test_torque_off_resets_the_timer() -> None:
    device, fw = firmware()
    run(fw, device, [ABOVE_A] * 1000)
    device.set_item("Torque Enable", 0)
    step(fw, ABOVE_A)
    assert fw.overload_timer_s == 0.0
