"""The actuators' torque, as the loop keeps it: on at the start, off when the supervisor latches
torque_off (tried again until the bus takes it), and the configured exit state at the end.

When the supervisor latches torque_off, the loop turns torque off at once; if the bus does not
take it (a silent device), it tries again every DISABLE_RETRY_TICKS ticks, not every tick (each
try costs the driver's timeouts), and on the tick the actuators answer again.

On every exit path the configured exit torque state is applied (`[safety] on_exit`), best
effort on every joint whatever the bus raises, and the bus is closed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from hil.safety import SafeState
from hil.vocabulary import Reaction

if TYPE_CHECKING:
    from drivers.joint_bus import JointBus, JointSample
    from hil.safety import Supervisor

DISABLE_RETRY_TICKS = 20  # a torque off the bus did not take is tried again this often
# The exit path's torque off: tries before it is reported as failed (each costs the driver's
# timeouts: ~4 ms on hardware with a silent device, the lock-step allowance on an emulator).
EXIT_TORQUE_OFF_TRIES = 3

EventLog = Callable[..., None]  # RunLog.event


class TorqueKeeper:
    """What the loop knows of the actuators' torque and of its tries to turn it off."""

    def __init__(self, bus: JointBus, event: EventLog) -> None:
        self.bus = bus
        self.event = event
        self.on = False
        self.retry_tick = 0
        self.failures = 0
        self.answered_before = True
        self.exit_failed = False  # the exit path's torque off was not taken

    def enable(self) -> None:
        self.bus.enable()
        self.on = True

    def off_if_latched(
        self, k: int, time_s: float, sample: JointSample, supervisor: Supervisor
    ) -> None:
        """Torque off when the supervisor has latched it (again on a retry tick, or when the
        actuators answer again after a silence)."""
        answered = bool(sample.motor_valid.all())
        due = k >= self.retry_tick or (answered and not self.answered_before)
        if supervisor.state == SafeState.TORQUE_OFF and self.on and due:
            why = "safety stop" + (f" (try {self.failures + 1})" if self.failures else "")
            self.on = not self.disable(time_s, why, quiet=self.failures > 0)
            supervisor.torque_disabled()
            if self.on:
                self.failures += 1
                self.retry_tick = k + DISABLE_RETRY_TICKS
        self.answered_before = answered

    def disable(self, time_s: float, why: str, quiet: bool = False) -> bool:
        """Torque off on every joint, one try; False (and logged, unless `quiet`) if the bus
        did not take it."""
        return self._torque_off(time_s, why, quiet, tries=1) is not None

    def _torque_off(self, time_s: float, why: str, quiet: bool, tries: int) -> int | None:
        """Torque off, up to `tries` times until the bus takes it: the tries it took (in the
        event too), or None if it did not (logged, unless `quiet`).

        Any exception counts as a failure: on an exit path a lost port may raise what it likes,
        and the log must still be completed.
        """
        error: Exception | None = None
        for attempt in range(1, tries + 1):
            try:
                self.bus.disable()
            except Exception as exc:  # noqa: BLE001 - best effort, reported
                error = exc
                continue
            took = f" ({_tries(attempt)})" if attempt > 1 else ""
            self.event(time_s, "torque_off", f"{why}: torque off{took}", tries=attempt)
            return attempt
        if not quiet:
            took = f" ({_tries(tries)})" if tries > 1 else ""
            self.event(
                time_s,
                "torque_off_failed",
                f"{why}: could not turn torque off{took}: {error}",
                tries=tries,
            )
        return None

    def exit_state(self, on_exit: Reaction, time_s: float, opened: bool) -> list[str]:
        """The configured exit torque state and the bus closed; notes for summary.json.

        Torque off is tried up to EXIT_TORQUE_OFF_TRIES times, as on hardware a command whose
        status packet was lost (noise, a busy adapter) is sent again: the devices take a
        repeated Torque Enable = 0 as the first. The note says how many tries it took when
        it took more than one."""
        if not opened:
            return ["bus never opened: nothing was sent"]
        notes: list[str] = []
        if on_exit is Reaction.TORQUE_OFF:
            tries = self._torque_off(time_s, "exit", False, EXIT_TORQUE_OFF_TRIES)
            if tries is None:
                notes.append(
                    f"torque off FAILED ({_tries(EXIT_TORQUE_OFF_TRIES)}; see events.jsonl)"
                )
            else:
                notes.append("torque off" + (f" ({_tries(tries)})" if tries > 1 else ""))
            self.exit_failed = tries is None
        else:
            notes.append(f"torque left {'on' if self.on else 'off'} (on_exit = hold)")
            self.event(time_s, "exit_hold", "exit: torque left as it was (on_exit = hold)")
        try:
            self.bus.close()
        except Exception as exc:  # noqa: BLE001 - best effort, reported
            notes.append(f"close failed: {exc}")
            self.event(time_s, "close_failed", str(exc))
        return notes


def _tries(count: int) -> str:
    return f"{count} {'try' if count == 1 else 'tries'}"
