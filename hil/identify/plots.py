"""The fit-quality figure: measured against modelled signals over time, and the residuals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from hil.identify.result import IdentificationResult, Parameter


def _shade_holdout(axes, time_s: np.ndarray, start: int) -> None:
    if start < len(time_s):
        for ax in axes:
            ax.axvspan(time_s[start], time_s[-1], color="0.9", zorder=0, lw=0)


def _title(result: IdentificationResult, source: str) -> str:
    p = result.parameters

    def show(parameter: Parameter, fmt: str) -> str:
        e = p[parameter]
        return f"{fmt.format(e.value)} [{fmt.format(e.low)}, {fmt.format(e.high)}]"

    return (
        f"{source}: K = {show(Parameter.GEAR_STIFFNESS, '{:.0f}')} N m/rad, "
        f"D = {show(Parameter.GEAR_DAMPING, '{:.1f}')} N m s/rad, "
        f"Kp(4) = {show(Parameter.SERVO_KP, '{:.2f}')} 1/s\n"
        f"Kpp = {show(Parameter.POSITION_GAIN, '{:.2f}')} 1/s, "
        f"kv = {show(Parameter.VELOCITY_GAIN, '{:.1f}')} N m s/rad, "
        f"Ti = {show(Parameter.VELOCITY_INTEGRAL_TIME, '{:.1f}')} s (95 %)"
    )


def write_identification_figure(
    result: IdentificationResult, path: str | Path, log_index: int = 0
) -> Path:
    """Write the figure for one of the result's logs (PNG, SVG or PDF by suffix); the Agg
    canvas, so it needs no display. The held-out samples are shaded."""
    traces = result.traces[log_index]
    log = traces.log
    t = log.time_s - log.time_s[0]
    deflection = log.link_angle_rad - log.motor_angle_rad
    sim_deflection = traces.link_angle_sim_rad - traces.motor_angle_sim_rad
    figure = Figure(figsize=(11, 12), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(6, 1, sharex=True)
    (ax_motor, ax_defl, ax_current, ax_res_motor, ax_res_defl, ax_res_current) = axes
    _shade_holdout(axes, t, traces.holdout_start_index)

    ax_motor.plot(t, log.goal_rad, color="0.6", lw=0.8, label="goal u")
    ax_motor.plot(t, log.motor_angle_rad, lw=1.0, label="motor, measured")
    ax_motor.plot(t, traces.motor_angle_sim_rad, "--", lw=1.0, label="motor, simulated")
    ax_motor.set_ylabel("angle [rad]")

    ax_defl.plot(t, 1e3 * deflection, lw=1.0, label="measured")
    ax_defl.plot(
        t,
        1e3 * traces.deflection_from_motor_rad,
        "--",
        lw=1.0,
        label="gear model, measured motor in",
    )
    ax_defl.plot(t, 1e3 * sim_deflection, ":", lw=1.0, label="whole joint simulated")
    ax_defl.set_ylabel("deflection\ntheta_j - theta_m [mrad]")

    ax_current.plot(t, log.motor_current_a, lw=0.8, label="measured")
    ax_current.plot(t, traces.motor_current_sim_a, "--", lw=0.8, label="simulated")
    ax_current.set_ylabel("current [A]")

    ax_res_motor.plot(
        t,
        1e3 * (traces.motor_angle_sim_rad - log.motor_angle_rad),
        lw=0.8,
        label="cascade model (whole joint)",
    )
    ax_res_motor.plot(
        t,
        1e3 * (traces.first_order_motor_rad - traces.first_order_measured_rad),
        lw=0.8,
        label="first-order (4), high-passed",
    )
    ax_res_motor.set_ylabel("motor angle\nresidual [mrad]")

    ax_res_defl.plot(
        t, 1e6 * (traces.deflection_from_motor_rad - deflection), lw=0.8, label="gear model"
    )
    ax_res_defl.set_ylabel("deflection\nresidual [urad]")

    ax_res_current.plot(
        t, traces.motor_current_sim_a - log.motor_current_a, lw=0.8, label="whole joint simulated"
    )
    ax_res_current.set_ylabel("current\nresidual [A]")
    ax_res_current.set_xlabel("time [s] (shaded: held out of the fit)")
    for ax in axes:
        ax.legend(loc="upper left", fontsize=7, ncol=3)
        ax.grid(True, lw=0.3)

    figure.suptitle(_title(result, log.source), fontsize=10)
    path = Path(path)
    figure.savefig(path, dpi=110)
    return path
