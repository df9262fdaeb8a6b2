"""Where a twin fit's replays run: in this process, in forked processes on this machine, or as
tasks on Ray (`hil twin --ray`, the sweeps' Ray: a local one, or a cluster at --address).

A fit evaluates its residual a few hundred times, in batches (a Jacobian's columns, ~10-20
replays at once): a batch is `many(items)`, each item replayed by `function(item)` where the
runs and the recorded configuration are already installed (`install(*shared)`, once per
process: a forked process inherits them, a Ray worker receives them once through Ray's object
store and installs them on its first task).
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from threadpoolctl import threadpool_limits

if TYPE_CHECKING:
    from hil.config import Config
    from hil.twin.runs import RecordedRun

Item = TypeVar("Item")
Result = TypeVar("Result")

_INSTALLED: list[int] = []  # in a Ray worker: the id of the shared data installed
# The runs a process's replays use and their recorded configuration (`install_runs`): set
# before a pool forks (its processes inherit them), or on a Ray worker's first task.
_RUNS: list[RecordedRun] = []
_BASE: list[Config] = []

# A fit's linear algebra on one BLAS thread, in each process it runs in (the fit's own and every
# replay's): a sum's order follows the thread count, so with the machine's default a fit run
# alone and the same fit beside a gain designer (which holds one thread) differed in the 14th
# digit, and a chaotic walk replayed on the two twins by 2x. The fits' few small matrices gain
# nothing from more threads.
one_blas_thread = threadpool_limits.wrap(limits=1, user_api="blas")


def install_runs(runs: list[RecordedRun], base: Config) -> None:
    """The runs and configuration for this process's replays. A fit's trial figures may make
    MuJoCo's integration unstable: the replay says so (`Replayed.unstable`) and the fit steps
    back, so MuJoCo's own warning (to stderr, and MUJOCO_LOG.TXT in the working directory) is
    silenced here (`ReplayExecutor.close` gives this process its handler back)."""
    import mujoco

    _RUNS[:] = runs
    _BASE[:] = [base]
    # a Ray worker's process (a forked one inherits the fit's): held for the process's life, or
    # in the fit's own process until the fit's `one_blas_thread` gives back the thread count
    threadpool_limits(limits=1, user_api="blas")
    mujoco.set_mju_user_warning(_ignore_warning)


def _ignore_warning(message: str) -> None:
    """MuJoCo's warnings in a fit: counted in MjData.warning, which the replay reads."""


def installed() -> tuple[list[RecordedRun], Config]:
    """The runs and configuration installed in this process."""
    return _RUNS, _BASE[0]


def _on_ray_worker(
    function: Callable[[Any], Any],
    install: Callable[..., None],
    key: int,
    item: Any,
    *shared: Any,  # (top-level arguments: Ray passes them resolved from its object store)
) -> Any:
    if [key] != _INSTALLED:
        install(*shared)
        _INSTALLED[:] = [key]
    return function(item)


class ReplayExecutor(Generic[Item, Result]):
    """Runs `function` over batches of items (see the module docstring).

    workers: processes at a time on this machine (1: in this process), or Ray's CPUs when
        `ray` is set and Ray is started here.
    ray: None (no Ray), or the address of a Ray cluster ("" for a local Ray with `workers`
        CPUs, started here and ended at `close`).
    """

    def __init__(
        self,
        function: Callable[[Item], Result],
        install: Callable[..., None],
        shared: tuple[Any, ...],
        workers: int = 1,
        ray: str | None = None,
    ) -> None:
        import mujoco

        self.function = function
        self._warning_handler = mujoco.get_mju_user_warning()
        install(*shared)  # this process's own batches of one
        self.workers = workers
        self.pool: concurrent.futures.ProcessPoolExecutor | None = None
        self._ray: Any = None
        self._remote: Any = None
        self._started_here: set[Any] | None = None
        if ray is not None:
            self._start_ray(install, shared, workers, ray)
        elif workers > 1:
            self.pool = concurrent.futures.ProcessPoolExecutor(
                workers, mp_context=multiprocessing.get_context("fork")
            )

    def _start_ray(
        self, install: Callable[..., None], shared: tuple[Any, ...], workers: int, address: str
    ) -> None:
        from hil.sweep.engine import import_ray, start_ray
        from hil.sweep.processes import descendants

        ray = import_ray()
        if not ray.is_initialized():
            self._started_here = descendants(os.getpid())
        start_ray(workers, address or None)
        self._ray = ray
        self._shared = [ray.put(value) for value in shared]
        self._install = install
        self._key = id(self)
        self._remote = ray.remote(num_cpus=1, max_retries=0)(_on_ray_worker)

    @property
    def where(self) -> str:
        if self._ray is not None:
            cpus = int(self._ray.cluster_resources().get("CPU", 1))
            return f"on Ray ({cpus} CPUs)"
        if self.pool is not None:
            return f"{self.workers} processes"
        return "in this process"

    def many(self, items: Sequence[Item]) -> list[Result]:
        if self._ray is not None:
            refs = [
                self._remote.remote(self.function, self._install, self._key, item, *self._shared)
                for item in items
            ]
            return list(self._ray.get(refs))
        if self.pool is None or len(items) == 1:
            return [self.function(item) for item in items]
        return list(self.pool.map(self.function, items))

    def close(self) -> None:
        import mujoco

        mujoco.set_mju_user_warning(self._warning_handler)
        if self.pool is not None:
            self.pool.shutdown()
            self.pool = None
        if self._ray is not None and self._started_here is not None:
            from hil.sweep.processes import shutdown_ray_started_here

            shutdown_ray_started_here(self._ray, self._started_here)
        self._ray = None
