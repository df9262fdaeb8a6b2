"""Identification of a flexible joint's constants from the logs of a run.

What is fitted (Kim et al., ICRA 2018, Sec. II; the actuator as the H54 firmware runs it):

    (1)  tau_j = K (theta_m - theta_j + delta_0) + D (theta_m' - theta_j')      the gear
    (3)  I theta_j'' = tau_j - g m r cos theta_j                                 the link, 1-DoF
    (4)  theta_m' = Kp (u - theta_m)                                            the paper's servo
    the actuator's cascade, which (4) approximates:
         w* = Kpp (u - theta_m),  tau = kv (w* - theta_m') + iota,  iota' = kv/Ti (w* - theta_m')
         Jm theta_m'' = tau - b theta_m' - F_c sgn(theta_m') - tau_j,  |tau| <= Kt i_max
         the measured current i = tau / Kt

u is the goal held over each loop period, delta_0 the deflection the encoders read with no
torque in the gear (their zero offsets). Equations and discretisation: `models`.

The estimator (`estimation`; each fit in its module: `gear_fit`, `servo_fit`, `cascade_fit`,
`current_limit`, over `least_squares` and `options`), three least-squares fits, each on the part
of the data that carries its parameters, each with the samples from the hold-out point on kept
out:
1. K, D, delta_0: output error of theta_j simulated by (1), (3) from the measured motor motion
   (exact discretisation, motor angle between samples the cubic through the measured angles
   and velocities). The motor's own model does not enter, so its errors (friction) cannot
   bias K and D.
2. Kp of (4): output error of theta_m simulated by (4) from u, both high-passed at 0.1 Hz
   (the slow gravity lag is not in (4)). The best first-order description on the swept band.
3. Kpp, kv, Ti (with iota_0, Jm, b, F_c as nuisance): prediction error of theta_m, theta_m'
   and i one period ahead from each measured state, through the cascade stepped at 1 ms
   like the emulator's MuJoCo plant; iota reconstructed from the measured signals. The current
   carries the servo law directly; friction and inertia only need to be right for 5 ms.
Intervals: 95 %, from the Jacobian and a Newey-West sandwich over time-correlated residuals
(`covariance`); fit quality: VAF and normalised RMS error on the held-out samples, of each
model and of the whole joint simulated from the goals alone.

Assumptions: the link moves freely (no contact, no push); the run stays below the current and
speed caps (then the cascade is linear but for friction); the logs are uniformly sampled (the
fit takes the longest uninterrupted stretch); the link is one rigid body about the joint axis.

What these encoders cannot identify, and why:
- The absolute scale of K and D. Motor angle, link angle and motor velocity are kinematics:
  they fix K/I, D/I and g m r/I, never K alone. The fit takes the link inertia I (and m r)
  from the configuration; an error in I passes one to one into K and D. The other absolute
  reference is the current times the torque constant Kt (a data-sheet figure), used here for
  the velocity-loop gain kv only.
- kv's scale rests on Kt the same way (Kpp and Ti are rates and times: scale-free).
- g m r against delta_0: with the link near one angle, cos theta_j barely changes, so the
  static gravity torque and an encoder offset look the same; m r is given and delta_0 fitted.
- Ti needs a run of about twice Ti or more, with a steady load (gravity) for the integral to
  wind out: with the link vertical or a short run it is barely seen (the fit notes it).
- The current limit only if the run reaches it, which an identification run must not (the
  overload protection trips near it): otherwise only a lower bound, the largest current seen.
  Read it from the actuator's Torque Limit register instead (give it as current_limit_a).
- The motor side (reflected inertia, gearbox friction): its dynamics (~300 rad/s through the
  velocity loop) sit near the 200 Hz loop's Nyquist frequency and the friction's stick-slip is
  only approximately Coulomb: fitted so the cascade can be, reported as nuisance.
- Kp of (4) is not a constant of the actuator: the first-order fit of the cascade depends on
  the amplitude (Coulomb friction adds a lag of F_c/(Kpp kv), larger for small motions) and on
  the load. It is the best (4) for the excitation's band and amplitude.
"""

import importlib

from hil.identify.excitation import (
    ChirpExcitation,
    ExcitationTrajectory,
    chirp_goal_offsets,
    peak_motor_torque_bound_nm,
)
from hil.identify.records import (
    H54_TORQUE_CONSTANT_NM_PER_A,
    JointLog,
    KnownJointFigures,
    LogFormatError,
)
from hil.identify.result import (
    FitQuality,
    IdentificationResult,
    Parameter,
    ParameterEstimate,
    Status,
    render_config_fragment,
    result_to_json,
)

# The fits (scipy.optimize, .signal, .stats) and the figure (matplotlib) load when first asked
# for: the excitation and the records are all an experiment needs to run (hil run identify).
_LAZY = {
    "IdentificationOptions": "options",
    "fit_cascade": "cascade_fit",
    "fit_first_order_servo": "servo_fit",
    "fit_gear": "gear_fit",
    "identify": "estimation",
    "GearParams": "models",
    "MotorParams": "models",
    "ServoParams": "models",
    "write_identification_figure": "plots",
}


def __getattr__(name: str) -> object:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


__all__ = [
    "H54_TORQUE_CONSTANT_NM_PER_A",
    "ChirpExcitation",
    "ExcitationTrajectory",
    "FitQuality",
    "GearParams",
    "IdentificationOptions",
    "IdentificationResult",
    "JointLog",
    "KnownJointFigures",
    "LogFormatError",
    "MotorParams",
    "Parameter",
    "ParameterEstimate",
    "ServoParams",
    "Status",
    "chirp_goal_offsets",
    "fit_cascade",
    "fit_first_order_servo",
    "fit_gear",
    "identify",
    "peak_motor_torque_bound_nm",
    "render_config_fragment",
    "result_to_json",
    "write_identification_figure",
]
