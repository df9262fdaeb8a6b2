"""DYROS-JET legs that are not the default emulator, for the legs' twin tests: an [emulator]
whose every figure the fit recovers differs from the default's, joint by joint, and is never
given to the fit (the runs record the host's configuration; `bench_hardware.record` runs them
on this truth).

The figures: each joint's gear, servo and rotor off the default by 4-12 %, its Coulomb and
viscous friction by up to 16 %, in both directions; three joints of each leg with another
friction model than the default's; encoder zeros of 1-3 mrad (motor) and 0.15-0.4 mrad (link);
the whole robot 6 % heavier (a battery, a harness the model does not know). Why not more: with
twice these deviations (K 1600-2450 N m/rad, Kpp 8.6-12.2 1/s, kv 67-91 N m s/rad, ...) the
slow walk ends in a safety stop (a joint oscillating at 15.5-15.9 s) with pid and gc+lqr+dob
alike, though each group of figures alone leaves it walking: a bench whose robot cannot walk
is not the test of a twin's walk.
"""

from __future__ import annotations

from hil.config import Config

LEGS_TRUTH_EMULATOR = {
    "plant": {
        # per joint, the lab's order: L hip yaw, roll, pitch, knee, ankle pitch, roll, then R
        "gear_stiffness_nm_per_rad": [1850.0, 2150.0, 1925.0, 2125.0, 1800.0, 2200.0,
                                      2100.0, 1875.0, 2175.0, 1900.0, 2225.0, 1825.0],
        "gear_damping_nms_per_rad": [90.0, 110.0, 95.0, 107.5, 87.5, 112.5,
                                     109.0, 92.5, 105.0, 89.0, 111.0, 94.0],
        "motor_reflected_inertia_kg_m2": [0.23, 0.27, 0.24, 0.265, 0.225, 0.275,
                                          0.26, 0.235, 0.275, 0.23, 0.265, 0.245],
        "gearbox_coulomb_friction_nm": [3.45, 4.3, 3.6, 4.45, 3.35, 4.2,
                                        4.35, 3.5, 4.25, 3.55, 4.4, 3.4],
        "gearbox_viscous_friction_nms_per_rad": [1.02, 1.27, 1.07, 1.32, 0.97, 1.22,
                                                 1.3, 1.05, 1.25, 1.0, 1.32, 1.07],
        "gearbox_friction_model": ["coulomb-viscous", "stribeck", "load-dependent",
                                   "coulomb-viscous", "stribeck", "load-dependent",
                                   "load-dependent", "coulomb-viscous", "stribeck",
                                   "load-dependent", "coulomb-viscous", "stribeck"],
        "gearbox_stribeck_friction_nm": [0.0, 1.5, 0.0, 0.0, 1.2, 0.0,
                                         0.0, 0.0, 1.6, 0.0, 0.0, 1.3],
        "gearbox_stribeck_velocity_rad_s": [0.05, 0.08, 0.05, 0.05, 0.06, 0.05,
                                            0.05, 0.05, 0.07, 0.05, 0.05, 0.09],
        "gearbox_load_friction_ratio": [0.0, 0.0, 0.08, 0.0, 0.0, 0.1,
                                        0.09, 0.0, 0.0, 0.11, 0.0, 0.0],
        "position_gain_per_s": [10.75, 9.4, 11.0, 9.5, 10.5, 9.3,
                                9.6, 10.9, 9.35, 10.6, 9.55, 11.1],
        "velocity_gain_nms_per_rad": [74.0, 83.0, 73.0, 84.0, 75.0, 82.0,
                                      83.0, 74.0, 85.0, 75.0, 84.0, 73.0],
        "velocity_integral_time_s": [13.0, 17.0, 13.5, 16.5, 12.5, 17.5,
                                     16.75, 13.25, 17.25, 12.75, 16.25, 13.75],
        "mass_scale": 1.06,
    },  # fmt: skip
    "motor_zero_error_rad": [2.0e-3, -1.5e-3, 2.5e-3, -2.0e-3, 1.0e-3, -2.5e-3,
                             -1.8e-3, 2.2e-3, -1.2e-3, 1.6e-3, -2.8e-3, 1.4e-3],
    "link_zero_error_rad": [3.0e-4, -2.0e-4, 4.0e-4, -3.0e-4, 2.0e-4, -4.0e-4,
                            -3.5e-4, 2.5e-4, -1.5e-4, 3.5e-4, -2.5e-4, 1.5e-4],
}  # fmt: skip


def legs_truth_config(host: Config) -> Config:
    return host.changed("emulator", **LEGS_TRUTH_EMULATOR)
