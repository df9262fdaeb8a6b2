"""The configuration file: the sample parses, and every kind of bad input is refused clearly."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.cli import main
from hil.config import ConfigError, default_config_text, load_config, parse_config
from hil.hardware import Connection

SAMPLE = default_config_text()


def _with(old: str, new: str) -> str:
    assert old in SAMPLE, old
    return SAMPLE.replace(old, new, 1)


def test_the_sample_describes_the_papers_testbed() -> None:
    config = load_config()
    (joint,) = config.joints
    assert config.loop.period_s == pytest.approx(0.005)
    assert (joint.stiffness_nm_per_rad, joint.damping_nms_per_rad, joint.servo_gain_per_s) == (
        2000.0,
        100.0,
        10.0,
    )
    assert joint.encoder_counts_per_rev == 120 * 8192
    assert config.can.bus_kwargs() == {
        "interface": "socketcan",
        "channel": "can0",
        "bitrate": 1_000_000,
    }


def test_hil_config_prints_a_file_that_loads(capsys, tmp_path: Path) -> None:
    assert main(["config"]) == 0
    path = tmp_path / "testbed.toml"
    path.write_text(capsys.readouterr().out)
    assert load_config(path).joints == load_config().joints


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[loop]\nrate_hz = 200.0\n[[joint]]\n", "missing required key"),
        (_with("[loop]", "[lop]"), r"unknown section\(s\) \['lop'\]"),
        (
            _with("stop_cycles = 5", "stop_cycle = 5"),
            r"\[loop\]: unknown key\(s\) \['stop_cycle'\]",
        ),
        (_with("rate_hz = 200.0", 'rate_hz = "fast"'), "rate_hz: expected a number"),
        (_with("rate_hz = 200.0", "rate_hz = -5.0"), "rate_hz: must be in"),
        (_with('model = "H54-200-S500-R"', 'model = "XM430-W350"'), "only 'H54-200-S500-R'"),
        (_with("min_angle_rad = -0.8", "min_angle_rad = 0.9"), "must be below max_angle_rad"),
        (_with("max_angle_rad = 0.8", "max_angle_rad = 4.0"), "outside the H54's position range"),
        (_with("encoder_direction = 1", "encoder_direction = 2"), "must be 1 or -1"),
        (_with("node_id = 10", "node_id = 5"), "clashes with \\[force_sensor\\] node_id"),
        (_with('on_exit = "torque_off"', 'on_exit = "pray"'), "on_exit: 'pray' is not one of"),
        (_with('name = "gc+lqr+dob"', 'name = "mpc"'), "'mpc' is not one of"),
        (_with('clock = "lockstep"', 'clock = "sundial"'), "'lockstep' or 'realtime'"),
        ("[loop\n", "not valid TOML"),
    ],
)
def test_bad_configurations_are_refused_with_where_and_why(text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_config(text, source="bad.toml")


def test_duplicate_ids_are_refused() -> None:
    joint = SAMPLE[SAMPLE.index("[[joint]]") : SAMPLE.index("[force_sensor]")]
    second = joint.replace('name = "testbed"', 'name = "second"').replace(
        "encoder_node_id = 5", "encoder_node_id = 6"
    )
    text = SAMPLE.replace("[force_sensor]", second + "\n[force_sensor]")
    with pytest.raises(ConfigError, match=r"duplicate dynamixel_id \[1\]"):
        parse_config(text)


def test_a_hardware_run_needs_a_port() -> None:
    config = parse_config(_with('port = "/dev/ttyUSB0"', 'port = ""'))
    with pytest.raises(ConfigError, match=r"\[dynamixel\] port: missing"):
        Connection.from_config(config)


def test_cli_reports_a_bad_file_and_exits_2(tmp_path: Path, capsys) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(_with("stop_cycles = 5", "stop_cycles = 5\nwarp = 9"))
    assert main(["run", "impact", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert "configuration error" in err and "warp" in err
    assert main(["run", "impact", "--config", str(tmp_path / "missing.toml")]) == 2
    assert "cannot read configuration file" in capsys.readouterr().err


def test_a_hardware_run_on_a_port_that_does_not_exist_sends_nothing(tmp_path: Path, capsys) -> None:
    path = tmp_path / "hw.toml"
    path.write_text(_with('port = "/dev/ttyUSB0"', f'port = "{tmp_path / "no-such-port"}"'))
    code = main(["run", "impact", "--config", str(path), "--out", str(tmp_path), "--no-plots"])
    assert code == 1
    out = capsys.readouterr().out
    assert "bus failure" in out and "no-such-port" in out
