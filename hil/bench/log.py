"""`hil bench log`: what the run log costs a tick - CSV only, CSV + run.mcap, and CSV + run.mcap +
the live view (`hil run --live`) with a viewer subscribed to every channel - side by side.

Each case is the loop of `hil run` (impact experiment, gc+lqr+dob, lock-step) on the
in-process bus, `ticks` ticks; the cases run in turn, ROUNDS times, the order rotated each
round, so a burst of machine load falls on all of them alike. From each run's timing.csv:
    compute  controller + supervisor + bus write (the goal is sent at its end)
    log      writing the tick's CSV row and encoding + handing its messages to the sinks;
             it runs after the goal is sent, in the slack before the next tick
The viewer is a WebSocket client in a child process, as Foxglove would be (the `websockets`
package, a test dependency); without it the live case is measured with no viewer, and says so.
"""

from __future__ import annotations

import json
import multiprocessing
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from drivers.timing import DurationStats as Distribution
from hil.bench.common import machine
from hil.config import Config
from hil.experiments import IMPACT
from hil.loop import LockstepClock, RunRequest, run_experiment
from hil.output.channels import ChannelSet
from hil.output.progress import Progress
from hil.vocabulary import ControllerChoice, ControllerKind
from hil.wiring.in_process import in_process_bus

DEFAULT_LOG_TICKS = 1000
ROUNDS = 3
CASES = ("csv", "csv+mcap", "csv+mcap+live")


def _view(url: str, ready: Any, done: Any, received: Any) -> None:
    """A Foxglove WebSocket client (another process, as a viewer is): subscribes to every
    advertised channel and reads everything until `done`."""
    from websockets.sync.client import connect

    wanted = len(ChannelSet([], [], []).channels)
    subscribed: set[int] = set()
    with connect(url, subprotocols=["foxglove.sdk.v1"]) as ws:
        while not done.is_set():
            try:
                frame = ws.recv(timeout=0.05)
            except TimeoutError:
                continue
            if isinstance(frame, bytes):
                received.value += 1
                continue
            message = json.loads(frame)
            if message.get("op") == "advertise":
                new = [c["id"] for c in message["channels"]]
                subscriptions = [{"id": i, "channelId": i} for i in new]
                ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                subscribed.update(new)
                if len(subscribed) >= wanted:
                    ready.set()


class _Viewer:
    """`_view` in a child process."""

    def __init__(self, url: str) -> None:
        context = multiprocessing.get_context("spawn")
        self.ready, self.done = context.Event(), context.Event()
        self.received = context.Value("i", 0)
        self.process = context.Process(
            target=_view, args=(url, self.ready, self.done, self.received), daemon=True
        )

    def start(self) -> None:
        self.process.start()

    def stop(self) -> int:
        """After the messages in flight have arrived (the count stays put for 0.2 s)."""
        last, deadline = -1, time.monotonic() + 3.0
        while self.received.value != last and time.monotonic() < deadline:
            last = self.received.value
            time.sleep(0.2)
        self.done.set()
        self.process.join(timeout=10)
        if self.process.is_alive():
            self.process.kill()
        return int(self.received.value)


def _viewer_available() -> bool:
    try:
        import websockets.sync.client  # noqa: F401
    except ImportError:
        return False
    return True


def _run(config: Config, ticks: int, out_dir: Path, mcap: bool, sinks: tuple) -> np.ndarray:
    request = RunRequest(
        IMPACT,
        ControllerChoice(ControllerKind.GC_LQR_DOB, config.controller.kdist),
        out_dir,
        duration_s=ticks * config.loop.period_s,
        mcap=mcap,
        sinks=sinks,
    )
    bus = in_process_bus(config, IMPACT)
    run_experiment(config, request, bus, LockstepClock(config.loop.period_s), {"bench": "log"})
    return np.loadtxt(out_dir / "timing.csv", delimiter=",", skiprows=1, ndmin=2)[1:]


class _WaitingPublisher:
    """The live sink, holding the run's first message until the viewer has subscribed."""

    def __init__(self, viewer: _Viewer | None) -> None:
        from hil.output.live import LivePublisher

        self.inner = LivePublisher(port=0)
        self.viewer = viewer
        self.waited = False

    def add_channel(self, channel: Any) -> None:
        self.inner.add_channel(channel)

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        if self.viewer is not None and not self.waited:
            self.viewer.ready.wait(timeout=10)
            self.waited = True
        self.inner.message(channel_id, log_time_ns, data)

    def close(self) -> None:
        self.inner.close()


def _live_case(config: Config, ticks: int, out_dir: Path) -> tuple[np.ndarray, int]:
    viewer = None
    publisher = _WaitingPublisher(None)
    if _viewer_available():
        viewer = _Viewer(publisher.inner.url)
        publisher.viewer = viewer
        viewer.start()
    count = -1
    try:
        table = _run(config, ticks, out_dir, True, (publisher,))
    finally:
        if viewer is not None:
            count = viewer.stop()
        publisher.close()
    return table, count


def run_bench_log(
    config: Config,
    ticks: int = DEFAULT_LOG_TICKS,
    say: Callable[[str], None] = lambda _t: None,
    progress: bool | None = False,
) -> dict[str, Any]:
    """progress: a bar on stderr (None: when it is a terminal) instead of `say` lines."""
    tables: dict[str, list[np.ndarray]] = {case: [] for case in CASES}
    received: list[int] = []
    bar = Progress(ROUNDS * len(CASES), unit="runs", desc="bench log", enabled=progress)
    with tempfile.TemporaryDirectory(prefix="hil-bench-log-") as tmp, bar:
        for round_index in range(ROUNDS):
            order = CASES[round_index % len(CASES) :] + CASES[: round_index % len(CASES)]
            for number, case in enumerate(order, start=round_index * len(CASES)):
                what = f"round {round_index + 1}/{ROUNDS}, {case}, {ticks} ticks"
                if bar.enabled:
                    bar.update_to(number, what)
                else:
                    say(f"bench log: {what} ...")
                out_dir = Path(tmp) / f"{round_index}-{case.replace('+', '-')}"
                if case == "csv+mcap+live":
                    table, count = _live_case(config, ticks, out_dir)
                    received.append(count)
                else:
                    table = _run(config, ticks, out_dir, case != "csv", ())
                tables[case].append(table)
    cases = []
    for case in CASES:
        table = np.vstack(tables[case])
        cases.append(
            {
                "case": case,
                "ticks": int(table.shape[0]),
                "compute": asdict(Distribution.of(table[:, 2])),
                "log": asdict(Distribution.of(table[:, 5])),
                "compute_and_log": asdict(Distribution.of(table[:, 2] + table[:, 5])),
            }
        )
    return {
        "bench": "log",
        "machine": machine(),
        "period_s": config.loop.period_s,
        "viewer_messages_received": received,
        "viewer": _viewer_available(),
        "cases": cases,
    }


def log_report_text(report: dict[str, Any]) -> str:
    viewer = (
        f"a WebSocket viewer subscribed to every channel (messages received per run: "
        f"{report['viewer_messages_received']})"
        if report["viewer"]
        else "NO viewer (install `websockets` to measure with one)"
    )
    lines = [
        "hil bench log: per tick, in-process lock-step loop (impact, gc+lqr+dob), "
        f"{ROUNDS} interleaved rounds; live case with {viewer}",
        "  median / p99 / max [ms]:",
        f"  {'case':<15} {'compute (read->write)':<26} {'log (after the write)':<26} compute + log",
    ]
    for case in report["cases"]:
        lines.append(
            f"  {case['case']:<15} {Distribution(**case['compute']).text():<26} "
            f"{Distribution(**case['log']).text():<26} "
            f"{Distribution(**case['compute_and_log']).text()}"
        )
    return "\n".join(lines)
