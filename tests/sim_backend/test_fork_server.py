"""Emulators forked from the fork server (sim_backend/fork_server.py): what a host sees of them.

The lock-step logs of emulators so started are the bytes the fresh-interpreter emulators gave
(checked on three runs when it was built); every end-to-end test runs through it.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import hil.wiring.emulation as emulation
from hil.wiring.emulation import EmbeddedEmulator, EmulatorStartError
from sim_backend.spec import EmulatedJointSpec, EmulatorSpec

pytestmark = pytest.mark.timeout(120)

SPEC = EmulatorSpec(joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),))
REPO = Path(__file__).resolve().parents[2]


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _gone_within(pids: list[int], timeout_s: float) -> list[int]:
    deadline = time.monotonic() + timeout_s
    while (left := [p for p in pids if _alive(p)]) and time.monotonic() < deadline:
        time.sleep(0.05)
    return left


def test_no_emulator_outlives_a_host_killed_without_a_chance_to_stop_it() -> None:
    host = textwrap.dedent(
        """
        import sys, time
        from hil.wiring.emulation import EmbeddedEmulator
        from sim_backend.spec import EmulatedJointSpec, EmulatorSpec
        emulator = EmbeddedEmulator(
            EmulatorSpec(joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),))
        )
        emulator.start()
        print(emulator.process.pid, flush=True)
        time.sleep(600)
        """
    )
    process = subprocess.Popen(
        [sys.executable, "-c", host], cwd=REPO, stdout=subprocess.PIPE, text=True
    )
    try:
        assert process.stdout is not None
        emulator_pid = int(process.stdout.readline())
        assert _alive(emulator_pid)
        process.send_signal(signal.SIGKILL)  # no exit path runs: nothing stops the emulator
        process.wait(10)
        assert not _gone_within([emulator_pid], 10.0), "the emulator outlived its host"
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_an_emulator_that_fails_at_start_up_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(emulation, "spec_to_json", lambda _spec: "{not a spec")
    with pytest.raises(EmulatorStartError, match="exited at start-up:\nhil emulate: JSONDecode"):
        EmbeddedEmulator(SPEC).start()


def _parent_pid(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def _server_of(emulator: EmbeddedEmulator) -> int:
    assert emulator.process is not None
    return _parent_pid(emulator.process.pid)


def _start_and_stop_one(answers: multiprocessing.Queue) -> None:
    with EmbeddedEmulator(SPEC) as emulator:
        answers.put((emulator.endpoints["ids"], _server_of(emulator)))


def test_a_forked_copy_of_a_host_starts_its_emulators_from_a_server_of_its_own() -> None:
    """A fork of a host that has a server (the gain designer, the log writer are forks) holds
    a copy of its control socket: requests through it would interleave with the host's."""
    with EmbeddedEmulator(SPEC) as first:
        assert first.endpoints["ids"] == [1]
        hosts_server = _server_of(first)
        answers: multiprocessing.Queue = multiprocessing.get_context("fork").Queue()
        child = multiprocessing.get_context("fork").Process(
            target=_start_and_stop_one, args=(answers,)
        )
        child.start()
        ids, childs_server = answers.get(timeout=60)
        child.join(30)
        assert child.exitcode == 0
        assert ids == [1]
        assert childs_server not in (hosts_server, os.getpid())
    with EmbeddedEmulator(SPEC) as again:  # and the host's own server still answers
        assert again.endpoints["ids"] == [1] and _server_of(again) == hosts_server


def test_a_stopped_emulator_is_gone_and_leaves_its_fault_counts() -> None:
    emulator = EmbeddedEmulator(SPEC)
    emulator.start()
    assert emulator.process is not None
    pid = emulator.process.pid
    emulator.stop()
    assert not _alive(pid)
    assert "dynamixel" in emulator.fault_counts  # its last line, read to the end
    assert os.getpid() != pid
