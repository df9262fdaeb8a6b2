"""The configuration file: the sample parses, and every kind of bad input is refused clearly,
naming the file, the key as written and the value; device figures are the drivers' to check."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.cli import main
from hil.config import ConfigError, default_config_text, load_config, parse_config
from hil.wiring import Connection, check_devices

SAMPLE = default_config_text()


def _with(old: str, new: str) -> str:
    assert old in SAMPLE, old
    return SAMPLE.replace(old, new, 1)


def test_the_sample_describes_the_papers_testbed() -> None:
    config = load_config()
    (joint,) = config.joints
    model = config.model
    assert config.loop.period_s == pytest.approx(0.005)
    assert (model.stiffness_nm_per_rad, model.damping_nms_per_rad, model.servo_gain_per_s) == (
        2000.0,
        100.0,
        10.0,
    )
    assert joint.encoder_counts_per_rev == 120 * 8192
    assert config.can[0].bus_kwargs() == {
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
        ("[loop]\nrate_hz = 200.0\n[[joint]]\n", r"\[\[joint\]\] #1 name: Field required"),
        (_with("[loop]", "[lop]"), r"bad.toml \[lop\]: unknown key"),
        (_with("stop_cycles = 5", "stop_cycle = 5"), r"\[loop\] stop_cycle: unknown key"),
        (
            _with("rate_hz = 200.0", 'rate_hz = "fast"'),
            r"\[loop\] rate_hz: Input should be a valid number \(got 'fast'\)",
        ),
        (
            _with("rate_hz = 200.0", "rate_hz = -5.0"),
            r"rate_hz: Input should be greater than or equal to 10",
        ),
        (_with("rate_hz = 200.0", "rate_hz = nan"), r"rate_hz: Input should be a finite number"),
        (_with("rate_hz = 200.0", "rate_hz = true"), r"rate_hz: Input should be a valid number"),
        (
            _with("spin_before_tick_ms = 0.3", "spin_before_tick_ms = -0.1"),
            r"\[loop\] spin_before_tick_ms: Input should be greater than or equal to 0",
        ),
        (
            _with("min_angle_rad = -0.8", "min_angle_rad = 0.9"),
            r"\[\[joint\]\] #1 'testbed': min_angle_rad \(0.9\) must be below max_angle_rad",
        ),
        (_with("encoder_direction = 1", "encoder_direction = 2"), "Input should be 1 or -1"),
        (_with("node_id = 10", "node_id = 5"), r"duplicate CAN node ID .* \[5\]"),
        (_with('on_exit = "torque_off"', 'on_exit = "pray"'), r"on_exit: Input should be 'hold'"),
        (_with('on_exit = "torque_off"', 'on_exit = "back_off"'), r"on_exit: must be"),
        (_with("kdist = 1.0", "kdist = -1.0"), r"\[controller\] kdist: Input should be greater"),
        (_with('clock = "lockstep"', 'clock = "sundial"'), "'lockstep' or 'realtime'"),
        (_with("seed = 0", "seed = -1"), r"\[emulator\] seed: Input should be greater"),
        (_with("servo_gain_per_s = 10.0", "servo_gain_per_s = 0.0"), r"\[model\] servo_gain"),
        (
            _with(
                "\n[controller]\n",
                "\n[model.joint.knee]\nservo_gain_per_s = 18.0\n\n[controller]\n",
            ),
            r"\[model.joint\] names joints that do not exist: \['knee'\]",
        ),
        (
            _with("min_angle_rad = -0.8", "min_angle_rad = -0.8\nstiffness_nm_per_rad = 1.0"),
            r"belong to the robot model now: move them to the \[model\] section",
        ),
        ("[loop\n", "not valid TOML"),
    ],
)
def test_bad_configurations_are_refused_with_where_and_why(text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_config(text, source="bad.toml")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('model = "H54-200-S500-R"', 'model = "XM430-W350"', "'XM430-W350' is not supported"),
        ("max_angle_rad = 0.8", "max_angle_rad = 4.0", "outside the H54-200-S500-R's position"),
        ("baudrate = 3000000", "baudrate = 3000001", "is not a rate the H54-200-S500-R supports"),
        ("dynamixel_id = 1", "dynamixel_id = 300", "dxl_id must be in 0..252"),
        ("encoder_node_id = 5", "encoder_node_id = 200", "node_id must be a CANopen node ID"),
    ],
)
def test_device_figures_are_checked_by_the_drivers_in_every_mode(
    old: str, new: str, message: str
) -> None:
    config = parse_config(_with(old, new), source="bad.toml")  # the schema has no device facts
    with pytest.raises(ConfigError, match=message):
        check_devices(config)


def test_a_single_table_and_an_array_of_tables_are_the_same_bus() -> None:
    one = parse_config(SAMPLE)
    many = parse_config(SAMPLE.replace("[[dynamixel]]", "[dynamixel]").replace("[[can]]", "[can]"))
    assert one.dynamixel == many.dynamixel and one.can == many.can


def test_several_chains_need_each_joint_to_name_its_chain() -> None:
    chain = SAMPLE[SAMPLE.index("\n[[dynamixel]]\n") : SAMPLE.index("\n[[can]]\n")]
    second = chain.replace('name = "rs485"', 'name = "left"').replace("ttyUSB0", "ttyUSB1")
    text = SAMPLE.replace("\n[[can]]\n", second + "\n[[can]]\n", 1)
    with pytest.raises(ConfigError, match=r"dynamixel: required when there are several"):
        parse_config(text)
    config = parse_config(text.replace("dynamixel_id = 1", 'dynamixel_id = 1\ndynamixel = "left"'))
    assert config.chain_of(config.joints[0]) == "left"


def test_command_line_values_pass_the_same_checks_and_name_the_option() -> None:
    config = load_config()
    assert config.changed("controller", kdist=0.5, option="--kdist").controller.kdist == 0.5
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match=r"^--kdist: Input should be"):
            config.changed("controller", kdist=bad, option="--kdist")


def test_duplicate_ids_are_refused() -> None:
    joint = SAMPLE[SAMPLE.index("\n[[joint]]\n") : SAMPLE.index("# --- the controller's model")]
    second = joint.replace('name = "testbed"', 'name = "second"').replace(
        "encoder_node_id = 5", "encoder_node_id = 6"
    )
    text = SAMPLE.replace("# --- the controller's model", second + "\n# --- the controller's model")
    with pytest.raises(ConfigError, match=r"duplicate dynamixel_id on chain 'rs485': \[1\]"):
        parse_config(text)


def test_a_hardware_run_needs_a_port() -> None:
    config = parse_config(_with('port = "/dev/ttyUSB0"', 'port = ""'))
    with pytest.raises(ConfigError, match=r"\[\[dynamixel\]\] 'rs485' port: missing"):
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
