"""What the benches share: retries when a measurement fails to start, test configurations, the
machine's description, strict JSON.

This machine is shared and noisy, so whatever is compared is measured side by side in one run,
interleaved, never in two separate runs. Against the emulator the driver's reply timeout is
widened to a latency term of at least 10 ms (`with_bench_reply_timeout`: a stall of the
emulator process shows in the maxima instead of losing a reply), and a measurement that fails
to start is retried up to 3 times, the failures reported with the figures (`with_retries`).
"""

from __future__ import annotations

import math
import os
import platform
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from drivers.joint_bus import BusError
from hil.config import Config
from hil.wiring.emulation import EmulatorStartError

MAX_ATTEMPTS = 3  # per measurement, when it fails to start (see `with_retries`)
# The Dynamixel latency term the benches use at least (see `with_bench_reply_timeout`).
BENCH_MIN_LATENCY_TIMER_MS = 10.0
FIRST_ENCODER_NODE_ID = 5

T = TypeVar("T")


class BenchError(RuntimeError):
    """A bench could not complete (the message says why)."""


class StartFailed(RuntimeError):
    """A measurement did not get going (emulator start, bus open, the run's first ticks)."""


def with_retries(
    what: str, run: Callable[[], T], say: Callable[[str], None]
) -> tuple[T, list[str]]:
    """run() up to MAX_ATTEMPTS times while it fails to start; returns its result and the
    failures before it, which are reported with the figures.

    Why: on this shared 2-core VM a freshly started emulator now and then answers one of its
    first requests 3-7 ms late (measured), beyond the ~4 ms reply timeout that the configured
    1 ms latency timer gives on the realtime line (2 x 1 ms + 2 ms + wire time).
    """
    failures: list[str] = []
    for attempt in range(1, MAX_ATTEMPTS + 1):
        try:
            return run(), failures
        except (StartFailed, BusError, EmulatorStartError) as exc:
            failures.append(f"{type(exc).__name__}: {exc}")
            say(f"  {what}: attempt {attempt} of {MAX_ATTEMPTS} failed to start: {exc}")
    raise BenchError(f"{what}: {MAX_ATTEMPTS} attempts failed; the last: {failures[-1]}")


def config_with_joints(base: Config, n_joints: int) -> Config:
    """`base` with `n_joints` copies of its first joint (Dynamixel IDs 1..n, encoder nodes 5..).

    The force sensor is left out, so its node ID cannot clash with an encoder's.
    """
    if not 1 <= n_joints <= 100:
        raise ValueError(f"n_joints must be in 1..100, got {n_joints}")
    template = base.joints[0]
    joints = [
        template.model_copy(
            update={
                "name": f"joint{index + 1}" if n_joints > 1 else template.name,
                "dynamixel_id": index + 1,
                "encoder_node_id": FIRST_ENCODER_NODE_ID + index,
            }
        )
        for index in range(n_joints)
    ]
    return base.replaced(
        joints=joints, force_sensor=base.force_sensor.model_copy(update={"node_id": 0})
    ).replaced(model=base.model.model_copy(update={"joint": {}}))


def with_bench_reply_timeout(config: Config) -> Config:
    """`config` with a Dynamixel latency timer of at least BENCH_MIN_LATENCY_TIMER_MS.

    The latency term sets the driver's reply timeout (2 x latency + 2 ms + wire time); it
    changes no figure while replies arrive. On this shared 2-core VM the emulator process now
    and then answers 3-7 ms late (measured; most often just after it started), past the ~4 ms
    timeout of the built-in 1 ms: with it a bench would lose that reply (a failed read; in a
    run, a safety stop) instead of showing the stall in its maxima. Lock-step connections
    already widen it (`hil.wiring.hardware.LOCKSTEP_LATENCY_TIMER_MS`).
    """
    chains = [
        d.model_copy(
            update={"latency_timer_ms": max(d.latency_timer_ms, BENCH_MIN_LATENCY_TIMER_MS)}
        )
        for d in config.dynamixel
    ]
    # the emulated adapter keeps the configured latency timer: only the timeout is widened
    adapter_ms = config.emulator.usb_latency_timer_ms
    if adapter_ms is None:
        adapter_ms = config.dynamixel[0].latency_timer_ms
    emulator = config.emulator.model_copy(update={"usb_latency_timer_ms": adapter_ms})
    return config.replaced(dynamixel=chains, emulator=emulator)


def without_nan(value: Any) -> Any:
    """NaN/inf (an empty statistic) -> None, so that --json prints strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: without_nan(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [without_nan(item) for item in value]
    return value


def machine() -> dict[str, Any]:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "load_average_1min": load[0],
    }


def failed_starts_text(what: str, failures: Sequence[str]) -> list[str]:
    return [f"  note: {what}: a start failed and was retried: {failure}" for failure in failures]


def termination_text(run: dict[str, Any]) -> list[str]:
    lines = failed_starts_text(f"{run['experiment']} run", run["failed_starts"])
    if run["termination"] != "completed":
        lines.append(f"  note: the run ended early: {run['termination']}")
    return lines
