"""A twin fit's replays as Ray tasks (hil/twin/executor.py, `hil twin --ray`): on a local Ray
the very residuals the fit computes in process, byte for byte; Ray started for them is ended;
an unreachable cluster is refused before anything is fitted."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main
from hil.config import load_config
from hil.twin.block_lm import replay_all
from hil.twin.executor import ReplayExecutor, install_runs
from hil.twin.legs_figures import leg_figures_of
from hil.twin.runs import read_run
from hil.vocabulary import Robot
from tests.support.bench_hardware import record

pytestmark = [pytest.mark.slow, pytest.mark.ray, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    host = load_config(robot=Robot.DYROS_JET)
    out = tmp_path_factory.mktemp("legs")
    return record(host, host, "suspended-chirp", "pid", out, duration_s=2.0).out_dir


def test_ray_replays_are_the_in_process_ones(short_run: Path) -> None:
    ray = pytest.importorskip("ray")
    from hil.sweep.processes import descendants

    run = read_run(short_run)
    start = leg_figures_of(run.config)
    other = start.copy()
    other.joints["gear_stiffness_nm_per_rad"] *= 1.2
    before = descendants(os.getpid())
    here = ReplayExecutor(replay_all, install_runs, ([run], run.config))
    on_ray = ReplayExecutor(replay_all, install_runs, ([run], run.config), workers=2, ray="")
    try:
        assert on_ray.where.startswith("on Ray")
        local = here.many([start, other])
        remote = on_ray.many([start, other])
    finally:
        on_ray.close()
        here.close()
    assert not ray.is_initialized()
    assert not (descendants(os.getpid()) - before)  # Ray's processes started here are gone
    for a, b in zip(local, remote, strict=True):
        assert a is not None and b is not None
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
    assert not np.array_equal(local[0][0], local[1][0])  # (the figures made a difference)


def test_an_unreachable_cluster_is_refused(short_run: Path, capsys: pytest.CaptureFixture) -> None:
    pytest.importorskip("ray")
    code = main(["twin", str(short_run), "--address", "127.0.0.1:9", "--out",
                 str(short_run.parent / "twin.toml")])  # fmt: skip
    assert code == 2
    assert "127.0.0.1:9" in capsys.readouterr().err
