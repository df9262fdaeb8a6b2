"""A twin fit does its linear algebra on one BLAS thread in every process it runs in - its own,
a forked replay worker, a fresh process such as a Ray worker - whatever the caller's thread
count, and gives the caller's count back: the summation order follows the thread count, and a
fit run alone and the same fit beside a gain designer (which holds one thread) once differed in
the 14th digit (hil/twin/executor.py)."""

from __future__ import annotations

import multiprocessing

from threadpoolctl import threadpool_info, threadpool_limits

from hil.config import load_config
from hil.twin.executor import ReplayExecutor, install_runs, one_blas_thread


def _blas_threads(_: object = None) -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


@one_blas_thread
def _in_a_fit() -> tuple[list[int], list[int]]:
    """What the fit's own process and its forked replay workers have."""
    executor = ReplayExecutor(_blas_threads, install_runs, ([], load_config()), workers=2)
    try:
        workers = executor.many([0, 1, 2, 3])
    finally:
        executor.close()
    return _blas_threads(), sorted({n for w in workers for n in w})


def _fresh_process(answers: multiprocessing.Queue) -> None:
    threadpool_limits(limits=2, user_api="blas")
    install_runs([], load_config())
    answers.put(_blas_threads())


def test_a_fit_and_its_forked_workers_use_one_blas_thread_and_give_the_callers_back() -> None:
    with threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() and set(_blas_threads()) == {2}  # else the test shows nothing
        own, workers = _in_a_fit()
        assert set(own) == {1}
        assert workers == [1]
        assert set(_blas_threads()) == {2}


def test_a_fresh_worker_process_takes_one_blas_thread_when_the_runs_are_installed() -> None:
    context = multiprocessing.get_context("spawn")  # nothing inherited, as on a Ray worker
    answers = context.Queue()
    child = context.Process(target=_fresh_process, args=(answers,))
    child.start()
    threads = answers.get(timeout=120)
    child.join(timeout=30)
    assert threads and set(threads) == {1}
