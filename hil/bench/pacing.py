"""`hil bench pacing`: the wall clock's two ways to wait for a tick, side by side in one run.

- *sleep, then spin*: sleep until `[loop] spin_before_tick_ms` before the tick, spin from there
  (the configured value; the built-in 0.3 ms when the configuration already never sleeps);
- *never sleep*: spin the whole period, one core kept busy.

Each is the 200 Hz wall-clock run of `hil bench loop` (the impact experiment with gc+lqr+dob
against the realtime emulator). The runs alternate, A B A B ..., `pairs` pairs of `ticks` ticks
each: a machine's noise changes by the minute, so only runs taken in turn compare.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.bench.common import termination_text, with_bench_reply_timeout
from hil.bench.loop import bench_wall_clock
from hil.config import Config
from hil.config.schema import LoopSection

DEFAULT_PACING_TICKS = 4000  # 20 s at 200 Hz per run
DEFAULT_PACING_PAIRS = 3
BUILT_IN_SPIN_MS = LoopSection().spin_before_tick_ms


def pacing_cases(config: Config) -> tuple[float, float]:
    """(sleep-then-spin stretch, never-sleep stretch) [ms] for this configuration."""
    period_ms = config.loop.period_s * 1e3
    configured = config.loop.spin_before_tick_ms
    return (configured if configured < period_ms else BUILT_IN_SPIN_MS), period_ms


def _with_spin(config: Config, spin_ms: float) -> Config:
    loop = config.loop.model_copy(update={"spin_before_tick_ms": spin_ms})
    return config.model_copy(update={"loop": loop})


def run_bench_pacing(
    config: Config,
    ticks: int = DEFAULT_PACING_TICKS,
    pairs: int = DEFAULT_PACING_PAIRS,
    say: Callable[[str], None] = lambda _text: None,
) -> dict[str, Any]:
    config = with_bench_reply_timeout(config)
    cases = pacing_cases(config)
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="hil-bench-pacing-") as tmp:
        for pair in range(pairs):
            for spin_ms in cases:
                say(f"bench pacing: pair {pair + 1}/{pairs}, spin {spin_ms:g} ms, {ticks} ticks")
                out = Path(tmp) / f"{pair}-{spin_ms:g}"
                wall = bench_wall_clock(_with_spin(config, spin_ms), ticks, out, say)
                runs.append({"pair": pair, "spin_before_tick_ms": spin_ms, **wall})
    sleeping, never = ([r for r in runs if r["spin_before_tick_ms"] == c] for c in cases)
    return {
        "bench": "pacing",
        "period_s": config.loop.period_s,
        "ticks_per_run": ticks,
        "pairs": pairs,
        "cases_ms": list(cases),
        "runs": runs,
        "overruns": [sum(r["overruns"] for r in sleeping), sum(r["overruns"] for r in never)],
        "pairs_fewer_never_sleeping": sum(
            1 for a, b in zip(sleeping, never, strict=True) if b["overruns"] < a["overruns"]
        ),
    }


def pacing_report_text(report: dict[str, Any]) -> str:
    sleep_ms, never_ms = report["cases_ms"]
    lines = [
        "hil bench pacing",
        "",
        f"the 200 Hz wall-clock run, {report['ticks_per_run']} ticks per run, in turn: "
        f"sleep then spin {sleep_ms:g} ms (A) / never sleep, spin {never_ms:g} ms (B)",
        f"  {'pair':>4}  {'case':<4}  {'overruns':>8}  {'period p99 [ms]':>15}  "
        f"{'lateness p99 [ms]':>17}  {'slack median [ms]':>17}",
    ]
    for run in report["runs"]:
        case = "A" if run["spin_before_tick_ms"] == sleep_ms else "B"
        lines.append(
            f"  {run['pair'] + 1:>4}  {case:<4}  {run['overruns']:>8}  "
            f"{run['period']['p99_s'] * 1e3:>15.3f}  {run['lateness']['p99_s'] * 1e3:>17.3f}  "
            f"{run['slack']['median_s'] * 1e3:>17.3f}"
        )
        lines += termination_text(run)
    a, b = report["overruns"]
    ratio = f"{b / a:.2f}" if a else "n/a"
    lines.append(
        f"  overruns in all: A {a}, B {b} (B / A {ratio}); B fewer in "
        f"{report['pairs_fewer_never_sleeping']} of {report['pairs']} pairs"
    )
    return "\n".join(lines)
