"""The paper's comparison (Figs. 5 and 6) on the in-process emulated testbed, for a controller
option set: what an option does to each paper relation, without the buses.

    .venv/bin/python tests/controller/comparison.py                       # as hil runs it
    .venv/bin/python tests/controller/comparison.py --design continuous-cost
    .venv/bin/python tests/controller/comparison.py --no-noise --contact-s 32

The figures are hil.metrics' (contact: peak and mean force in contact, overload trip; impact:
first peak, settling, oscillations) plus the quasi-static error 3.75 s after the push (what the
5 s run's "steady_state_error_rad" measures). Not a test: a tool for the report.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from sim_harness import (  # noqa: E402
    IMPACT_PUSH_START_S,
    Trace,
    configured_controller,
    contact_scene,
    impact_scene,
    simulate,
)

from hil.metrics import contact_metrics, impact_metrics  # noqa: E402
from hil.steady_state import quasi_static_error  # noqa: E402
from sim_backend.server import SensorNoise  # noqa: E402
from sim_backend.servo import OVERLOAD_BIT, H54ServoParams  # noqa: E402

RUNS: tuple[tuple[str, str, float, dict[str, Any]], ...] = (
    ("pid", "pid", 1.0, {}),
    ("gc", "gc", 1.0, {}),
    ("gc+lqr", "gc+lqr", 1.0, {}),
    ("gc+lqr+dob (Kdist 0.5)", "gc+lqr+dob", 0.5, {}),
    ("gc+lqr+dob (Kdist 1)", "gc+lqr+dob", 1.0, {}),
    ("gc+lqr+dob (Kdist 1), literal", "gc+lqr+dob", 1.0, {"composition": "literal"}),
)


def _bounded(kdist: float) -> tuple[str, str, float, dict[str, Any]]:
    return (
        f"gc+lqr+dob (Kdist {kdist:g}), accumulated-integral",
        "gc+lqr+dob",
        kdist,
        {
            "composition": "accumulated-integral",
            "dob_integral_time_s": H54ServoParams().velocity_integral_time_s,
        },
    )


def _columns(trace: Trace) -> dict[str, np.ndarray]:
    return {
        "time_s": trace.time_s,
        "contact_force_n": trace.contact_force_n,
        "hardware_error": np.where(trace.overload, OVERLOAD_BIT, 0),
        "torque_enabled": trace.torque_enabled.astype(float),
        "link_angle_rad": trace.link_angle_rad,
        "reference_rad": trace.reference_rad,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--design", default="euler", help="LQR design (ControllerParams)")
    parser.add_argument("--no-noise", action="store_true", help="ideal sensors")
    parser.add_argument("--contact-s", type=float, default=8.0)
    parser.add_argument("--impact-s", type=float, default=5.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    noise = SensorNoise(0.0, 0.0) if args.no_noise else SensorNoise()
    servo = (
        H54ServoParams(current_noise_a=0.0, velocity_noise_rad_s=0.0)
        if args.no_noise
        else H54ServoParams()
    )
    runs = (*RUNS, _bounded(0.5), _bounded(1.0))
    print(f"design {args.design}, noise {'off' if args.no_noise else 'nominal'}, seed {args.seed}")
    common = {"seed": args.seed, "servo": servo, "sensor_noise": noise}
    for label, name, kdist, options in runs:
        fresh = [
            configured_controller(name, kdist, discretisation=args.design, **options)
            for _ in range(2)
        ]
        contact = contact_metrics(
            _columns(simulate(fresh[0], contact_scene(args.contact_s), **common))
        )
        impact_trace = simulate(fresh[1], impact_scene(args.impact_s), **common)
        impact = impact_metrics(_columns(impact_trace), IMPACT_PUSH_START_S)
        quasi = quasi_static_error(
            impact_trace.time_s,
            impact_trace.link_angle_rad,
            impact_trace.reference_rad,
            IMPACT_PUSH_START_S,
            min(3.75, args.impact_s - IMPACT_PUSH_START_S - 0.05),
        )
        trip = contact["trip_time_after_contact_s"]
        print(
            f"{label:52s} contact peak {contact['peak_contact_force_n']:5.1f} N "
            f"mean {contact['mean_contact_force_n']:5.1f} N "
            f"{'trip ' + format(trip, '.2f') + ' s' if trip is not None else 'no trip':11s} | "
            f"impact peak {impact['first_peak_rad']:.4f} rad "
            f"settle {impact['settling_time_s']:.2f} s "
            f"osc {impact['oscillations']} "
            f"e({quasi.after_push_s:g} s) {quasi.error_rad:+.4f} rad"
        )


if __name__ == "__main__":
    main()
