"""Exit paths through the real buses: the emulated actuator is left in the configured torque
state (read back over the bus with ROBOTIS's SDK after the run) and a complete log is on disk -
the normal end, Ctrl-C and SIGTERM to a `hil run` process, the emulator process killed
mid-run, a permanently silent actuator's cost per tick. The other exit paths (on_exit = hold, an
exception in the controller, torque off reaching an actuator that answers again) run on the
in-process bus: tests/hil/test_loop_exits.py."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import hil.loop.runner
import hil.loop.torque
from hil.config import load_config
from hil.loop import LockstepClock, RunRequest, run_experiment
from hil.robots import get_experiment
from hil.vocabulary import ControllerChoice
from hil.wiring import Connection, make_bus
from sim_backend.scenario import parse_fault
from tests.support.rig import (
    PERIOD_S,
    DeviceUnreachable,
    assert_log_complete,
    emulated_testbed,
    load_run,
    read_device,
    run_on,
)


@pytest.mark.timeout(60)
def test_normal_end_leaves_torque_off(tmp_path: Path) -> None:
    config = load_config()
    with emulated_testbed(config, "impact") as emulator:
        result, run = run_on(emulator, config, "impact", "gc+lqr+dob", tmp_path, duration_s=1.5)
        device = read_device(emulator.endpoints)
    assert result.ok
    assert_log_complete(run)
    assert run.summary["exit"][0] == "torque off"
    assert device.torque_enabled == 0 and device.hardware_error == 0


@pytest.mark.timeout(60)
def test_a_lost_bus_ends_the_run_with_a_complete_log_and_says_torque_could_not_be_set(
    tmp_path: Path,
) -> None:
    """The emulator process dies mid-run (as a USB adapter unplugged): the loop ends with a
    bus failure, no traceback, summary and log written; the exit path tries torque off and
    reports that it could not."""
    config = load_config()
    with emulated_testbed(config, "contact") as emulator:

        def unplug(time_s: float, _total_s: float) -> None:
            if time_s >= 1.0:
                os.kill(emulator.process.pid, signal.SIGKILL)

        request_started = time.perf_counter()
        clock = LockstepClock(PERIOD_S)
        connection = Connection.from_endpoints(emulator.endpoints, config)
        bus = make_bus(config, connection, clock=clock.now)
        request = RunRequest(
            get_experiment("contact"),
            ControllerChoice("gc+lqr+dob", 1.0),
            tmp_path,
            duration_s=3.0,
            on_progress=unplug,
        )
        result = run_experiment(config, request, bus, clock, {})
        elapsed = time.perf_counter() - request_started
    assert result.ending.text.startswith("bus failure")
    run = load_run(tmp_path)
    assert_log_complete(run)
    assert run.summary["ticks"] == round(1.0 / PERIOD_S) + 1
    assert run.events_of("bus_failure")
    assert "torque off FAILED" in run.summary["exit"][0]
    assert elapsed < 10.0


@pytest.mark.timeout(60)
def test_a_permanently_silent_actuator_costs_one_read_timeout_per_tick_not_more(
    tmp_path: Path,
) -> None:
    """After the bus_error stop the loop keeps reading (the log goes on), but tries torque off
    only every DISABLE_RETRY_TICKS ticks: each tick costs one sync-read timeout, and the exit
    path reports honestly that the device could not be reached (it holds its last goal)."""
    config = load_config()
    fault = parse_fault("silent_id@1.0")
    with emulated_testbed(config, "contact", faults=(fault,)) as emulator:
        _, run = run_on(emulator, config, "contact", "pid", tmp_path, duration_s=1.1)
        with pytest.raises(DeviceUnreachable):
            read_device(emulator.endpoints)
    assert run.termination == "safety stop: bus_error (torque_off)"
    assert "torque off FAILED" in run.summary["exit"][0]
    assert_log_complete(run)
    failures = run.events_of("torque_off_failed")
    assert len(failures) == 2  # the first try in the loop (retries are quiet) + the exit
    with open(run.dir / "timing.csv") as f:
        cycles = np.array([float(r["cycle_s"]) for r in csv.DictReader(f)])
    silent = cycles[round(1.0 / PERIOD_S) :]
    # the driver's sync-read timeout in lock-step: 2 x 50 ms latency + 2 ms margin (+ wire)
    read_timeout_s = 0.102
    assert np.median(silent) < 1.3 * read_timeout_s
    # one torque-off try (write + timeout) per DISABLE_RETRY_TICKS, not one per tick
    tries = 1 + (len(silent) - 3) // hil.loop.torque.DISABLE_RETRY_TICKS
    assert silent.sum() < (len(silent) + tries) * 1.3 * read_timeout_s


def _wait_for_rows(log: Path, rows: int, process: subprocess.Popen, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read() if process.stderr else ""
        if log.is_file() and log.read_text().count("\n") > rows:
            return
        time.sleep(0.05)
    raise AssertionError(f"{log} did not reach {rows} rows in {timeout_s} s")


@pytest.mark.timeout(90)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_in_the_middle_of_a_run_leaves_torque_off_and_the_log_complete(
    tmp_path: Path, signum: signal.Signals
) -> None:
    """`hil run --attach` to a running `hil emulate`, interrupted after ~1 s of 30."""
    config = load_config()
    with emulated_testbed(config, "contact") as emulator:
        out = tmp_path / "runs"
        command = [
            sys.executable,
            "-m",
            "hil",
            "run",
            "contact",
            "--controller",
            "gc+lqr+dob",
            "--duration",
            "30",
            "--no-plots",
            "--attach",
            json.dumps(emulator.endpoints),
            "--out",
            str(out),
        ]
        process, run_dir, _, stderr = _attached_run(
            command, out, 200, lambda p: p.send_signal(signum)
        )
        device = read_device(emulator.endpoints)
    assert process.returncode == 1, stderr
    run = load_run(run_dir)
    assert run.termination == f"interrupted: {signum.name}"
    assert_log_complete(run)
    assert 200 <= run.summary["ticks"] < 30 / PERIOD_S
    assert run.summary["exit"][0] == "torque off"
    assert run.events_of("torque_off")[-1]["message"] == "exit: torque off"
    assert device.torque_enabled == 0


def _attached_run(
    command: list[str], out: Path, rows: int, act: Callable[[subprocess.Popen], object]
) -> tuple[subprocess.Popen, Path, str, str]:
    """Start `hil run` (`command`), wait for `rows` log rows, `act` on it (a signal, the
    emulator killed), wait for its end: (process, run directory, stdout, stderr)."""
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_until_a_run_dir(out, process)
        (run_dir,) = out.iterdir()
        _wait_for_rows(run_dir / "log.csv", rows, process, timeout_s=30)
        act(process)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    return process, run_dir, stdout, stderr


def _wait_until_a_run_dir(out: Path, process: subprocess.Popen) -> None:
    deadline = time.monotonic() + 30
    while not (out.is_dir() and any(out.iterdir())):
        assert process.poll() is None, process.stderr.read() if process.stderr else ""
        assert time.monotonic() < deadline, "hil run did not start"
        time.sleep(0.05)


@pytest.mark.timeout(120)
def test_torque_that_could_not_be_turned_off_is_said_loudly_and_has_its_own_exit_status(
    tmp_path: Path,
) -> None:
    """`hil run --attach ... --json` while its `hil emulate` is killed (the bus is lost: torque
    cannot be turned off): stderr says so loudly, the --json line carries it, and the exit
    status is its own (README, exit-status table), not the 1 of an ordinary failed run."""
    from hil.cli.exit_codes import ExitCode
    from hil.output.strict_json import strict_loads

    config = load_config()
    with emulated_testbed(config, "impact") as emulator:
        out = tmp_path / "runs"
        command = [
            sys.executable, "-m", "hil", "run", "impact", "--controller", "gc+lqr+dob",
            "--duration", "60", "--json", "--no-plots", "--attach",
            json.dumps(emulator.endpoints), "--out", str(out),
        ]  # fmt: skip
        process, run_dir, stdout, stderr = _attached_run(
            command, out, 100, lambda _p: emulator.process.kill()
        )
    assert process.returncode == ExitCode.TORQUE_NOT_OFF == 3, stderr
    assert "TORQUE COULD NOT BE TURNED OFF" in stderr
    line = strict_loads(stdout.strip().splitlines()[-1])
    assert line["torque_off_failed"] is True
    assert any("torque off FAILED" in note for note in line["exit"])
    assert load_run(run_dir).summary["exit"] == line["exit"]
