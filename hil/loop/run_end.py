"""Every exit path of a run (a mixin of `hil.loop.runner.Loop`): the configured exit torque
state applied best effort on every joint, the bus closed, the metrics, summary.json and the
log completed - after the end, Ctrl-C, SIGTERM, a lost bus or an exception alike."""

from __future__ import annotations

import dataclasses
from typing import Any

from hil.output.log_process import LogWriterLost
from hil.output.records import RunResult
from hil.output.rundir import load_run
from hil.vocabulary import Reaction, RunEnding, Termination

# The exit path's torque off: tries before it is reported as failed (each costs the driver's
# timeouts: ~4 ms on hardware with a silent device, the lock-step allowance on an emulator).
EXIT_TORQUE_OFF_TRIES = 3


def _tries(count: int) -> str:
    return f"{count} {'try' if count == 1 else 'tries'}"


class RunEnd:
    """`_finish` (from `Loop.run`'s `finally`), with `_disable`, `_exit_path` and `_metrics`."""

    def _disable(self, time_s: float, why: str, quiet: bool = False) -> bool:
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
            self.log.event(time_s, "torque_off", f"{why}: torque off{took}", tries=attempt)
            return attempt
        if not quiet:
            took = f" ({_tries(tries)})" if tries > 1 else ""
            self.log.event(
                time_s,
                "torque_off_failed",
                f"{why}: could not turn torque off{took}: {error}",
                tries=tries,
            )
        return None

    def _exit_path(self) -> list[str]:
        """The configured exit torque state and the bus closed; notes for summary.json.

        Torque off is tried up to EXIT_TORQUE_OFF_TRIES times, as on hardware a command whose
        status packet was lost (noise, a busy adapter) is sent again: the devices take a
        repeated Torque Enable = 0 as the first. The note says how many tries it took when
        it took more than one."""
        time_s = self._now()
        if not self.opened:
            return ["bus never opened: nothing was sent"]
        notes: list[str] = []
        if self.config.safety.on_exit is Reaction.TORQUE_OFF:
            tries = self._torque_off(time_s, "exit", False, EXIT_TORQUE_OFF_TRIES)
            if tries is None:
                notes.append(
                    f"torque off FAILED ({_tries(EXIT_TORQUE_OFF_TRIES)}; see events.jsonl)"
                )
            else:
                notes.append("torque off" + (f" ({_tries(tries)})" if tries > 1 else ""))
            self.torque_off_failed = tries is None
        else:
            notes.append(f"torque left {'on' if self.torque.on else 'off'} (on_exit = hold)")
            self.log.event(time_s, "exit_hold", "exit: torque left as it was (on_exit = hold)")
        try:
            self.bus.close()
        except Exception as exc:  # noqa: BLE001 - best effort, reported
            notes.append(f"close failed: {exc}")
            self.log.event(time_s, "close_failed", str(exc))
        return notes

    def _finish(self, wall_time_s: float) -> None:
        try:
            self._write_kept_record()
        except LogWriterLost as exc:  # the rows of the end are lost with the writer: say so
            if self.ending.ok:
                self.ending = RunEnding(Termination.BUS_FAILURE, str(exc))
        if self.scheduler is not None:
            self.scheduler.close()
        self._log_safety()
        exit_notes = self._exit_path()
        metrics = self._metrics()
        choice = self.request.choice
        summary = {
            "experiment": self.experiment.name,
            "controller": str(choice.kind),
            "controller_label": choice.label,
            "kdist": choice.kdist if choice.kind.has_dob else None,
            "termination": self.ending.text,
            "ticks": self.ticks_done,
            "wall_time_s": wall_time_s,
            "exit": exit_notes,
            "safety_events": [e.record() for e in self.supervisor.events],
            "safety_notices": [n.record() for n in self.supervisor.notices],
            "safety_counters": self.supervisor.counters(),
            "homing": self.homing.to_dict() if self.homing is not None else None,
            "experiment_start_s": self.timeline.experiment_start_s,
            "current_limit_a": self.current_limits.tolist(),
            "gain_schedule": self.scheduler.schedule.record() if self.scheduler else None,
            "reference_feedback": self.feedback.describe() if self.feedback else None,
            "metrics": metrics,
        }
        self.log.write_summary(summary)
        self.log.close()
        self.result = RunResult(
            self.request.out_dir,
            self.ending,
            metrics,
            list(self.supervisor.events),
            self.ticks_done,
            wall_time_s,
            tuple(exit_notes),
            self.torque_off_failed,
        )

    def _metrics(self) -> dict[str, Any]:
        if self.log.rows < 2:
            return {}
        self.log.close()  # flushed and complete before it is read back
        try:
            run = load_run(self.log.dir)  # summary.json comes after the metrics: say when the
            # experiment's timeline started here
            summary = {"experiment_start_s": self.timeline.experiment_start_s}
            return self.experiment.metrics(dataclasses.replace(run, summary=summary))
        except (ValueError, KeyError) as exc:
            return {"error": str(exc)}
