"""A Ctrl-C while `hil` starts is one line and status 1, also when it lands inside a compiled
module's initialisation (MuJoCo's, measured at 0.6 s under load: Python raises "ImportError:
initialization failed" from the KeyboardInterrupt); any other ImportError still propagates.
(The whole start, process by process: tests/e2e/test_front_door_limits.py.)"""

from __future__ import annotations

import pytest

import hil.cli
from hil.cli import ExitCode


def _interrupted_import(_argv: list[str] | None) -> int:
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as interrupt:
        raise ImportError("initialization failed") from interrupt


def _broken_import(_argv: list[str] | None) -> int:
    raise ImportError("No module named 'mujoco'")


def test_a_ctrl_c_inside_a_compiled_modules_initialisation_is_an_interrupt(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(hil.cli, "_main", _interrupted_import)
    assert hil.cli.main(["run"]) == ExitCode.FAILED
    assert capsys.readouterr().err == "hil: interrupted\n"


def test_an_import_that_fails_on_its_own_is_not_taken_for_an_interrupt(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(hil.cli, "_main", _broken_import)
    with pytest.raises(ImportError, match="mujoco"):
        hil.cli.main(["run"])
