"""The product's LQR (+ DOB) closed around the linearised emulated DYROS-JET (for the tests and
docs/studies/lqr_design): what `sim_backend.humanoid.linear` gives, with the controller of
controller/controllers.py written out as a linear map per tick.

    the plant            z(k+1) = F z(k) + G u(k)  (the goal written at k, held one period)
    the controller       the samples theta_m(k), theta_j(k); the link velocity
                         v(k) = (theta_j(k) - theta_j(k-1)) / dt and the motor's
                         w(k) = (theta_m(k) - theta_m(k-1)) / dt (controller/estimation.py);
                         duc(k) = -(Ke (theta_j - theta_d) + Kx dx(k) + Kw dw(k)) (24);
                         the DOB's q(k) = alpha q(k-1) + (1 - alpha) ((theta_m(k) - a
                         theta_m(k-1)) / b - u(k-1)) (9)-(11); the accumulated reading of (25):
                         u(k) = u(k-1) + duc(k) + s Kdist q(k)
    loop state           [z; theta_m, theta_j, v, w at k-1; u(k-1); q(k-1)]

The reference and the gravity compensator's ug are constant: they do not enter a linear loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from controller import ControllerParams, TrackingGain
from controller.humanoid import HumanoidLegGravity, LegModel, SupportState
from sim_backend.dynamixel import H54Device
from sim_backend.humanoid.linear import TickModel, rigid_body_mode
from sim_backend.humanoid.params import RobotTruthParams, leg_eeprom_overrides
from sim_backend.humanoid.robot import EmulatedRobot
from sim_backend.servo import RAD_PER_PULSE

URDF_PATH = Path(__file__).resolve().parents[2] / "hil" / "data" / "robots" / "dyros_jet.urdf"
GEAR_STIFFNESS_NM_PER_RAD = 2000.0


def settled_robot(
    angles: np.ndarray,
    support: SupportState,
    *,
    seconds: float = 3.0,
    truth: RobotTruthParams | None = None,
    urdf_text: str | None = None,
) -> EmulatedRobot:
    """The emulated robot placed at `angles` on the feet of `support`, its goals the gravity
    compensator's (8) (angles + K^-1 tau_g), settled for `seconds`."""
    text = urdf_text if urdf_text is not None else URDF_PATH.read_text()
    tau = HumanoidLegGravity(LegModel(text), support).gravity_torque(angles)
    goal = angles + tau / GEAR_STIFFNESS_NM_PER_RAD
    devices = [H54Device(i + 1, eeprom_overrides=leg_eeprom_overrides()) for i in range(12)]
    robot = EmulatedRobot(
        text, devices, truth=truth, initial_leg_angles_rad=angles, support_feet=support.feet
    )
    for joint, device in enumerate(devices):
        device.set_item("Torque Enable", 1)
        device.set_item("Goal Position", round(goal[joint] / RAD_PER_PULSE))
    robot.advance(seconds)
    return robot


@dataclass(frozen=True)
class Dob:
    """The DOB in the loop: Kdist per joint (times the gain's scale) and its nominal servo."""

    kdist: float
    params: ControllerParams

    def coefficients(self, dt_s: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(a, b) of the nominal servo sampled as the controller samples it, and alpha."""
        kp = self.params.joints.servo_gain_per_s
        a = 1.0 - kp * dt_s if self.params.discretisation == "euler" else np.exp(-kp * dt_s)
        return a, 1.0 - a, self.params.q_filter_pole(dt_s)


def closed_loop(model: TickModel, gain: TrackingGain, dob: Dob | None = None) -> np.ndarray:
    """The loop's matrix per tick (module docstring), built column by column."""
    n = gain.n_joints
    size = model.size
    dt = model.period_s
    ke, kx = gain.error_gain, gain.state_increment_gain
    kw = gain.motor_velocity_increment_gain
    scale = gain.dob_gain_scale if gain.dob_gain_scale is not None else np.ones(n)
    coefficients = dob.coefficients(dt) if dob is not None else None
    loop_size = size + 5 * n + (n if dob is not None else 0)

    def step(z: np.ndarray) -> np.ndarray:
        x = z[:size]
        previous = z[size : size + 4 * n]
        u_previous = z[size + 4 * n : size + 5 * n]
        motor, link = model.motor_angle @ x, model.link_angle @ x
        link_velocity = (link - previous[n : 2 * n]) / dt
        motor_velocity = (motor - previous[:n]) / dt
        sample = np.concatenate([motor, link, link_velocity, motor_velocity])
        increment = sample - previous
        duc = -(ke @ link + kx @ increment[: 3 * n])
        if kw is not None:
            duc -= kw @ increment[3 * n :]
        u = u_previous + duc
        parts = [sample]
        if dob is not None and coefficients is not None:
            a, b, alpha = coefficients
            q_previous = z[size + 5 * n :]
            q = alpha * q_previous + (1 - alpha) * ((motor - a * previous[:n]) / b - u_previous)
            u = u + scale * dob.kdist * q
            parts += [u, q]
        else:
            parts += [u]
        return np.concatenate([model.f @ x + model.g @ u, *parts])

    return np.array([step(column) for column in np.eye(loop_size)]).T


@dataclass(frozen=True)
class LoopModes:
    """The loop's largest |z| (rigid-body modes of the plant aside) and the largest |z| of its
    oscillatory modes (above 0.2 Hz), with their frequencies [Hz]."""

    radius: float
    radius_hz: float
    oscillatory: float
    oscillatory_hz: float

    def text(self) -> str:
        return (
            f"{self.radius:.5f} ({self.radius_hz:.2f} Hz); oscillatory {self.oscillatory:.4f} "
            f"({self.oscillatory_hz:.2f} Hz)"
        )


def loop_modes(model: TickModel, matrix: np.ndarray, min_hz: float = 0.2) -> LoopModes:
    eigenvalues, vectors = np.linalg.eig(matrix)
    keep = [
        i
        for i, value in enumerate(eigenvalues)
        if not (abs(value - 1) < 1e-6 and rigid_body_mode(model, vectors[:, i]))
    ]
    values = eigenvalues[keep]
    hz = np.abs(np.angle(values)) / (2 * np.pi * model.period_s)
    top = int(np.argmax(np.abs(values)))
    oscillating = np.flatnonzero(hz > min_hz)
    top_osc = oscillating[int(np.argmax(np.abs(values[oscillating])))]
    return LoopModes(
        float(abs(values[top])),
        float(hz[top]),
        float(abs(values[top_osc])),
        float(hz[top_osc]),
    )
