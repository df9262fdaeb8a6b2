"""What another process of this run is doing now, from Linux's /proc: `ProcessActivity`.

A lock-step run waits for processes of its own - the emulator behind its buses, the LQR's gain
designer - and must tell a slow one (a loaded machine: runnable, waiting for a CPU) from one
that will not answer (stopped, ended, asleep with nothing to do). One look reads

    /proc/PID/stat       its state: R running or runnable; S asleep; D in uninterruptible I/O;
                         T stopped (SIGSTOP, Ctrl-Z); t stopped by a debugger; Z ended
    /proc/PID/schedstat  the CPU time it has used [ns] (stat's is in 10 ms clock ticks)

which is what drivers/peer_wait.py's `PeerActivity` asks for. Where there is no /proc (not
Linux) or the process has ended, a look says None: a wait then ends at its allowance.
"""

from __future__ import annotations

from pathlib import Path

from drivers.peer_wait import PeerLook

PROC = Path("/proc")
_STATES = {
    "R": "running",
    "S": "asleep",
    "I": "idle",
    "D": "in uninterruptible I/O",
    "T": "stopped (SIGSTOP or Ctrl-Z)",
    "t": "stopped by a debugger",
    "Z": "ended (not yet reaped)",
    "X": "ended",
}


def _fields(stat_line: str) -> list[str]:
    """The fields of a /proc/PID/stat line after the command name (which may hold spaces
    and parentheses): [0] is the state, [19] the start time."""
    return stat_line.rsplit(")", 1)[1].split()


def describe_state(letter: str) -> str:
    return _STATES.get(letter, f"in state {letter!r}")


def proc_available() -> bool:
    """Whether processes can be looked at here (Linux's /proc with scheduler statistics)."""
    return (PROC / "self" / "schedstat").is_file()


class ProcessActivity:
    """Looks at process `pid` (see the module docstring). The process is known by its pid and
    its start time, read now: a pid that another process took after this one ended is never
    looked at (it has another start time)."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self._stat = PROC / str(pid) / "stat"
        self._schedstat = PROC / str(pid) / "schedstat"
        self._started = self._start_time()

    def look(self) -> PeerLook | None:
        try:
            fields = _fields(self._stat.read_text())
            cpu_ns = int(self._schedstat.read_text().split()[0])
        except (OSError, ValueError, IndexError):  # gone, or no /proc
            return None
        state = fields[0]
        if state in ("Z", "X") or self._started is None or fields[19] != self._started:
            return None
        # in uninterruptible I/O (D: a page it faults in, a write the disk holds up) a process
        # is working as surely as a runnable one, only not on a CPU: on a machine whose disk
        # others load, an emulator paging its code back in lost a whole sync read (all twelve
        # joints invalid for a tick of a lock-step walk) to a 10 ms idle window
        working = state in ("R", "D")
        return PeerLook(runnable=working, cpu_s=cpu_ns * 1e-9, state=describe_state(state))

    def _start_time(self) -> str | None:
        try:
            return _fields(self._stat.read_text())[19]
        except (OSError, IndexError):
            return None
