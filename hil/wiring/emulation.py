"""From the configuration file to the emulated robot, and the embedded emulator process.

`emulator_spec()` turns the hardware description (IDs, node IDs, resolutions, mountings, baud)
plus the [emulator] section and an experiment's world into what `sim_backend` builds.
`EmbeddedEmulator` runs the server of `hil emulate` - what a user runs in another terminal - in
a process of its own (forked from sim_backend's fork server, which has imported it once) and
reads the endpoints from its first line, so the embedded default and the cross-process setup
take the same path over the same wire.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from hil.config import Config, ConfigError
from hil.experiments import Experiment
from hil.robots import profile_of
from hil.vocabulary import EmulatorClock
from hil.wiring.hardware import encoder_counts_per_rev
from sim_backend.fork_server import ForkedEmulator, ForkServerError, fork_server
from sim_backend.plant import TestbedPlantParams
from sim_backend.scenario import FaultEvent, PelvisPushEvent, PushEvent, Scenario
from sim_backend.servo import H54ServoParams, ServoCascade
from sim_backend.spec import EmulatedJointSpec, EmulatorSpec, SensorNoise
from sim_backend.spec_json import spec_from_json, spec_to_json  # spec_from_json re-exported

__all__ = [
    "EmbeddedEmulator",
    "EmulatorStartError",
    "emulator_spec",
    "spec_from_json",
    "spec_to_json",
]

STARTUP_TIMEOUT_S = 30.0


def experiment_scenario(
    experiment: Experiment | None, faults: tuple[FaultEvent, ...] = ()
) -> Scenario:
    """The world an experiment needs (the block, the pushes) plus injected faults."""
    if experiment is None:
        return Scenario(faults=faults)
    world = experiment.world
    return Scenario(
        pushes=tuple(
            PushEvent(p.start_s, p.duration_s, p.force_n, joint=p.joint) for p in world.pushes
        ),
        faults=faults,
        obstacle_contact_angle_rad=(
            world.obstacle.contact_angle_rad if world.obstacle is not None else None
        ),
        pelvis_pushes=tuple(
            PelvisPushEvent(p.start_s, p.duration_s, p.force_n) for p in world.pelvis_pushes
        ),
    )


def plant_servo_noise(
    config: Config, initial_angle_rad: np.ndarray | None = None
) -> tuple[TestbedPlantParams, H54ServoParams, SensorNoise]:
    """The emulated plant's, servo's and sensors' parameters: [emulator] plant / servo /
    sensor_noise over their defaults (the plant's checked against the robot's own truth, its
    profile's `emulation.plant`); `initial_angle_rad`: where the experiment starts, per joint."""
    emulator = config.emulator
    emulation = profile_of(config).emulation
    overrides = dict(emulator.plant)
    if initial_angle_rad is not None:
        for key, value in emulation.start_overrides(initial_angle_rad).items():
            overrides.setdefault(key, value)
    parts: tuple[tuple[str, Callable[..., Any], dict[str, Any]], ...] = (
        ("plant", lambda **values: emulation.plant(config, values), overrides),
        ("servo", H54ServoParams, emulator.servo),
        ("sensor_noise", SensorNoise, emulator.sensor_noise),
    )
    built = []
    for key, build, values in parts:
        try:
            built.append(build(**values))
        except (TypeError, ValueError) as exc:  # an unknown key, or a value out of range
            raise ConfigError(f"{config.source} [emulator] {key}: {exc}") from exc
    return built[0], built[1], built[2]


@dataclass(frozen=True)
class EmulatedJointStiffness:
    """One emulated joint's static stiffness: its gear spring in series with its servo at the
    gain registers a run leaves it with (the configuration's, written at open, or the
    emulated device's power-on values)."""

    name: str
    gear_stiffness_nm_per_rad: float
    servo: ServoCascade

    @property
    def compliance_rad_per_nm(self) -> float:
        """1/K + 1/(Kpp kv): what the joint deflects per N m of load before the servo's
        velocity integral grows (controller.gravity.joint_static_compliance)."""
        return 1.0 / self.gear_stiffness_nm_per_rad + 1.0 / self.servo.static_stiffness_nm_per_rad


def emulated_joint_stiffness(config: Config) -> tuple[EmulatedJointStiffness, ...]:
    """The emulated robot's joints as `hil emulate` builds them from this configuration (the
    truth: [emulator] plant and servo over their defaults, and the [[joint]] gain registers)."""
    _, servo, _ = plant_servo_noise(config)
    try:
        truth = profile_of(config).emulation.joint_truth(config, servo)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{config.source} [emulator] plant: {exc}") from exc
    joints = []
    for i, joint in enumerate(config.joints):
        params = truth.servos[i]
        cascade = params.cascade_at(
            _register(joint.position_p_gain, truth.power_on_position_gain_registers[i]),
            _register(joint.velocity_p_gain, params.default_velocity_p_gain_register),
            _register(joint.velocity_i_gain, params.default_velocity_i_gain_register),
        )
        joints.append(
            EmulatedJointStiffness(joint.name, float(truth.gear_stiffness_nm_per_rad[i]), cascade)
        )
    return tuple(joints)


def _register(configured: int | None, power_on: int) -> int:
    return power_on if configured is None else configured


def emulator_spec(
    config: Config,
    *,
    experiment: Experiment | None = None,
    faults: tuple[FaultEvent, ...] = (),
    clock: EmulatorClock | None = None,
    seed: int | None = None,
    truth_log: Path | None = None,
) -> EmulatorSpec:
    """The emulator of `config`'s robot for one run of `experiment` (its world and start
    posture); `truth_log`: where it writes its ground truth (sim_backend/truth_log.py)."""
    if len(config.can) != 1:
        raise ConfigError(
            f"{config.source}: the emulator serves one CAN channel (this configuration has "
            f"{len(config.can)})"
        )
    chains = [section.name for section in config.dynamixel]
    start = None
    if experiment is not None:
        start = np.broadcast_to(experiment.reference(0.0), (len(config.joints),))
    plant, servo, noise = plant_servo_noise(config, start)
    try:
        motor_errors, link_errors = config.emulator.zero_errors(len(config.joints))
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc
    # a zero error e in the joint frame is the device's offset moved by direction x e: the host,
    # undoing the [[joint]] offset, then reads the physical angle plus e
    joints = tuple(
        EmulatedJointSpec(
            dxl_id=j.dynamixel_id,
            encoder_node_id=j.encoder_node_id,
            encoder_counts_per_rev=encoder_counts_per_rev(j),
            encoder_direction=j.encoder_direction,
            encoder_offset_rad=j.encoder_offset_rad + j.encoder_direction * link_error,
            motor_direction=j.motor_direction,
            motor_offset_rad=j.motor_offset_rad + j.motor_direction * motor_error,
            model=config.actuator_of(j),
            chain=chains.index(config.chain_of(j)),
        )
        for j, motor_error, link_error in zip(config.joints, motor_errors, link_errors, strict=True)
    )
    for fault in faults:
        if not 0 <= fault.joint < len(joints):
            raise ConfigError(f"fault {fault.kind}: joint index {fault.joint} out of range")
    emulation = profile_of(config).emulation
    try:
        return EmulatorSpec(
            joints=joints,
            baudrate=config.dynamixel[0].baudrate,
            chain_baudrates=tuple(section.baudrate for section in config.dynamixel),
            can_bitrate=config.can[0].bitrate,
            force_sensor_node_id=config.force_sensor.node_id,
            period_s=config.loop.period_s,
            clock=str(clock or config.emulator.clock),
            seed=config.emulator.seed if seed is None else seed,
            plant=plant,
            servo=servo,
            scenario=experiment_scenario(experiment, faults),
            reboot_time_s=config.emulator.reboot_time_s,
            sensor_noise=noise,
            robot=emulation.kind,
            usb_latency_timer_s=_usb_latency_ms(config) * 1e-3,
            truth_log=str(truth_log) if truth_log is not None else "",
            **emulation.spec_parts(config, start, experiment),
        )
    except ValueError as exc:
        raise ConfigError(f"{config.source}: {exc}") from exc


class EmulatorStartError(RuntimeError):
    pass


class EmbeddedEmulator:
    """`hil emulate` in a process of its own, forked from this process's fork server
    (sim_backend/fork_server.py: imported once, each emulator in milliseconds); `endpoints` is
    its first stdout line with its process's "pid", `fault_counts` its last once stopped."""

    def __init__(self, spec: EmulatorSpec) -> None:
        self.spec = spec
        self.process: ForkedEmulator | None = None
        self.endpoints: dict[str, Any] = {}
        self._spec_file: Path | None = None
        self._stdout: TextIO | None = None
        self._stderr: Any = None
        # The emulator's last line after it stopped: how often each injected fault acted.
        self.fault_counts: dict[str, Any] = {}

    def start(self) -> dict[str, Any]:
        """Start the emulator and read its endpoints; on any failure or interrupt, stop it."""
        try:
            return self._start()
        except BaseException:
            self.stop()
            raise

    def _start(self) -> dict[str, Any]:
        fd, name = tempfile.mkstemp(prefix="hil-emulator-", suffix=".json")
        self._spec_file = Path(name)
        with os.fdopen(fd, "w") as f:
            f.write(spec_to_json(self.spec))
        # stderr goes to a file: a pipe nobody reads could fill up and stall the emulator
        self._stderr = tempfile.TemporaryFile(mode="w+", prefix="hil-emulator-stderr-")  # noqa: SIM115
        stdout_read, stdout_write = os.pipe()
        self._stdout = os.fdopen(stdout_read, "r")
        try:
            self.process = fork_server().start(name, stdout_write, self._stderr.fileno())
        except ForkServerError as exc:
            raise EmulatorStartError(str(exc)) from exc
        finally:
            os.close(stdout_write)  # the emulator's copy is the one left: EOF when it ends
        line = self._read_first_line()
        try:
            endpoints = json.loads(line)
        except json.JSONDecodeError:
            self.stop()
            raise EmulatorStartError(
                f"the emulator printed {line!r} instead of its endpoints"
            ) from None
        # its process, which a lock-step bus waits for while it works (hil/wiring/hardware.py)
        assert self.process is not None
        self.endpoints = {**endpoints, "pid": self.process.pid}
        return self.endpoints

    def _read_first_line(self) -> str:
        assert self.process is not None and self._stdout is not None
        readable, _, _ = select.select([self._stdout], [], [], STARTUP_TIMEOUT_S)
        if not readable:
            self.stop()
            raise EmulatorStartError(f"the emulator did not start within {STARTUP_TIMEOUT_S} s")
        line = self._stdout.readline()
        if not line:
            self.process.wait(5.0)
            self._stderr.seek(0)
            err = self._stderr.read()
            self.stop()
            raise EmulatorStartError(f"the emulator exited at start-up:\n{err}")
        return line

    def stop(self) -> None:
        process = self.process
        if process is not None:
            if process.running():
                process.terminate()
                if not process.wait(5.0):
                    process.kill()
                    process.wait(5.0)
            process.close()
        if self._stdout is not None:
            with contextlib.suppress(OSError, ValueError):
                self.fault_counts = _fault_counts(self._stdout.read())
            self._stdout.close()
            self._stdout = None
        if getattr(self, "_stderr", None) is not None:
            self._stderr.close()
            self._stderr = None
        if self._spec_file is not None:
            self._spec_file.unlink(missing_ok=True)
            self._spec_file = None

    def __enter__(self) -> EmbeddedEmulator:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()


def _usb_latency_ms(config: Config) -> float:
    """The emulated adapter's latency timer: [emulator] usb_latency_timer_ms, or the chain's."""
    configured = config.emulator.usb_latency_timer_ms
    return config.dynamixel[0].latency_timer_ms if configured is None else configured


def _fault_counts(rest_of_stdout: str) -> dict[str, Any]:
    """The `{"fault_counts": ...}` line `hil emulate` prints when it stops ({} if none)."""
    for line in reversed(rest_of_stdout.splitlines()):
        with contextlib.suppress(json.JSONDecodeError):
            record = json.loads(line)
            if isinstance(record, dict) and "fault_counts" in record:
                return dict(record["fault_counts"])
    return {}
