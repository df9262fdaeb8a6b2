"""A loaded machine must not fail a healthy lock-step run (issue 25): with 10 runs on 2 cores,
2 of 10 ended `bus failure ... no answer to PING` at bus open, and a run failed at tick 0 (and
its exit path's single torque-off try), all on healthy emulators. Now the lock-step bus waits
for its emulator while that process works, however long, and not for one that is asleep or
stopped: the run is what it is alone, byte for byte.

The load is made deterministic: the emulator here is `hil emulate`'s own server with some of
its answers made slow - at bus open (the first PING), on tick 0 and every few transactions and
SYNCs after - by a busy loop (the process runs, as a loaded machine's emulator waits for a CPU:
runnable) or by a sleep (the process is idle: nothing will come)."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from hil.config import load_config
from hil.loop import LockstepClock, RunRequest, run_experiment
from hil.robots import get_experiment
from hil.vocabulary import ControllerChoice
from hil.wiring import Connection, make_bus
from hil.wiring.emulation import emulator_spec
from tests.support.rig import assert_log_complete, emulated_testbed, load_run, run_on

pytestmark = [
    pytest.mark.timeout(240),
    pytest.mark.skipif(not Path("/proc/self/schedstat").exists(), reason="needs Linux's /proc"),
]

CONFIG = load_config()
CONTACT = get_experiment("contact")
DURATION_S = 1.0
SLOW_S = 0.25  # > the lock-step allowance of a reply (2 x 50 ms + 2 ms) and its idle window
EVERY = 40  # the 1st, 41st, ... transaction and SYNC are slow

_SLOW_EMULATOR = textwrap.dedent(
    """
    import os, pickle, sys, time
    from sim_backend import server
    from sim_backend.dynamixel.line import DynamixelLine

    spec, slow_s, every, how = pickle.loads(bytes.fromhex(sys.argv[1]))

    def slow():
        if how == "busy":  # runnable all along, as an emulator waiting for a CPU
            end = time.perf_counter() + slow_s
            while time.perf_counter() < end:
                pass
        else:
            time.sleep(slow_s)

    def slowed(method):
        calls = [0]
        def call(self, *args):
            calls[0] += 1
            if calls[0] % every == 1:
                slow()
            return method(self, *args)
        return call

    DynamixelLine.on_readable = slowed(DynamixelLine.on_readable)
    server.Emulator._on_sync = slowed(server.Emulator._on_sync)
    server.serve(spec, extra={"pid": os.getpid()})
    """
)


def _run_on_slow_emulator(out_dir: Path, how: str):
    spec = emulator_spec(CONFIG, experiment=CONTACT)
    argument = pickle.dumps((spec, SLOW_S, EVERY, how)).hex()
    emulator = subprocess.Popen(
        [sys.executable, "-c", _SLOW_EMULATOR, argument],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert emulator.stdout is not None
        endpoints = json.loads(emulator.stdout.readline())
        connection = Connection.from_endpoints(endpoints, CONFIG)
        assert connection.lockstep and connection.emulator_pid == emulator.pid
        clock = LockstepClock(CONFIG.loop.period_s)
        bus = make_bus(CONFIG, connection, clock=clock.now)
        request = RunRequest(
            CONTACT, ControllerChoice("gc+lqr+dob", 1.0), out_dir, duration_s=DURATION_S
        )
        result = run_experiment(CONFIG, request, bus, clock, {"test": True})
        return result, load_run(out_dir)
    finally:
        emulator.terminate()
        try:
            emulator.wait(10)
        except subprocess.TimeoutExpired:
            emulator.kill()
            emulator.wait()


@pytest.mark.faults
def test_a_lockstep_run_on_a_slow_emulator_is_the_run_alone(tmp_path: Path) -> None:
    with emulated_testbed(CONFIG, CONTACT) as alone:
        _, reference = run_on(
            alone, CONFIG, CONTACT, "gc+lqr+dob", tmp_path / "alone", duration_s=DURATION_S
        )
    result, run = _run_on_slow_emulator(tmp_path / "slow", "busy")
    assert run.termination == "completed", run.termination
    assert run.summary["exit"] == reference.summary["exit"] == ["torque off"]
    assert_log_complete(run)
    assert (run.dir / "log.csv").read_bytes() == (reference.dir / "log.csv").read_bytes()
    # it did wait: the first PING and the SYNCs of ticks 0, 40, 80, 120 and 160 were slow
    assert result.wall_time_s > 6 * SLOW_S


@pytest.mark.faults
def test_an_emulator_that_does_not_work_on_an_answer_is_not_waited_for(tmp_path: Path) -> None:
    """The same slowness as a sleep: the emulator is idle (as a stopped, dead or silent one
    is), so the wait ends at its allowance plus the idle window, as before."""
    _, run = _run_on_slow_emulator(tmp_path, "asleep")
    assert run.termination.startswith("bus failure"), run.termination
    assert "no answer to PING" in run.termination
    assert run.summary["exit"] == ["bus never opened: nothing was sent"]


def test_on_hardware_and_on_the_wall_clock_the_bus_does_not_wait_on() -> None:
    hardware = Connection.from_config(CONFIG, require_ports=False)
    assert make_bus(CONFIG, hardware).peer is None
    endpoints = {
        "dynamixel_port": "/dev/pts/0",
        "baudrate": 3_000_000,
        "can": {"interface": "slcan", "channel": "/dev/pts/1"},
        "pid": 1,
    }
    wall = Connection.from_endpoints({**endpoints, "clock": "realtime"}, CONFIG)
    assert make_bus(CONFIG, wall).peer is None
    lockstep = Connection.from_endpoints({**endpoints, "clock": "lockstep"}, CONFIG)
    assert make_bus(CONFIG, lockstep).peer is not None
