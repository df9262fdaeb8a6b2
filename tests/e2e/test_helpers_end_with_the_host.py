"""Nothing outlives a killed host (issue 25): SIGKILL of a wall-clock humanoid run while its
gain designer was stopped left the designer stopped (ppid 1) holding the fork server's control
socket, so the fork server and the emulator ran on. Now the designer dies with the host
(PR_SET_PDEATHSIG: SIGKILL) and holds none of its descriptors, and the fork server ends when
its host does even while a fork of the host holds its socket."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from hil.loop.gain_scheduler import DESIGNER_PROCESS_NAME

pytestmark = [
    pytest.mark.faults,
    pytest.mark.timeout(180),
    pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux's /proc"),
]

REPO = Path(__file__).resolve().parents[2]


def _stat(pid: int) -> list[str] | None:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _alive(pid: int) -> bool:
    fields = _stat(pid)
    return fields is not None and fields[0] not in ("Z", "X")


def _descendants(root: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and (fields := _stat(int(entry.name))) is not None:
            children.setdefault(int(fields[1]), []).append(int(entry.name))
    found, todo = [], [root]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def _comm(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def _wait_for(what, timeout_s: float, process: subprocess.Popen):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert process.poll() is None, "the host ended on its own"
        if found := what():
            return found
        time.sleep(0.05)
    raise AssertionError(f"not there within {timeout_s} s")


def _gone_within(pids: list[int], timeout_s: float) -> list[int]:
    deadline = time.monotonic() + timeout_s
    while (left := [p for p in pids if _alive(p)]) and time.monotonic() < deadline:
        time.sleep(0.05)
    return left


def _kill_all(pids: list[int]) -> None:
    for pid in pids:
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)


def test_a_killed_wall_clock_humanoid_run_leaves_no_process(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "hil", "run", "stand", "--robot", "dyros-jet"]
    command += ["--controller", "gc+lqr", "--realtime", "--duration", "60", "--no-plots"]
    host = subprocess.Popen(
        [*command, "--out", str(tmp_path)],
        cwd=REPO,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    everything: list[int] = []
    try:
        name = DESIGNER_PROCESS_NAME.decode()
        (designer,) = _wait_for(
            lambda: [p for p in _descendants(host.pid) if _comm(p) == name], 120.0, host
        )
        os.kill(designer, signal.SIGSTOP)  # as the scheduler does during a tick, or a hung host
        everything = _descendants(host.pid)  # the designer, the log writer, the fork server,
        assert len(everything) >= 4  # and the emulator
        host.send_signal(signal.SIGKILL)  # no exit path runs
        host.wait(10)
        left = _gone_within(everything, 10.0)
        assert not left, [(pid, _comm(pid), (_stat(pid) or ["?"])[0]) for pid in left]
    finally:
        if host.poll() is None:
            host.kill()
            host.wait()
        _kill_all(everything)


def test_the_fork_server_ends_with_its_host_while_a_fork_of_the_host_holds_its_socket() -> None:
    """Any helper forked from the host (the log writer, a user's fork) holds a copy of the
    control socket; one that a SIGSTOP or a hung disk keeps from ending kept the server and
    every emulator alive."""
    script = textwrap.dedent(
        """
        import os, signal, sys, time
        from hil.wiring.emulation import EmbeddedEmulator
        from sim_backend.spec import EmulatedJointSpec, EmulatorSpec
        emulator = EmbeddedEmulator(
            EmulatorSpec(joints=(EmulatedJointSpec(dxl_id=1, encoder_node_id=5),))
        )
        emulator.start()
        helper = os.fork()
        if helper == 0:
            os.kill(os.getpid(), signal.SIGSTOP)
            os._exit(0)
        print(emulator.process.pid, helper, flush=True)
        time.sleep(600)
        """
    )
    host = subprocess.Popen(
        [sys.executable, "-c", script], cwd=REPO, stdout=subprocess.PIPE, text=True
    )
    pids: list[int] = []
    try:
        assert host.stdout is not None
        emulator, helper = (int(word) for word in host.stdout.readline().split())
        server = int((_stat(emulator) or ["", "0"])[1])
        pids = [emulator, server, helper]
        assert all(_alive(pid) for pid in pids)
        host.send_signal(signal.SIGKILL)
        host.wait(10)
        assert not _gone_within([emulator, server], 5.0), "the emulator outlived its host"
    finally:
        if host.poll() is None:
            host.kill()
            host.wait()
        _kill_all(pids)
