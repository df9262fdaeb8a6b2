"""The figures each experiment reports, computed from a run's log columns (SI units).

contact (Fig. 5):
    contact_time_s              first tick the force sensor reads more than CONTACT_THRESHOLD_N
    peak_contact_force_n        largest force reading
    mean_contact_force_n        mean force while in contact and the actuator still has torque
    overload_tripped            the actuator reported its Overload bit (Hardware Error Status 0x20)
    trip_time_after_contact_s   first Overload report minus contact_time_s (None without a trip)
impact (Fig. 6):
    first_peak_rad              largest |link angle - link angle just before the push| within
                                FIRST_PEAK_WINDOW_S after the push starts
    settling_time_s             from the push until the link stays within
                                max(SETTLING_FRACTION x first peak, SETTLING_FLOOR_RAD) of its
                                final value (the mean of the last FINAL_WINDOW_S)
    steady_state_error_rad      |final value - reference| at the end of the run
    oscillations                sign changes of (link - final) above the settling band after
                                the push: a count of half-periods of ringing
"""

from __future__ import annotations

from typing import Any

import numpy as np

CONTACT_THRESHOLD_N = 1.0
OVERLOAD_BIT = 0x20
FIRST_PEAK_WINDOW_S = 0.5
SETTLING_FRACTION = 0.1
SETTLING_FLOOR_RAD = 0.5e-3
FINAL_WINDOW_S = 0.5


def _first_time(times: np.ndarray, mask: np.ndarray) -> float | None:
    index = np.flatnonzero(mask)
    return float(times[index[0]]) if index.size else None


def contact_metrics(columns: dict[str, np.ndarray], joint: str = "") -> dict[str, Any]:
    suffix = f"[{joint}]" if joint else ""
    time = columns["time_s"]
    force = columns["contact_force_n"]
    hw_error = columns[f"hardware_error{suffix}"].astype(int)
    torque_on = columns[f"torque_enabled{suffix}"] > 0.5
    touching = force > CONTACT_THRESHOLD_N
    contact_time = _first_time(time, touching)
    trip_time = _first_time(time, (hw_error & OVERLOAD_BIT) != 0)
    in_contact = touching & torque_on
    return {
        "contact_time_s": contact_time,
        "peak_contact_force_n": float(np.nanmax(force)) if force.size else 0.0,
        "mean_contact_force_n": float(np.nanmean(force[in_contact])) if in_contact.any() else 0.0,
        "overload_tripped": trip_time is not None,
        "trip_time_after_contact_s": (
            trip_time - contact_time if trip_time is not None and contact_time is not None else None
        ),
    }


def impact_metrics(
    columns: dict[str, np.ndarray], push_start_s: float, joint: str = ""
) -> dict[str, Any]:
    suffix = f"[{joint}]" if joint else ""
    time = columns["time_s"]
    link = columns[f"link_angle_rad{suffix}"]
    reference = columns[f"reference_rad{suffix}"]
    period = float(np.median(np.diff(time))) if time.size > 1 else 0.005
    before = np.flatnonzero(time < push_start_s)
    after = time >= push_start_s
    if not before.size or not after.any():
        raise ValueError("the log does not cover the push")
    baseline = link[before[-1]]
    window = after & (time < push_start_s + FIRST_PEAK_WINDOW_S)
    first_peak = float(np.nanmax(np.abs(link[window] - baseline)))
    final_count = max(1, int(round(FINAL_WINDOW_S / period)))
    final = float(np.nanmean(link[-final_count:]))
    band = max(SETTLING_FRACTION * first_peak, SETTLING_FLOOR_RAD)
    deviation = link[after] - final
    outside = np.flatnonzero(np.abs(deviation) > band)
    settling = float(time[after][outside[-1]] + period - push_start_s) if outside.size else 0.0
    significant = deviation[np.abs(deviation) > band]
    oscillations = int(np.count_nonzero(np.diff(np.sign(significant)) != 0))
    return {
        "first_peak_rad": first_peak,
        "settling_time_s": settling,
        "steady_state_error_rad": abs(final - float(reference[-1])),
        "oscillations": oscillations,
    }
