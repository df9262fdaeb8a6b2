"""Bad input gets a clear error (exit status 2) and changes nothing on the hardware.

Every case points `hil run` at a running emulated testbed (`--attach`), as a user would point
it at real hardware. Afterwards the emulated actuator is read with ROBOTIS's SDK: a run that
got as far as opening the bus would have written its configuration (Return Delay Time 0, the
joint's position limits) - the factory values are still there, and torque is still off.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.cli import main
from hil.config import default_config_text, load_config
from tests.support.rig import (
    FACTORY_MAX_POSITION,
    FACTORY_RETURN_DELAY,
    emulated_testbed,
    read_device,
)

SAMPLE = default_config_text()


def _edited(old: str, new: str) -> str:
    assert old in SAMPLE, old
    return SAMPLE.replace(old, new, 1)


BAD_CONFIGS = {
    "unknown key": (_edited("[safety]\n", "[safety]\nmax_deflection = 0.1\n"), "unknown key"),
    "duplicate IDs": (
        SAMPLE + "\n[[joint]]\nname = 'second'\ndynamixel_id = 1\nencoder_node_id = 6\n",
        "duplicate dynamixel_id",
    ),
    "wrong model": (_edited('model = "H54-200-S500-R"', 'model = "XM430-W350"'), "model"),
    "impossible limits": (
        _edited("min_angle_rad = -0.8", "min_angle_rad = 0.9"),
        "must be below max_angle_rad",
    ),
    "limit beyond the actuator": (
        _edited("max_angle_rad = 0.8", "max_angle_rad = 4.0"),
        "position-mode range",
    ),
    "unknown reaction": (
        _edited('on_bus_error = "torque_off"', 'on_bus_error = "panic"'),
        "on_bus_error",
    ),
    # values that validated once but failed after the bus was open (exit 1): now at load
    "CAN bitrate 0": (_edited("bitrate = 1000000", "bitrate = 0"), "bitrate"),
    "a NaN in the emulated plant": (
        _edited("# plant = { load_mass_kg = 3.0 }", "plant = { load_mass_kg = nan }"),
        "load_mass_kg",
    ),
    "an encoder offset no encoder can read": (
        _edited("encoder_offset_rad = 0.0 ", "encoder_offset_rad = 1e6 "),
        "encoder_offset_rad",
    ),
    "a DOB cut-off above the Nyquist frequency": (
        _edited("dob_cutoff_hz = 11.4 ", "dob_cutoff_hz = 150.0 "),
        "dob_cutoff_hz",
    ),
    "trajectory beyond the limits": (
        # the contact experiment's reference goes down to -0.3 rad
        _edited("min_angle_rad = -0.8", "min_angle_rad = -0.25"),
        "beyond joint 'testbed'",
    ),
}
BAD_ARGUMENTS = {
    "negative kdist": (["--kdist", "-1"], "kdist"),
    "zero duration": (["--duration", "0"], "duration"),
    "unknown fault": (["--inject", "meteor@1"], "unknown fault"),
    "bad fault time": (["--inject", "overrun@soon"], "overrun@START"),
    "unknown controller": (["--controller", "lqr+magic"], "unknown controller 'lqr+magic'"),
    # judged before the first byte, not after torque is on
    "a duration no run can have": (["--duration", "1e9"], "--duration"),
    "kdist above max_kdist": (["--kdist", "5"], "max_kdist"),
    "kdist for a controller without a DOB": (["--controller", "pid", "--kdist", "0.5"], "--kdist"),
    "an attach that names nothing": (["--attach", ""], "--attach"),
}


@pytest.fixture(scope="module")
def testbed():
    config = load_config()
    with emulated_testbed(config, "contact") as emulator:
        before = read_device(emulator.endpoints)
        assert before.return_delay_time == FACTORY_RETURN_DELAY
        yield emulator


def _assert_untouched(emulator) -> None:
    device = read_device(emulator.endpoints)
    assert device.return_delay_time == FACTORY_RETURN_DELAY
    assert device.max_position_limit == FACTORY_MAX_POSITION
    assert device.torque_enabled == 0


@pytest.mark.timeout(60)
@pytest.mark.parametrize("case", sorted(BAD_CONFIGS))
def test_a_bad_configuration_is_refused_and_nothing_is_sent(
    case: str, testbed, tmp_path: Path, capsys
) -> None:
    text, expected = BAD_CONFIGS[case]
    path = tmp_path / "testbed.toml"
    path.write_text(text)
    attach = json.dumps(testbed.endpoints)
    code = main(
        ["run", "contact", "--config", str(path), "--attach", attach, "--out", str(tmp_path)]
    )
    assert code == 2
    assert expected in capsys.readouterr().err
    assert not list(tmp_path.glob("*/log.csv"))  # no run started
    _assert_untouched(testbed)


@pytest.mark.timeout(60)
@pytest.mark.parametrize("case", sorted(BAD_ARGUMENTS))
def test_bad_arguments_are_refused_and_nothing_is_sent(
    case: str, testbed, tmp_path: Path, capsys
) -> None:
    args, expected = BAD_ARGUMENTS[case]
    attach = json.dumps(testbed.endpoints)
    command = ["run", "contact", "--attach", attach, "--out", str(tmp_path), *args]
    try:
        code = main(command)
    except SystemExit as exc:  # argparse's own refusal
        code = exc.code
    assert code == 2
    assert expected in capsys.readouterr().err
    _assert_untouched(testbed)


@pytest.mark.timeout(60)
def test_a_hardware_run_without_a_port_is_refused(tmp_path: Path, capsys) -> None:
    path = tmp_path / "testbed.toml"
    path.write_text(_edited('port = "/dev/ttyUSB0"', 'port = ""'))
    assert main(["run", "impact", "--config", str(path), "--out", str(tmp_path)]) == 2
    assert "port: missing" in capsys.readouterr().err
