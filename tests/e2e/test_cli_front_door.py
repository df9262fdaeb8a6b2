"""What can be judged before the first byte is judged then: exit status 2, nothing sent, no run
directory. (The configuration's and `hil run`'s value checks against a running emulator are in
test_cli_inputs.py; these are the other commands and the places a run writes to.)"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import default_config_text


def _exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:  # argparse's own refusal
        return int(exc.code or 0)


@pytest.mark.parametrize("command", ["run", "monitor", "calibrate", "reboot"])
def test_an_attach_that_names_nothing_is_refused(command: str, tmp_path: Path, capsys) -> None:
    argv = [command, "--attach", ""]
    if command == "run":
        argv = ["run", "impact", "--attach", "", "--out", str(tmp_path)]
    assert _exit_code(argv) == 2
    assert "--attach" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["run", "monitor", "calibrate", "reboot"])
def test_an_attach_file_that_does_not_exist_says_so(command: str, tmp_path: Path, capsys) -> None:
    missing = str(tmp_path / "nonexistent.json")
    argv = [command, "--attach", missing]
    if command == "run":
        argv = ["run", "impact", "--attach", missing, "--out", str(tmp_path / "runs")]
    assert _exit_code(argv) == 2
    err = capsys.readouterr().err
    assert "no such file" in err and missing in err, err
    assert not (tmp_path / "runs").exists()


def test_scan_refuses_a_baud_rate_of_zero(capsys) -> None:
    assert _exit_code(["scan", "--port", "/dev/null", "--baudrate", "0"]) == 2
    assert "--baudrate" in capsys.readouterr().err


@pytest.mark.parametrize("where", ["a file", "below a file"])
def test_out_onto_a_file_is_refused_before_a_run_directory_is_named(
    where: str, tmp_path: Path, capsys
) -> None:
    a_file = tmp_path / "notes.txt"
    a_file.write_text("not a directory\n")
    out = a_file if where == "a file" else a_file / "runs"
    assert _exit_code(["run", "impact", "--duration", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "->" not in err, err  # the run's banner names its directory
    assert a_file.read_text() == "not a directory\n"


def test_a_robot_description_that_is_not_a_urdf_is_refused_at_load(tmp_path: Path, capsys) -> None:
    not_urdf = tmp_path / "robot.urdf"
    not_urdf.write_text("<html><body>not a robot</body></html>\n")
    text = default_config_text("dyros-jet")
    line = next(li for li in text.splitlines() if li.startswith("description = "))
    config = tmp_path / "jet.toml"
    config.write_text(text.replace(line, f"description = {json.dumps(str(not_urdf))}"))
    out = tmp_path / "runs"
    code = _exit_code(["run", "stand", "--config", str(config), "--emulate", "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert "[model] description" in err, err
    assert not out.exists()
