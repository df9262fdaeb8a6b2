"""End to end on the emulated testbed: `hil emulate` in its own process, our drivers and
ROBOTIS's SDK on the wire, the loop in lock-step and on the wall clock."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from hil.cli import main
from hil.config import load_config
from hil.robots import get_experiment
from hil.wiring import Connection, make_bus
from hil.wiring.emulation import EmbeddedEmulator, emulator_spec

MOTOR_STEP_RAD = 2 * math.pi / 501_923
LINK_STEP_RAD = 2 * math.pi / 983_040


def _is_quantised(values: np.ndarray, step: float, offset: float = 0.0) -> bool:
    counts = (np.asarray(values) - offset) / step
    return bool(np.all(np.abs(counts - np.round(counts)) < 1e-6))


@pytest.mark.timeout(60)
def test_a_goal_written_through_the_driver_moves_the_emulated_plant() -> None:
    config = load_config()
    spec = emulator_spec(config, experiment=get_experiment("impact"))  # no block in the way
    with EmbeddedEmulator(spec) as emulator:
        connection = Connection.from_endpoints(emulator.endpoints, config)
        bus = make_bus(config, connection, clock=time.monotonic)
        with bus:
            first = bus.read()
            assert first.motor_valid.all() and first.link_valid.all()
            bus.enable()
            goal = first.motor_angle_rad + 0.1
            samples = []
            for _ in range(200):  # 1 s of plant time: one period per SYNC
                bus.write(goal)
                samples.append(bus.read())
            bus.disable()
        last = samples[-1]
    # The motor went most of the way to the goal (the servo is a lag, not a jump) and the link
    # followed through the elastic gear.
    moved = float(last.motor_angle_rad[0] - first.motor_angle_rad[0])
    assert 0.08 < moved < 0.11
    assert abs(float(last.link_angle_rad[0] - first.link_angle_rad[0]) - moved) < 0.01
    # What crossed the wire is quantised at the real sensors' resolutions.
    motor = np.array([s.motor_angle_rad[0] for s in samples])
    link = np.array([s.link_angle_rad[0] for s in samples])
    assert _is_quantised(motor, MOTOR_STEP_RAD)
    assert _is_quantised(link, LINK_STEP_RAD)
    assert len(np.unique(np.diff(motor)[np.diff(motor) != 0].round(12))) > 3  # it really moved


def _run_json(tmp_path: Path, *args: str) -> dict:
    out = tmp_path / "out.txt"
    command = [sys.executable, "-m", "hil", "run", *args, "--out", str(tmp_path), "--json"]
    proc = subprocess.run(command, capture_output=True, text=True, timeout=120)
    out.write_text(proc.stdout)
    assert proc.returncode in (0, 1), proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.timeout(200)
def test_lockstep_runs_with_the_same_seed_write_the_same_log(tmp_path: Path) -> None:
    """Same seed, same bytes; another seed, another log (the noisy encoder's noise is seeded)."""
    logs = []
    for name, seed in (("a", "7"), ("b", "7"), ("c", "8")):
        result = _run_json(
            tmp_path / name,
            "impact",
            "--controller",
            "gc+lqr+dob",
            "--duration",
            "2.5",
            "--no-plots",
            "--inject",
            "noisy_encoder@0.5",
            "--seed",
            seed,
        )
        logs.append((Path(result["out_dir"]) / "log.csv").read_bytes())
    assert logs[0] == logs[1]
    assert logs[0] != logs[2]
    stop_cycles = load_config().loop.stop_cycles
    assert len(logs[0].splitlines()) == 1 + 2.5 / 0.005 + stop_cycles  # header + every tick


@pytest.mark.timeout(120)
def test_run_json_line_carries_the_contact_metrics(tmp_path: Path) -> None:
    result = _run_json(
        tmp_path, "contact", "--controller", "gc+lqr+dob", "--duration", "4", "--no-plots"
    )
    for key in (
        "peak_contact_force_n",
        "mean_contact_force_n",
        "overload_tripped",
        "trip_time_after_contact_s",
    ):
        assert key in result
    assert result["peak_contact_force_n"] > 1.0  # the reference drove the link into the block


@pytest.mark.timeout(60)
def test_robotis_sdk_alone_drives_the_realtime_emulator_as_an_h54() -> None:
    """A script that knows only the H54 control table: ping, configure, drive, read back."""
    emulator = subprocess.Popen(
        [sys.executable, "-m", "hil", "emulate", "--realtime"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        endpoints = json.loads(emulator.stdout.readline())
        port = PortHandler(endpoints["dynamixel_port"])
        assert port.openPort() and port.setBaudRate(endpoints["baudrate"])
        packet = PacketHandler(2.0)
        model, comm, error = packet.ping(port, 1)
        assert (model, comm, error) == (54024, COMM_SUCCESS, 0)
        for address, size, value in ((11, 1, 3), (9, 1, 0)):  # position mode, no return delay
            comm, error = packet.writeTxRx(
                port, 1, address, size, list(value.to_bytes(size, "little"))
            )
            assert (comm, error) == (COMM_SUCCESS, 0)
        present, comm, _ = packet.read4ByteTxRx(port, 1, 611)
        start = present - (1 << 32) if present >= 1 << 31 else present
        goal = start + 20_000  # 0.25 rad
        assert packet.write4ByteTxRx(port, 1, 596, goal)[0] == COMM_SUCCESS
        assert packet.write1ByteTxRx(port, 1, 562, 1) == (COMM_SUCCESS, 0)
        time.sleep(1.0)  # the plant runs on the wall clock
        present, comm, error = packet.read4ByteTxRx(port, 1, 611)
        assert comm == COMM_SUCCESS and error == 0
        present = present - (1 << 32) if present >= 1 << 31 else present
        assert abs(present - goal) < 2_000  # within 0.025 rad of the goal after 1 s
        packet.write1ByteTxRx(port, 1, 562, 0)
        port.closePort()
    finally:
        emulator.terminate()
        emulator.wait(timeout=10)


def test_hil_run_refuses_bad_arguments_with_exit_status_2(capsys) -> None:
    assert main(["run", "impact", "--kdist", "-1"]) == 2
    assert "kdist" in capsys.readouterr().err
    assert main(["run", "impact", "--inject", "meteor@1"]) == 2
    assert "unknown fault" in capsys.readouterr().err


@pytest.mark.timeout(60)
def test_a_canopen_master_in_another_process_reaches_the_emulated_encoder() -> None:
    """`hil emulate` (lock-step): its JSON line is all a CANopen master needs."""
    import can
    import canopen

    from sim_backend.canbus.encoder_node import ENCODER_EDS_FILE  # the EDS, for the master
    from sim_backend.canbus.object_store import eds_path

    emulator = subprocess.Popen(
        [sys.executable, "-m", "hil", "emulate"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        endpoints = json.loads(emulator.stdout.readline())
        network = canopen.Network(can.Bus(**endpoints["can"]))
        network.connect()
        try:
            node_id = endpoints["encoder_node_ids"][0]
            remote = network.add_node(node_id, str(eds_path(ENCODER_EDS_FILE)))
            remote.nmt.send_command(0x82)  # reset communication
            remote.nmt.wait_for_heartbeat(timeout=2.0)
            assert remote.sdo[0x1000].raw & 0xFFFF == 0x0196  # CiA 406 encoder
            assert remote.sdo[0x6001].raw == 983_040
            remote.tpdo.read(from_od=True)
            remote.nmt.state = "OPERATIONAL"
            assert remote.nmt.wait_for_heartbeat(timeout=2.0) == "OPERATIONAL"
            network.sync.transmit()
            remote.tpdo[1].wait_for_reception(timeout=2.0)
            counts = remote.tpdo[1]["Position value"].raw
            # The first SYNC samples the plant at t = 0, in static balance at its initial link
            # angle (the motor stands ahead by the gravity sag m g r / K, the link does not
            # move): the count is that angle as the encoder is mounted, within a few counts.
            spec = emulator_spec(load_config())
            mounting = spec.joints[0]
            angle_rad = spec.plant.initial_link_angle_rad
            expected = round(
                (mounting.encoder_direction * angle_rad + mounting.encoder_offset_rad)
                * 983_040
                / (2 * math.pi)
            )
            assert abs(counts - expected) <= 3
        finally:
            network.disconnect()
    finally:
        emulator.terminate()
        emulator.wait(timeout=10)
