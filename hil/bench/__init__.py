"""`hil bench bus` and `hil bench loop`: what the bus and the 200 Hz loop cost on this machine."""

from hil.bench.bus import run_bench_bus
from hil.bench.common import BenchError, config_with_joints
from hil.bench.loop import run_bench_loop

__all__ = ["BenchError", "config_with_joints", "run_bench_bus", "run_bench_loop"]
