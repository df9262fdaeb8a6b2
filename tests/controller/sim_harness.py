"""The emulated testbed in process, without the buses, for controller tests.

The same devices `hil emulate` serves (sim_backend's `EmulatedJoint` behind an `H54Device`
control table, the CiA 406 `LinkEncoderNode`, the MuJoCo plant with the experiment's block and
push), stepped in lock-step at the loop period exactly as the emulator does on each SYNC:

    tick 0       the scenario clock starts; sensors are read (no physics step yet)
    tick k > 0   the goal written at tick k-1 acts over one period (`VirtualTestbed.advance`),
                 then the encoder latches the link angle (SYNC -> TPDO) and the host reads the
                 control table's Present Position

The sensors carry the emulator's nominal noise (`SensorNoise`, `H54ServoParams`), seeded as
the emulator seeds them; pass zero figures for an ideal testbed.

Units cross the "wire" only through the emulator's own conversions: the goal is written as
Goal Position pulses (sim_backend.servo.RAD_PER_PULSE) through `H54Device.write` (the access
and limit rules of the real device apply), the motor angle is read as Present Position pulses,
the link angle arrives as the encoder node's TPDO counts (its counts per revolution).

The loop around the controller is hil's: hold the present position for `hold_ticks` (goal =
the motor angle read at tick 0), then reset the controller with that hold goal as the goal in
force and step it every tick. Of hil's supervisor only the goal's limits are kept (the joint's
angle range and the goal rate of the built-in configuration, fed back through notify_applied);
there is no current guard, so the actuator's own overload protection is what a test sees.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

import can
import numpy as np

from controller import (
    ControllerParams,
    FlexibleJointParams,
    JointController,
    LqrWeights,
    PendulumGravity,
    make_controller,
    single_link_sm,
)
from hil.experiments import CONTACT, IMPACT, Experiment
from sim_backend.canbus import LinkEncoderNode
from sim_backend.dynamixel import H54_LAYOUT, H54Device
from sim_backend.plant import TestbedPlantParams
from sim_backend.scenario import PushEvent
from sim_backend.server import SensorNoise, _rng, _with_obstacle
from sim_backend.servo import OVERLOAD_BIT, RAD_PER_PULSE, H54ServoParams
from sim_backend.testbed import EmulatedJoint, VirtualTestbed

PERIOD_S = 0.005  # the paper's 200 Hz
HOLD_TICKS = 5  # hil's [loop] stop_cycles
GOAL_RANGE_RAD = (-0.8, 0.8)  # hil/data/testbed.toml [[joint]] min/max_angle_rad
MAX_GOAL_RATE_RAD_S = 2.0  # hil/data/testbed.toml [safety] max_goal_rate_rad_s
ENCODER_NODE_ID = 5
_SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
_START_ALL = can.Message(arbitration_id=0x000, data=bytes([0x01, 0]), is_extended_id=False)
_GOAL_POSITION = H54_LAYOUT["Goal Position"]
_TORQUE_ENABLE = H54_LAYOUT["Torque Enable"]


@dataclass(frozen=True)
class Scene:
    """What the world does during a run: the reference, the block, the pushes."""

    name: str
    duration_s: float
    reference: Callable[[float], float]
    obstacle_contact_angle_rad: float | None = None
    pushes: tuple[PushEvent, ...] = ()
    initial_link_angle_rad: float = 0.0


def scene_of(experiment: Experiment, duration_s: float | None = None) -> Scene:
    """hil's experiment (Fig. 5 contact, Fig. 6 impact) as a scene, optionally longer."""
    return Scene(
        name=experiment.name,
        duration_s=experiment.duration_s if duration_s is None else duration_s,
        reference=experiment.reference,
        obstacle_contact_angle_rad=(
            experiment.obstacle.contact_angle_rad if experiment.obstacle else None
        ),
        pushes=tuple(PushEvent(p.start_s, p.duration_s, p.force_n) for p in experiment.pushes),
        initial_link_angle_rad=experiment.initial_angle_rad,
    )


def contact_scene(duration_s: float | None = None) -> Scene:
    return scene_of(CONTACT, duration_s)


def impact_scene(duration_s: float | None = None) -> Scene:
    return scene_of(IMPACT, duration_s)


IMPACT_PUSH_START_S = IMPACT.pushes[0].start_s


@dataclass
class Trace:
    """One run, one row per tick (the goal is NaN on ticks before the first write)."""

    time_s: np.ndarray
    reference_rad: np.ndarray
    link_angle_rad: np.ndarray
    motor_angle_rad: np.ndarray
    goal_rad: np.ndarray
    contact_force_n: np.ndarray
    overload: np.ndarray
    torque_enabled: np.ndarray
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def overload_tripped(self) -> bool:
        return bool(self.overload.any())

    def contact_time_s(self, threshold_n: float = 1.0) -> float | None:
        touching = np.flatnonzero(self.contact_force_n > threshold_n)
        return float(self.time_s[touching[0]]) if touching.size else None


def emulated_plant() -> TestbedPlantParams:
    return TestbedPlantParams()


def configured_controller(
    name: str,
    kdist: float = 1.0,
    *,
    plant: TestbedPlantParams | None = None,
    **overrides: object,
) -> JointController:
    """The controller as `hil run` builds it for the built-in testbed configuration: the paper's
    K, D, Kp, Q and R, the lab's Euler design, accumulated reading, 11.4 Hz cut-off, and the
    link inertia and gravity moment of the emulated plant (the model matched to the plant)."""
    plant = plant or emulated_plant()
    fields: dict[str, object] = {
        "joints": FlexibleJointParams.uniform(1),
        "lqr_weights": LqrWeights(10.0, 1.0, 1.0),
        "kdist": kdist,
        "dob_cutoff_hz": 11.4,
        "composition": "accumulated",
        "discretisation": "euler",
    }
    fields.update(overrides)
    params = ControllerParams(**fields)  # type: ignore[arg-type]
    return make_controller(
        name,
        params,
        sm=single_link_sm(plant.link_inertia_kg_m2),
        dt_s=PERIOD_S,
        gravity=PendulumGravity(plant.gravity_moment_kg_m, 1.0),
    )


class InProcessTestbed:
    """One emulated joint with its encoder node, stepped tick by tick (see module docstring)."""

    def __init__(
        self,
        scene: Scene,
        *,
        seed: int = 0,
        plant: TestbedPlantParams | None = None,
        servo: H54ServoParams | None = None,
        sensor_noise: SensorNoise | None = None,
    ) -> None:
        plant = plant or emulated_plant()
        noise = sensor_noise or SensorNoise()
        plant = TestbedPlantParams(
            **{
                **{f: getattr(plant, f) for f in plant.__dataclass_fields__},
                "initial_link_angle_rad": scene.initial_link_angle_rad,
            }
        )
        plant = _with_obstacle(plant, scene.obstacle_contact_angle_rad)
        self.device = H54Device(1)
        self.joint = EmulatedJoint(
            self.device, plant, servo or H54ServoParams(), rng=_rng(seed, 1000)
        )
        self.joint.pushes = list(scene.pushes)
        self.testbed = VirtualTestbed([self.joint])
        self.encoder = LinkEncoderNode(
            ENCODER_NODE_ID,
            lambda: self.joint.plant.link_angle_rad,
            seed=seed * 7919,  # as the emulator seeds its first encoder
            noise_counts_rms=noise.link_encoder_counts_rms,
        )
        self._tpdo_id = 0x180 + ENCODER_NODE_ID
        self._rad_per_count = 2.0 * math.pi / int(self.encoder._store.stored_value(0x6001))
        self._now_s = 0.0
        self.encoder.poll(0.0)  # boot-up
        self.encoder.handle(_START_ALL, 0.0)
        self.ticks = 0

    def sync(self, period_s: float) -> tuple[float, float]:
        """One SYNC: physics over the last period (not on the first), then (motor, link) [rad]."""
        if self.ticks == 0:
            self.testbed.start_scenario()
        else:
            self.testbed.advance(period_s)
        self._now_s += period_s
        self.ticks += 1
        frames = self.encoder.handle(_SYNC, self._now_s)
        tpdo = next(f for f in frames if f.arbitration_id == self._tpdo_id)
        (counts,) = struct.unpack("<i", bytes(tpdo.data[:4]))
        motor = self.device.item("Present Position") * RAD_PER_PULSE
        return motor, counts * self._rad_per_count

    def write_goal(self, goal_rad: float) -> None:
        pulses = round(goal_rad / RAD_PER_PULSE)
        error = self.device.write(_GOAL_POSITION.address, _GOAL_POSITION.encode(pulses))
        if error:
            raise RuntimeError(f"the device refused Goal Position {pulses}: error {error}")

    def enable_torque(self) -> None:
        error = self.device.write(_TORQUE_ENABLE.address, _TORQUE_ENABLE.encode(1))
        if error:
            raise RuntimeError(f"the device refused Torque Enable: error {error}")

    @property
    def overload(self) -> bool:
        return bool(self.device.hardware_error_status & OVERLOAD_BIT)


def simulate(
    controller: JointController,
    scene: Scene,
    *,
    seed: int = 0,
    plant: TestbedPlantParams | None = None,
    servo: H54ServoParams | None = None,
    sensor_noise: SensorNoise | None = None,
    hold_ticks: int = HOLD_TICKS,
    period_s: float = PERIOD_S,
    goal_range_rad: tuple[float, float] = GOAL_RANGE_RAD,
    max_goal_rate_rad_s: float = MAX_GOAL_RATE_RAD_S,
    before_step: Callable[[int, float, JointController], None] | None = None,
) -> Trace:
    """Run `controller` through `scene` on the in-process testbed; one Trace row per tick.

    before_step(tick, time_s, controller) runs before each controller step (e.g. a Kdist
    schedule)."""
    bed = InProcessTestbed(scene, seed=seed, plant=plant, servo=servo, sensor_noise=sensor_noise)
    n_ticks = int(round(scene.duration_s / period_s))
    rows = np.full((n_ticks, 8), math.nan)
    hold_goal = goal = math.nan
    for k in range(n_ticks):
        time_s = k * period_s
        motor, link = bed.sync(period_s)
        reference = scene.reference(time_s)
        if k == 0:
            bed.enable_torque()
            hold_goal = motor
        if k < hold_ticks:
            goal = hold_goal
        else:
            m, j, r = np.array([motor]), np.array([link]), np.array([reference])
            if k == hold_ticks:
                controller.reset(m, j, r, goal_in_force_rad=np.array([hold_goal]))
            if before_step is not None:
                before_step(k, time_s, controller)
            proposed = float(controller.step(m, j, r)[0])
            step_limit = max_goal_rate_rad_s * period_s
            goal = min(max(proposed, goal - step_limit), goal + step_limit)
            goal = min(max(goal, goal_range_rad[0]), goal_range_rad[1])
            controller.notify_applied(np.array([goal]))
        if bed.device.torque_enabled:
            bed.write_goal(goal)
        rows[k] = (
            time_s,
            reference,
            link,
            motor,
            goal,
            bed.joint.plant.contact_force_n(),
            bed.overload,
            bed.device.torque_enabled,
        )
    return Trace(
        time_s=rows[:, 0],
        reference_rad=rows[:, 1],
        link_angle_rad=rows[:, 2],
        motor_angle_rad=rows[:, 3],
        goal_rad=rows[:, 4],
        contact_force_n=rows[:, 5],
        overload=rows[:, 6] > 0.5,
        torque_enabled=rows[:, 7] > 0.5,
    )
