"""How far the emulated robot runs from the speed of its physics: three real-time factors of
the same lock-step experiment, measured side by side.

    through the buses   `hil run`'s path: `hil emulate` in a child process, the Dynamixel chain
                        and the CAN channel on pseudo-terminals, the unmodified SDKs
    in process          the same loop on the in-process joint bus (hil/wiring/in_process.py):
                        the same devices, firmware, plant and controller, no wire, no pty
    MuJoCo alone        `mujoco.mj_step` on the emulated plant's own model(s), as many physics
                        steps as the run simulates: nothing but the physics (the limit)
    bus alone           through the buses and in process, the bus without the loop: each tick a
                        read and a write of the held goal, no controller, supervisor or log.
                        Through the buses the host's own CPU per tick is measured too: the
                        unmodified SDKs' work and our drivers', the floor of the host's side
                        (`host_bound`: the factor it allows were the emulator and the loop free)

real-time factor = simulated time / wall time of the loop (from its second tick: the first
runs the start gate and turns torque on). The paths are taken in turn, `rounds` times
(A B C A B C ...), so a burst of load on this shared machine falls on all of them alike, and
the report gives each one's median and their ratios (through the buses / MuJoCo alone etc.).
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from drivers.joint_bus import JointBus
from hil.bench.common import StartFailed, with_retries
from hil.config import Config
from hil.experiments import Experiment
from hil.loop import LockstepClock, RunRequest, run_experiment
from hil.vocabulary import ControllerChoice, ControllerKind, EmulatorClock
from hil.wiring import Connection, make_bus
from hil.wiring.emulation import EmbeddedEmulator, emulator_spec
from hil.wiring.in_process import in_process_bus
from sim_backend.robots import build_hardware
from sim_backend.spec import EmulatorSpec

PATHS = ("buses", "in_process", "mujoco_alone", "buses_bus_alone", "in_process_bus_alone")
BUS_ALONE_WARMUP_TICKS = 20
DEFAULT_ROUNDS = 3


class _TickTimes(LockstepClock):
    """The lock-step clock, remembering when each tick started (perf_counter)."""

    def __init__(self, period_s: float) -> None:
        super().__init__(period_s)
        self.started_s: list[float] = []

    def next_tick(self):  # type: ignore[no-untyped-def]
        tick = super().next_tick()
        self.started_s.append(time.perf_counter())
        return tick

    def real_time_factor(self) -> tuple[float, float]:
        """(simulated s, factor) from the second tick to the last."""
        ticks = len(self.started_s)
        if ticks < 4:
            raise StartFailed(f"the run made only {ticks} tick(s)")
        simulated_s = (ticks - 2) * self.period_s
        return simulated_s, simulated_s / (self.started_s[-1] - self.started_s[1])


def _request(
    config: Config, experiment: Experiment, controller: ControllerKind, out: Path, ticks: int
):
    return RunRequest(
        experiment=experiment,
        choice=ControllerChoice(controller, config.controller.kdist),
        out_dir=out,
        duration_s=ticks * config.loop.period_s,
    )


def run_through_buses(
    config: Config, experiment: Experiment, controller: ControllerKind, ticks: int, out: Path
) -> dict[str, Any]:
    spec = emulator_spec(config, experiment=experiment, clock=EmulatorClock.LOCKSTEP)
    clock = _TickTimes(config.loop.period_s)
    with EmbeddedEmulator(spec) as emulator:
        connection = Connection.from_endpoints(emulator.endpoints, config)
        bus = make_bus(config, connection, clock=clock.now)
        result = run_experiment(
            config, _request(config, experiment, controller, out, ticks), bus, clock, {}
        )
    simulated_s, factor = clock.real_time_factor()
    return {"simulated_s": simulated_s, "real_time_factor": factor, "ending": result.ending.text}


def run_in_process(
    config: Config, experiment: Experiment, controller: ControllerKind, ticks: int, out: Path
) -> dict[str, Any]:
    clock = _TickTimes(config.loop.period_s)
    bus = in_process_bus(config, experiment)
    result = run_experiment(
        config, _request(config, experiment, controller, out, ticks), bus, clock, {}
    )
    simulated_s, factor = clock.real_time_factor()
    return {"simulated_s": simulated_s, "real_time_factor": factor, "ending": result.ending.text}


def run_bus_alone(config: Config, bus: JointBus, ticks: int) -> dict[str, Any]:
    """Open `bus`, turn torque on holding the present position, then `ticks` times a read and
    a write of that goal (after a few ticks' warm-up); torque off and closed on every exit."""
    bus.open()
    try:
        goal = bus.read().motor_angle_rad.copy()
        if not np.isfinite(goal).all():
            raise StartFailed("an actuator did not answer the first read")
        bus.enable()
        try:
            for _ in range(BUS_ALONE_WARMUP_TICKS):
                bus.read()
                bus.write(goal)
            cpu_started, started = time.process_time(), time.perf_counter()
            for _ in range(ticks):
                bus.read()
                bus.write(goal)
            wall_s = time.perf_counter() - started
            cpu_s = time.process_time() - cpu_started
        finally:
            bus.disable()
    finally:
        bus.close()
    simulated_s = ticks * config.loop.period_s
    return {
        "simulated_s": simulated_s,
        "real_time_factor": simulated_s / wall_s,
        "host_cpu_s_per_tick": cpu_s / ticks,
        "ending": "",
    }


def run_bus_alone_through_buses(
    config: Config, experiment: Experiment, ticks: int
) -> dict[str, Any]:
    spec = emulator_spec(config, experiment=experiment, clock=EmulatorClock.LOCKSTEP)
    with EmbeddedEmulator(spec) as emulator:
        connection = Connection.from_endpoints(emulator.endpoints, config)
        return run_bus_alone(config, make_bus(config, connection), ticks)


def run_bus_alone_in_process(config: Config, experiment: Experiment, ticks: int) -> dict[str, Any]:
    return run_bus_alone(config, in_process_bus(config, experiment), ticks)


def physics_models(spec: EmulatorSpec) -> list[tuple[mujoco.MjModel, mujoco.MjData]]:
    """The MuJoCo model(s) the emulated hardware of `spec` steps, at its initial state: one
    for the humanoid, one per joint for the testbed."""
    hardware = build_hardware(spec)
    robot = getattr(hardware, "robot", None)
    plants = [robot.plant] if robot is not None else [joint.plant for joint in hardware.joints]
    return [(plant.model, plant.data) for plant in plants]


def run_mujoco_alone(config: Config, experiment: Experiment, ticks: int) -> dict[str, Any]:
    """mj_step on the plant's model(s) for as many physics steps as `ticks` ticks simulate."""
    spec = emulator_spec(config, experiment=experiment, clock=EmulatorClock.LOCKSTEP)
    models = physics_models(spec)
    timestep_s = float(models[0][0].opt.timestep)
    steps = round((ticks - 2) * config.loop.period_s / timestep_s)
    step = mujoco.mj_step
    started = time.perf_counter()
    for _ in range(steps):
        for model, data in models:
            step(model, data)
    wall_s = time.perf_counter() - started
    simulated_s = steps * timestep_s
    return {"simulated_s": simulated_s, "real_time_factor": simulated_s / wall_s, "ending": ""}


def bench_speed(
    config: Config,
    experiment: Experiment,
    controller: ControllerKind,
    ticks: int,
    rounds: int = DEFAULT_ROUNDS,
    say: Callable[[str], None] = lambda _text: None,
) -> dict[str, Any]:
    """The real-time factors of `PATHS`, `rounds` times in turn; medians and ratios."""
    factors: dict[str, list[float]] = {path: [] for path in PATHS}
    endings: dict[str, str] = {}
    failures: list[str] = []
    host_cpu_s: list[float] = []
    with tempfile.TemporaryDirectory(prefix="hil-bench-speed-") as tmp:
        for round_index in range(rounds):
            out = Path(tmp) / f"round{round_index}"
            runs: dict[str, Callable[[], dict[str, Any]]] = {
                "buses": partial(
                    run_through_buses, config, experiment, controller, ticks, out / "b"
                ),
                "in_process": partial(
                    run_in_process, config, experiment, controller, ticks, out / "p"
                ),
                "mujoco_alone": partial(run_mujoco_alone, config, experiment, ticks),
                "buses_bus_alone": partial(run_bus_alone_through_buses, config, experiment, ticks),
                "in_process_bus_alone": partial(
                    run_bus_alone_in_process, config, experiment, ticks
                ),
            }
            for path, run in runs.items():
                say(f"bench speed: round {round_index + 1} of {rounds}, {path} ...")
                record, failed = with_retries(path, run, say)
                failures += failed
                factors[path].append(record["real_time_factor"])
                endings[path] = record["ending"]
                if path == "buses_bus_alone":
                    host_cpu_s.append(record["host_cpu_s_per_tick"])
    median = {path: statistics.median(values) for path, values in factors.items()}
    host_cpu_median_s = statistics.median(host_cpu_s)
    return {
        "experiment": experiment.name,
        "controller": str(controller),
        "ticks": ticks,
        "rounds": rounds,
        "real_time_factor": median,
        "real_time_factor_all": factors,
        "of_mujoco_alone": {
            path: median[path] / median["mujoco_alone"] for path in ("buses", "in_process")
        },
        "buses_over_in_process": median["buses"] / median["in_process"],
        "bus_alone": {
            "host_cpu_s_per_tick": host_cpu_median_s,
            "host_cpu_s_per_tick_all": host_cpu_s,
            "host_bound": config.loop.period_s / host_cpu_median_s,
        },
        "endings": endings,
        "failed_starts": failures,
    }


def speed_text(speed: dict[str, Any]) -> list[str]:
    factor, of_limit = speed["real_time_factor"], speed["of_mujoco_alone"]
    alone = speed["bus_alone"]
    lines = [
        f"real-time factor of a lock-step {speed['experiment']} run with {speed['controller']}, "
        f"{speed['ticks']} ticks, median of {speed['rounds']} rounds taken in turn:",
        f"  through the emulated buses {factor['buses']:8.2f} x  "
        f"({of_limit['buses']:.3f} of MuJoCo alone)",
        f"  in process                 {factor['in_process']:8.2f} x  "
        f"({of_limit['in_process']:.3f} of MuJoCo alone)",
        f"  MuJoCo alone (the physics) {factor['mujoco_alone']:8.2f} x",
        f"  through the buses / in process: {speed['buses_over_in_process']:.2f}",
        "the bus alone (each tick a read and a write of the held goal; no controller, "
        "supervisor or log):",
        f"  through the emulated buses {factor['buses_bus_alone']:8.2f} x  "
        f"(the host's own CPU {1e3 * alone['host_cpu_s_per_tick']:.3f} ms a tick: "
        f"{alone['host_bound']:.2f} x at most, were the emulator and the loop free)",
        f"  in process                 {factor['in_process_bus_alone']:8.2f} x  "
        "(the emulated robot and its in-process bus)",
    ]
    for path, ending in speed["endings"].items():
        if ending and ending != "completed":
            lines.append(f"  note: the {path.replace('_', ' ')} run ended: {ending}")
    return lines
