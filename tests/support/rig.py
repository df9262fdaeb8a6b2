"""The runs' rig: running the loop of `hil run` on a bus, and reading what a run left behind.

Two ways to run, one loop (hil.loop.run_experiment):
- `run_in_process`: on the in-process joint bus (hil.wiring.in_process): the same plant,
  firmware and faults as the emulator, in milliseconds - for loop, supervisor and session tests;
- `emulated_testbed` + `run_on`: `hil emulate` in its own process (the command a user runs), our
  drivers on the wire, and a direct look at the emulated actuator with ROBOTIS's unmodified
  dynamixel-sdk afterwards (`read_device`: the emulator keeps running) - for the end-to-end path.
A run directory is read back with the product's own loader (hil.output.load_run).
"""

from __future__ import annotations

import contextlib
import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from hil.cli import main
from hil.config import Config, load_config
from hil.experiments import Experiment
from hil.loop import LockstepClock, RunRequest, run_experiment
from hil.output import RunData, RunResult
from hil.output import load_run as load_run_data
from hil.robots import get_experiment
from hil.vocabulary import ControllerChoice
from hil.wiring import Connection, make_bus
from hil.wiring.emulation import EmbeddedEmulator, emulator_spec
from hil.wiring.in_process import InProcessJointBus, in_process_bus
from sim_backend.scenario import FaultEvent

PERIOD_S = 0.005
DXL_ID = 1
# H54-200-S500-R control table (e-Manual): address, size
TORQUE_ENABLE = (562, 1)
HARDWARE_ERROR_STATUS = (892, 1)
RETURN_DELAY_TIME = (9, 1)
MAX_POSITION_LIMIT = (36, 4)
GOAL_POSITION = (596, 4)
FACTORY_RETURN_DELAY = 250  # e-Manual default; the sample configuration writes 0 at open()
FACTORY_MAX_POSITION = 250_961


@dataclass
class Run:
    """One run directory as a user finds it, read with the product's loader."""

    data: RunData
    exit_code: int | None = None

    @property
    def dir(self) -> Path:
        return self.data.out_dir

    @property
    def summary(self) -> dict[str, Any]:
        return self.data.summary

    @property
    def events(self) -> list[dict[str, Any]]:
        return list(self.data.events)

    @property
    def columns(self) -> dict[str, np.ndarray]:
        return self.data.columns

    @property
    def termination(self) -> str:
        return str(self.summary["termination"])

    def trips(self) -> list[dict[str, Any]]:
        return list(self.summary["safety_events"])

    def first_trip(self) -> dict[str, Any] | None:
        trips = self.trips()
        return trips[0] if trips else None

    def notices(self, kind: str) -> list[dict[str, Any]]:
        return [n for n in self.summary["safety_notices"] if n["kind"] == kind]

    def events_of(self, kind: str) -> list[dict[str, Any]]:
        return [e for e in self.events if e["kind"] == kind]


def load_run(out_dir: Path, exit_code: int | None = None) -> Run:
    return Run(load_run_data(out_dir), exit_code)


def assert_log_complete(run: Run) -> None:
    """Every file of the run is on disk and whole: one log row per cycle the loop ran (a
    wall-clock loop that missed whole periods records them in `skipped_ticks`: rows plus skipped
    ticks make the run's ticks), no torn line, an exit note saying what torque was left in."""
    text = (run.dir / "log.csv").read_text()
    assert text.endswith("\n"), "log.csv ends in the middle of a row"
    rows = list(csv.reader(io.StringIO(text)))
    header, body = rows[0], rows[1:]
    assert all(len(row) == len(header) for row in body), "a log row is torn"
    ticks = [int(row[header.index("tick")]) for row in body]
    skipped = [int(row[header.index("skipped_ticks")]) for row in body]
    assert len(body) + sum(skipped) == run.summary["ticks"], (len(body), run.summary["ticks"])
    assert ticks[0] == skipped[0] and all(
        b - a == 1 + s for a, b, s in zip(ticks, ticks[1:], skipped[1:], strict=False)
    ), "the tick column does not follow the grid"
    assert run.summary["exit"], "summary.json does not say what the exit path did"
    for name in ("meta.json", "timing.csv", "events.jsonl"):
        assert (run.dir / name).is_file()


def hil_run(out_root: Path, *args: str) -> Run:
    """`hil run ARGS --no-plots --out OUT_ROOT` in this process; the one run it wrote."""
    out_root.mkdir(parents=True, exist_ok=True)
    before = set(out_root.iterdir())
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["run", *args, "--no-plots", "--out", str(out_root)])
    (out_dir,) = set(out_root.iterdir()) - before
    return load_run(out_dir, code)


def config_with(config: Config | None = None, **safety: Any) -> Config:
    """The built-in testbed configuration with [safety] keys replaced."""
    config = config or load_config()
    return config.changed("safety", **safety)


def run_in_process(
    config: Config,
    experiment: Experiment | str,
    controller: str,
    out_dir: Path,
    *,
    duration_s: float | None = None,
    kdist: float = 1.0,
    faults: tuple[FaultEvent, ...] = (),
    seed: int | None = None,
    bus: InProcessJointBus | None = None,
    choice: ControllerChoice | None = None,
    **request: Any,
) -> tuple[RunResult, Run]:
    """The loop of `hil run` (lock-step) on the in-process joint bus with the experiment's world;
    `choice` (a reading of (25), say) instead of controller + kdist."""
    if isinstance(experiment, str):
        experiment = get_experiment(experiment)
    bus = bus or in_process_bus(config, experiment, faults, seed=seed)
    run_request = RunRequest(
        experiment,
        choice or ControllerChoice(controller, kdist),
        out_dir,
        duration_s=duration_s,
        **request,
    )
    clock = LockstepClock(config.loop.period_s)
    result = run_experiment(config, run_request, bus, clock, {"test": True})
    return result, load_run(out_dir)


@contextlib.contextmanager
def emulated_testbed(
    config: Config, experiment: Experiment | str, faults: tuple[FaultEvent, ...] = ()
) -> Iterator[EmbeddedEmulator]:
    """`hil emulate` (lock-step) in a child process with the experiment's world."""
    if isinstance(experiment, str):
        experiment = get_experiment(experiment)
    with EmbeddedEmulator(emulator_spec(config, experiment=experiment, faults=faults)) as emulator:
        yield emulator


def run_on(
    emulator: EmbeddedEmulator,
    config: Config,
    experiment: Experiment | str,
    controller: str,
    out_dir: Path,
    *,
    duration_s: float,
    kdist: float = 1.0,
    **request: Any,
) -> tuple[RunResult, Run]:
    """The loop of `hil run` (lock-step clock) on an already running emulator."""
    if isinstance(experiment, str):
        experiment = get_experiment(experiment)
    clock = LockstepClock(config.loop.period_s)
    connection = Connection.from_endpoints(emulator.endpoints, config)
    bus = make_bus(config, connection, clock=clock.now)
    run_request = RunRequest(
        experiment, ControllerChoice(controller, kdist), out_dir, duration_s=duration_s, **request
    )
    result = run_experiment(config, run_request, bus, clock, {"test": True})
    return result, load_run(out_dir)


@dataclass(frozen=True)
class DeviceState:
    torque_enabled: int
    hardware_error: int  # the device's Hardware Error Status bits
    return_delay_time: int
    max_position_limit: int
    goal_position: int


class DeviceUnreachable(AssertionError):
    pass


def read_device(endpoints: dict[str, Any], dxl_id: int = DXL_ID) -> DeviceState:
    """Read the emulated actuator's control table with ROBOTIS's SDK (no driver of ours)."""
    port = PortHandler(endpoints["dynamixel_port"])
    assert port.openPort() and port.setBaudRate(int(endpoints["baudrate"]))
    packet = PacketHandler(2.0)
    try:
        values = []
        for address, size in (
            TORQUE_ENABLE,
            HARDWARE_ERROR_STATUS,
            RETURN_DELAY_TIME,
            MAX_POSITION_LIMIT,
            GOAL_POSITION,
        ):
            data, result, _error = packet.readTxRx(port, dxl_id, address, size)
            if result != COMM_SUCCESS:
                raise DeviceUnreachable(
                    f"ID {dxl_id} did not answer a READ of {address}: "
                    f"{packet.getTxRxResult(result)}"
                )
            values.append(int.from_bytes(bytes(data), "little", signed=size == 4))
        return DeviceState(*values)
    finally:
        port.closePort()


def write_torque(endpoints: dict[str, Any], value: int, dxl_id: int = DXL_ID) -> None:
    port = PortHandler(endpoints["dynamixel_port"])
    assert port.openPort() and port.setBaudRate(int(endpoints["baudrate"]))
    try:
        result, _error = PacketHandler(2.0).write1ByteTxRx(port, dxl_id, TORQUE_ENABLE[0], value)
        assert result == COMM_SUCCESS
    finally:
        port.closePort()


def first_tick(mask: np.ndarray) -> int | None:
    index = np.flatnonzero(mask)
    return int(index[0]) if index.size else None
