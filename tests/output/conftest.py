"""The runs the output tests read: a testbed contact run and a short walk of DYROS-JET with
its ROS 2 bag (`hil run --ros2`), once per worker."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.rig import hil_run


@pytest.fixture(scope="package")
def testbed_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = hil_run(tmp_path_factory.mktemp("testbed"), "contact", "--duration", "3")
    assert run.exit_code == 0
    return run.dir


@pytest.fixture(scope="package")
def walk_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("walk")
    run = hil_run(out, "walk-slow", "--robot", "dyros-jet", "--duration", "3", "--ros2")
    assert run.exit_code == 0
    return run.dir
