"""The lock-step bus's patience (drivers/peer_wait.py), on a scripted process and clock: a wait
past its allowance goes on while the process is runnable or uses the CPU, and ends after an
idle window when it is asleep or stopped, at once when it is gone."""

from __future__ import annotations

from drivers.peer_wait import BUSY_CPU_SHARE, IDLE_WINDOW_S, LOOK_INTERVAL_S, PeerLook, PeerWait


class _Scripted:
    """A process whose looks are given in advance, on a clock that each look advances."""

    def __init__(self, looks: list[PeerLook | None]) -> None:
        self.looks = looks
        self.now = 0.0

    def look(self) -> PeerLook | None:
        self.now += LOOK_INTERVAL_S
        return self.looks.pop(0)


def _wait(looks: list[PeerLook | None], **kwargs) -> tuple[int, PeerWait]:
    """How many extensions the wait gave before it ended."""
    process = _Scripted(looks)
    wait = PeerWait(process, clock=lambda: process.now, **kwargs)
    extensions = 0
    while wait.extension_s() > 0.0:
        extensions += 1
    return extensions, wait


RUNNABLE = PeerLook(runnable=True, cpu_s=0.0, state="running")
STOPPED = PeerLook(runnable=False, cpu_s=0.0, state="stopped (SIGSTOP or Ctrl-Z)")
IDLE_LOOKS = round(IDLE_WINDOW_S / LOOK_INTERVAL_S)


def test_a_runnable_process_is_waited_for_and_a_stopped_one_for_an_idle_window() -> None:
    extensions, wait = _wait([RUNNABLE] * 100 + [STOPPED] * 100)
    # the idle window counts from the last look that saw it work
    assert extensions == 100 + IDLE_LOOKS - 1
    assert wait.last_look == STOPPED


def test_a_gone_process_ends_the_wait_at_once() -> None:
    assert _wait([None])[0] == 0
    assert _wait([RUNNABLE, RUNNABLE, None])[0] == 2


def test_a_process_asleep_at_each_look_but_using_the_cpu_between_them_works() -> None:
    step = LOOK_INTERVAL_S * (BUSY_CPU_SHARE + 0.1)  # CPU used per look interval
    busy = [PeerLook(False, i * step, "asleep") for i in range(50)]
    light = LOOK_INTERVAL_S * BUSY_CPU_SHARE / 10  # an idle emulator's heartbeats
    idle = [PeerLook(False, 50 * step + i * light, "asleep") for i in range(50)]
    extensions, _ = _wait(busy + idle)
    assert extensions == 50 + IDLE_LOOKS  # (its first idle look still shows the last work)


def test_a_process_that_works_for_ever_without_answering_is_given_up() -> None:
    extensions, wait = _wait([RUNNABLE] * 1000, max_extension_s=100 * LOOK_INTERVAL_S)
    assert extensions == 100
    assert wait.extension_s() == 0.0  # and stays given up until the next wait begins
    wait.activity.looks = [RUNNABLE, None]  # type: ignore[attr-defined]
    wait.begin()
    assert wait.extension_s() > 0.0
