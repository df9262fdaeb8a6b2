"""Emulators forked from one interpreter that imported sim_backend once.

    server = ForkServer()                      # one per host process: `fork_server()`
    emulator = server.start(spec_path, stdout_fd, stderr_fd)
    emulator.pid, emulator.running(), emulator.terminate(), emulator.wait(5.0)

A run's emulator used to be a fresh interpreter (`python -P -m sim_backend --spec-file F`),
which spends 0.22 s of CPU importing sim_backend, numpy, MuJoCo and python-can before its first
byte, 0.47 s where Python may not write bytecode (measured on the project's 2-core machine,
December 2026) - on every run of a comparison, a sweep and the tests. The fork server
(`python -P -m sim_backend --fork-server FD`) imports them once per host process and forks each
emulator from that state in a few milliseconds. It forks from itself, not from the host: the
host may hold threads (a fork copies only the calling one, with whatever locks the others
held) and open files (a log writer's pipe, another run's ports); the server holds neither.

A forked emulator is what `python -P -m sim_backend --spec-file F` is: `serve_spec_file(F)` in
its own session (a terminal's Ctrl-C is for the host, which stops its emulators), stdout and
stderr where the host said, the same exit status. It is killed when the server ends (SIGKILL:
a stopped emulator would keep a SIGTERM pending for ever), and the server ends when its host
does: when the host's end of the control socket closes, or within PARENT_CHECK_S of the host's
end even while a fork of the host still holds a copy of that end (a helper process that a
SIGSTOP or a hung disk keeps from ending); it ignores SIGINT and SIGTERM, which are for the
host. So no emulator outlives the process that started it, even one killed without a chance
to stop it.

Linux only, like the ptys the emulator serves on: pidfd_open (Linux 5.3) gives the host a
handle on an emulator that is not its child, prctl(PR_SET_PDEATHSIG) ties the emulator to the
server.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import signal
import socket
import subprocess
import sys
import threading
from typing import NoReturn

from sim_backend.server import serve_spec_file

_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_MAX_REQUEST_BYTES = 4096  # a spec file's path
_SERVER_START_TIMEOUT_S = 60.0  # the server's imports, on a loaded machine
PARENT_CHECK_S = 0.5  # how often an idle server checks that its host is still there


class ForkServerError(RuntimeError):
    """The fork server could not start an emulator (it is gone, or could not fork)."""


# --- the server's side ---------------------------------------------------------------------
def serve_forks(control_fd: int) -> int:
    """`python -P -m sim_backend --fork-server FD`: fork an emulator for each request that
    comes on the SOCK_SEQPACKET socket `control_fd` (a spec file's path, with the descriptors
    for the emulator's stdout and stderr); answer with its pidfd. Returns when the host closes
    its end."""
    control = socket.socket(fileno=control_fd)
    for ending in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(ending, signal.SIG_IGN)  # the host ends the server, by closing `control`
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # the kernel reaps the emulators: no zombies
    server_pid, host_pid = os.getpid(), os.getppid()
    control.sendall(b"ready")
    while True:
        if not select.select([control], [], [], PARENT_CHECK_S)[0]:
            if os.getppid() != host_pid:  # the host has ended (a fork of it holds `control`)
                return 0
            continue
        try:
            request, fds, _flags, _address = socket.recv_fds(control, _MAX_REQUEST_BYTES, 2)
        except OSError:
            return 0
        if not request:
            return 0
        if len(fds) != 2:
            for fd in fds:
                os.close(fd)
            control.sendall(b"error: a request carries the emulator's stdout and stderr")
            continue
        try:
            pid = os.fork()
        except OSError as exc:
            for fd in fds:
                os.close(fd)
            control.sendall(f"error: fork failed: {exc}".encode())
            continue
        if pid == 0:
            _be_the_emulator(control, server_pid, request.decode(), fds[0], fds[1])
        for fd in fds:
            os.close(fd)
        try:
            pidfd = os.pidfd_open(pid)
        except ProcessLookupError:  # it has ended already (and was reaped)
            control.sendall(f"ended {pid}".encode())
            continue
        try:
            socket.send_fds(control, [f"started {pid}".encode()], [pidfd])
        finally:
            os.close(pidfd)


def _be_the_emulator(
    control: socket.socket, server_pid: int, spec_path: str, stdout_fd: int, stderr_fd: int
) -> NoReturn:
    status = 1
    try:
        control.close()
        os.dup2(stdout_fd, 1)  # first: whatever goes wrong next is on the emulator's stderr
        os.dup2(stderr_fd, 2)
        os.close(stdout_fd)
        os.close(stderr_fd)
        os.setsid()
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGCHLD):
            signal.signal(sig, signal.SIG_DFL)
        _end_with_parent(server_pid)
        status = serve_spec_file(spec_path)
    except BaseException as exc:  # noqa: BLE001 - the reason, as `hil emulate` gives it
        print(f"hil emulate: {type(exc).__name__}: {exc}", file=sys.stderr)
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
        os._exit(status)


def _end_with_parent(server_pid: int) -> None:
    """SIGKILL when the server ends (and so its host); at once if it already has."""
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != server_pid:  # the server ended before the prctl took effect
        os.kill(os.getpid(), signal.SIGKILL)


# --- the host's side -----------------------------------------------------------------------
class ForkedEmulator:
    """An emulator the fork server started: not this process's child, so it is reached through
    its pidfd (signals without a race on the pid, its end as a readable descriptor). Its exit
    status is not known here: what went wrong is on its stderr."""

    def __init__(self, pid: int, pidfd: int | None) -> None:
        self.pid = pid
        self._pidfd = pidfd

    def running(self) -> bool:
        return not self.wait(0.0)

    def wait(self, timeout_s: float) -> bool:
        """True once it has ended (within `timeout_s`)."""
        if self._pidfd is None:
            return True
        readable, _, _ = select.select([self._pidfd], [], [], timeout_s)
        return bool(readable)

    def send_signal(self, sig: int) -> None:
        if self._pidfd is not None:
            with contextlib.suppress(ProcessLookupError):
                signal.pidfd_send_signal(self._pidfd, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def close(self) -> None:
        if self._pidfd is not None:
            os.close(self._pidfd)
            self._pidfd = None


class ForkServer:
    """This process's fork server, started on first use (and again if it has gone)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()  # one request and its answer at a time
        self._process: subprocess.Popen[bytes] | None = None
        self._control: socket.socket | None = None
        self._owner_pid = 0

    def start(self, spec_path: str, stdout_fd: int, stderr_fd: int) -> ForkedEmulator:
        """Fork an emulator serving the spec at `spec_path`; its stdout and stderr go to the
        two descriptors (the caller keeps and closes its own)."""
        with self._lock:
            control = self._ready_control()
            try:
                socket.send_fds(control, [spec_path.encode()], [stdout_fd, stderr_fd])
                answer, fds, _flags, _address = socket.recv_fds(control, _MAX_REQUEST_BYTES, 1)
            except OSError as exc:
                self._forget()
                raise ForkServerError(f"the emulators' fork server is gone: {exc}") from exc
        if not answer:
            self._forget()
            raise ForkServerError("the emulators' fork server ended")
        word, _, detail = answer.decode().partition(" ")
        if word == "started" and len(fds) == 1:
            return ForkedEmulator(int(detail), fds[0])
        for fd in fds:
            os.close(fd)
        if word == "ended":
            return ForkedEmulator(int(detail), None)
        raise ForkServerError(f"the emulators' fork server says: {answer.decode()}")

    def _ready_control(self) -> socket.socket:
        alive = self._process is not None and self._process.poll() is None
        if self._control is not None and alive and self._owner_pid == os.getpid():
            return self._control
        self._forget()
        host_end, server_end = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            self._process = subprocess.Popen(
                # -P: not from the working directory (see hil/wiring/emulation.py)
                [
                    sys.executable,
                    "-P",
                    "-m",
                    "sim_backend",
                    "--fork-server",
                    str(server_end.fileno()),
                ],
                pass_fds=(server_end.fileno(),),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
            )
        finally:
            server_end.close()
        host_end.settimeout(_SERVER_START_TIMEOUT_S)
        try:
            ready = host_end.recv(16)
        except OSError as exc:
            host_end.close()
            raise ForkServerError(f"the emulators' fork server did not start: {exc}") from exc
        if ready != b"ready":
            host_end.close()
            raise ForkServerError("the emulators' fork server ended at start-up (see stderr)")
        host_end.settimeout(None)
        self._control, self._owner_pid = host_end, os.getpid()
        return host_end

    def _forget(self) -> None:
        """Drop the server (gone, or a forked copy's: a forked process starts its own)."""
        if self._control is not None:
            with contextlib.suppress(OSError):
                self._control.close()
        self._control = None
        if self._process is not None and self._owner_pid == os.getpid():
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(timeout=5)  # it ends once its control socket is closed
        self._process = None


_SERVER = ForkServer()


def fork_server() -> ForkServer:
    """This process's fork server."""
    return _SERVER
