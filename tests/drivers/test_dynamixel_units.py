"""Pure parts of the Dynamixel driver: units, control-table data, state-block layout, config
checks, port opening errors. No emulator needed; figures are checked against the e-Manual
numbers and hand calculation, not against the code's own output."""

from __future__ import annotations

import math
import os
import struct
import tty
from pathlib import Path

import numpy as np
import pytest

from drivers.dynamixel.config import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel.control_table import H54_200_S500_R, MODELS, model_name, model_spec
from drivers.dynamixel.port import (
    LowLatencyPortHandler,
    open_port,
    sdk_accepts_baudrate,
    usb_latency_timer_ms,
)
from drivers.dynamixel.scan import scan
from drivers.dynamixel.state_block import STATE_BLOCK_ITEMS, StateBlockLayout
from drivers.dynamixel.units import (
    H54_200_S500_R_UNITS as H54,
)
from drivers.dynamixel.units import (
    current_a_to_torque_estimate_nm,
    current_limit_a_to_raw,
    current_limit_raw_to_a,
    current_to_a,
    position_to_rad,
    rad_s_to_velocity,
    rad_to_position,
    return_delay_us_to_raw,
    to_signed,
    velocity_to_rad_s,
)
from drivers.joint_bus import BusError

# ------------------------------------------------------------------------------------- units


def test_signed_decoding_of_unsigned_sdk_values() -> None:
    assert to_signed(4294967289, 4) == -7  # what GroupSyncRead.getData returns for -7
    assert to_signed(0x7FFFFFFF, 4) == 2**31 - 1
    assert to_signed(0x80000000, 4) == -(2**31)
    assert to_signed(0xFFFF, 2) == -1
    assert to_signed(0x8000, 2) == -32768
    assert to_signed(0x7F, 1) == 127
    assert to_signed(0xFF, 1) == -1
    assert to_signed(250961, 4) == 250961
    with pytest.raises(ValueError, match="1, 2 or 4"):
        to_signed(1, 3)


def test_position_full_revolution_and_quantisation_step() -> None:
    assert position_to_rad(501_923, H54) == pytest.approx(2 * math.pi, rel=1e-15)
    step = position_to_rad(1, H54) - position_to_rad(0, H54)
    assert step == pytest.approx(2 * math.pi / 501_923, rel=1e-12)
    assert step == pytest.approx(1.2518e-5, rel=1e-4)  # e-Manual H54: 501,923 pulses/rev
    # The position-mode range +-250,961 pulses is +-179.999 degrees (e-Manual).
    assert math.degrees(position_to_rad(250_961, H54)) == pytest.approx(179.999, abs=1e-3)
    assert math.degrees(position_to_rad(-250_961, H54)) == pytest.approx(-179.999, abs=1e-3)


def test_position_direction_offset_and_round_trip() -> None:
    # joint = direction * (device - offset): device 0.5 rad, offset 0.2 rad, reversed -> -0.3.
    pulses = round(0.5 / (2 * math.pi / 501_923))
    assert position_to_rad(pulses, H54, -1, 0.2) == pytest.approx(-0.3, abs=1e-5)
    assert rad_to_position(-0.3, H54, -1, 0.2) == pulses
    rng = np.random.default_rng(1)
    raw = rng.integers(-250_961, 250_962, size=200)
    direction = rng.choice([-1, 1], size=200)
    offset = rng.uniform(-0.5, 0.5, size=200)
    angles = position_to_rad(raw, H54, direction, offset)
    np.testing.assert_array_equal(rad_to_position(angles, H54, direction, offset), raw)
    assert rad_to_position(np.array([0.1, -0.1]), H54).dtype == np.int64


def test_velocity_unit() -> None:
    rad_s_per_unit = 0.00199234 * 2 * math.pi / 60  # e-Manual: 0.00199234 rpm per unit
    assert velocity_to_rad_s(1, H54) == pytest.approx(rad_s_per_unit, rel=1e-12)
    assert rad_s_per_unit == pytest.approx(2.0864e-4, rel=1e-4)  # e-Manual H54 figure
    # 30,116 units x 0.00199234 rpm = 60.0017 rpm = 6.2834 rad/s.
    assert velocity_to_rad_s(30_116, H54) == pytest.approx(60.0017 * 2 * math.pi / 60, rel=1e-5)
    assert velocity_to_rad_s(-100, H54, -1) == pytest.approx(100 * rad_s_per_unit)
    assert rad_s_to_velocity(2 * math.pi, H54) == round(60 / 0.00199234)


def test_current_and_torque_estimate() -> None:
    assert current_to_a(2048, H54) == pytest.approx(33.0)  # 33,000 mA / 2,048 per unit
    assert current_to_a(-1, H54) == pytest.approx(-0.01611328, rel=1e-6)
    assert current_to_a(10, H54, -1) == pytest.approx(-0.1611328, rel=1e-6)
    # Default Torque Limit 620 units ~ 9.99 A (e-Manual H54: 16.11328 mA per unit).
    assert current_limit_raw_to_a(620, H54) == pytest.approx(9.99, abs=0.01)
    assert current_limit_a_to_raw(9.99, H54) == 620
    with pytest.raises(ValueError, match=">= 0 A"):
        current_limit_a_to_raw(-1.0, H54)
    # Spec: continuous 44.7 N m at 9.3 A.
    assert current_a_to_torque_estimate_nm(9.3, H54) == pytest.approx(44.7)
    assert H54.torque_constant_nm_per_a == pytest.approx(4.806, abs=1e-3)


def test_return_delay_time_units() -> None:
    assert return_delay_us_to_raw(0) == 0
    assert return_delay_us_to_raw(500) == 250  # H54 default 250 = 500 us
    for bad in (3, -2, 510):
        with pytest.raises(ValueError, match="even number of microseconds"):
            return_delay_us_to_raw(bad)


# ----------------------------------------------------------------------- control table data


def test_h54_control_table_addresses_from_the_emanual() -> None:
    spec = model_spec(54024)
    assert spec is H54_200_S500_R and MODELS[54024] is spec
    expected = {
        "Model Number": (0, 2),
        "Return Delay Time": (9, 1),
        "Operating Mode": (11, 1),
        "Torque Limit": (30, 2),
        "Max Position Limit": (36, 4),
        "Min Position Limit": (40, 4),
        "Shutdown": (48, 1),
        "Torque Enable": (562, 1),
        "Goal Position": (596, 4),
        "Present Position": (611, 4),
        "Present Velocity": (615, 4),
        "Present Current": (621, 2),
        "Present Input Voltage": (623, 2),
        "Present Temperature": (625, 1),
        "Status Return Level": (891, 1),
        "Hardware Error Status": (892, 1),
    }
    for name, (address, size) in expected.items():
        item = spec.item(name)
        assert (item.address, item.size) == (address, size), name
    assert spec.item("Present Position").signed and spec.item("Present Current").signed
    assert not spec.item("Hardware Error Status").signed
    assert spec.is_eeprom(spec.item("Max Position Limit"))
    assert not spec.is_eeprom(spec.item("Torque Enable"))
    assert spec.indirect_address_of(1) == 49 and spec.indirect_address_of(256) == 559
    assert spec.indirect_data_of(1) == 634 and spec.indirect_data_of(256) == 889
    with pytest.raises(ValueError, match="1..256"):
        spec.indirect_data_of(257)
    with pytest.raises(KeyError, match="no control-table item"):
        spec.item("Goal PWM")
    with pytest.raises(ValueError, match="1234 is not supported.*54024.*54025"):
        model_spec(1234)  # no PRO model: refused, naming the supported ones
    with pytest.raises(ValueError, match=r"35072 \(L42-10-S300-R\) is not supported.*PRO layout"):
        model_spec(35072)  # a PRO whose table is another: refused with the reason
    assert model_name(54025) == "H54-200-S500-R(A)"
    assert model_name(35072) == "L42-10-S300-R (not supported)"
    assert model_name(1234) == "unknown model 1234"


def test_state_block_layout() -> None:
    layout = StateBlockLayout(H54_200_S500_R, first_index=1)
    assert STATE_BLOCK_ITEMS[0] == "Present Position"
    assert layout.size == 15
    assert layout.indirect_targets == (
        *range(611, 619),  # Present Position, Present Velocity
        621, 622,  # Present Current
        623, 624,  # Present Input Voltage
        892,  # Hardware Error Status
        562,  # Torque Enable
        625,  # Present Temperature
    )  # fmt: skip
    assert layout.indirect_address_start == 49
    assert layout.data_start == 634
    assert layout.indirect_address_bytes[:4] == bytes([611 & 0xFF, 611 >> 8, 612 & 0xFF, 2])
    block = struct.pack("<iihHBBB", -250_961, -7, -2048, 240, 0x20, 1, 41)
    assert layout.decoder().unpack(block) == (-250_961, -7, -2048, 240, 0x20, 1, 41)
    assert StateBlockLayout(H54_200_S500_R, 10).data_start == 643
    with pytest.raises(ValueError, match="1..242"):
        StateBlockLayout(H54_200_S500_R, 243).check_fits()


# ----------------------------------------------------------------------------- configuration


def _joint(**overrides: object) -> DynamixelJointConfig:
    fields: dict[str, object] = {"dxl_id": 1, "min_position_rad": -1.0, "max_position_rad": 1.0}
    fields.update(overrides)
    return DynamixelJointConfig(**fields)  # type: ignore[arg-type]


def _chain(*joints: DynamixelJointConfig, **overrides: object) -> DynamixelChainConfig:
    fields: dict[str, object] = {"port": "/dev/null", "baudrate": 4_000_000, "joints": joints}
    fields.update(overrides)
    return DynamixelChainConfig(**fields)  # type: ignore[arg-type]


def test_joint_limits_map_to_device_limits_rounded_outwards() -> None:
    rad_per_pulse = 2 * math.pi / 501_923
    joint = _joint(min_position_rad=-1.0, max_position_rad=1.0)
    low, high = joint.device_position_limits_pulses(H54)
    assert low == math.floor(-1.0 / rad_per_pulse) and high == math.ceil(1.0 / rad_per_pulse)
    # Every goal inside the joint range, rounded to a pulse, stays inside the device limits.
    assert low <= rad_to_position(-1.0, H54) and rad_to_position(1.0, H54) <= high
    reversed_joint = _joint(direction=-1, offset_rad=0.5, min_position_rad=-0.2)
    low, high = reversed_joint.device_position_limits_pulses(H54)
    assert low == math.floor((0.5 - 1.0) / rad_per_pulse)
    assert high == math.ceil((0.5 + 0.2) / rad_per_pulse)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"direction": 2}, "direction must be"),
        ({"min_position_rad": 1.0}, "min_position_rad < max_position_rad"),
        ({"max_position_rad": math.nan}, "min_position_rad < max_position_rad"),
        ({"dxl_id": 253}, "dxl_id must be"),
        ({"torque_limit_a": 0.0}, "torque_limit_a"),
        ({"position_p_gain": 70000}, "position_p_gain"),
        ({"offset_rad": math.inf}, "offset_rad"),
    ],
)
def test_joint_config_rejects_bad_values(overrides: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _joint(**overrides)


def test_chain_config_checks() -> None:
    assert _chain(_joint(), _joint(dxl_id=2)).dxl_ids == (1, 2)
    with pytest.raises(ValueError, match="unique.*\\[1\\]"):
        _chain(_joint(), _joint())
    with pytest.raises(ValueError, match="at least one joint"):
        _chain()
    with pytest.raises(ValueError, match="not supported"):
        _chain(_joint(), model_number=1020)
    with pytest.raises(ValueError, match="19200 is not a rate the H54"):
        _chain(_joint(), baudrate=19_200)
    with pytest.raises(ValueError, match="even number"):
        _chain(_joint(), return_delay_time_us=3)
    with pytest.raises(ValueError, match="latency_timer_ms"):
        _chain(_joint(), latency_timer_ms=0.0)
    # +-pi is one pulse beyond the position-mode range of +-250,961 pulses.
    with pytest.raises(ValueError, match="outside the H54-200-S500-R's position-mode range"):
        _chain(_joint(min_position_rad=-math.pi, max_position_rad=math.pi))
    with pytest.raises(ValueError, match="outside the H54-200-S500-R's position-mode range"):
        _chain(_joint(offset_rad=3.0))
    with pytest.raises(ValueError, match="Torque Limit range"):
        _chain(_joint(torque_limit_a=31.0))
    with pytest.raises(ValueError, match="indirect_first_index"):
        _chain(_joint(), indirect_first_index=250)


# ---------------------------------------------------------------------------------- port


def test_sdk_baud_whitelist() -> None:
    assert sdk_accepts_baudrate(4_000_000) and sdk_accepts_baudrate(57_600)
    assert not sdk_accepts_baudrate(4_500_000)
    assert not sdk_accepts_baudrate(10_500_000)


def test_open_port_refuses_unsettable_baud_and_missing_port(tmp_path: Path) -> None:
    with pytest.raises(BusError, match="4500000 bps cannot be set through dynamixel-sdk"):
        open_port("/dev/does-not-exist", 4_500_000)
    with pytest.raises(BusError, match="cannot open serial port '/dev/does-not-exist'"):
        open_port("/dev/does-not-exist", 4_000_000)
    with pytest.raises(BusError, match="cannot open serial port"):
        scan(str(tmp_path / "nothing"), 1_000_000)


def test_packet_timeout_uses_configured_latency() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        handler = open_port(os.ttyname(slave), 4_000_000, latency_timer_ms=1.0)
        try:
            # (11 + 15 bytes) x 2.5 us/byte + 2 x 1 ms + 2 ms (SDK formula, latency 1 ms)
            assert handler.packet_timeout_ms(26) == pytest.approx(0.065 + 2.0 + 2.0)
            handler.setPacketTimeout(26)
            assert handler.packet_timeout == pytest.approx(4.065)
            assert not handler.isPacketTimeout()
        finally:
            handler.closePort()
        fast = LowLatencyPortHandler("x", latency_timer_ms=0.5, timeout_margin_ms=0.5)
        fast.tx_time_per_byte = 0.0025
        assert fast.packet_timeout_ms(11) == pytest.approx(0.0275 + 1.0 + 0.5)
        with pytest.raises(ValueError, match="latency_timer_ms"):
            LowLatencyPortHandler("x", latency_timer_ms=0.0)
    finally:
        os.close(master)
        os.close(slave)


def test_usb_latency_timer_longer_than_configured_is_refused(tmp_path: Path) -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        port = os.ttyname(slave)
        assert usb_latency_timer_ms(port, tmp_path) is None  # a pty has no latency timer
        device_dir = tmp_path / os.path.basename(port)
        device_dir.mkdir()
        (device_dir / "latency_timer").write_text("16\n")
        assert usb_latency_timer_ms(port, tmp_path) == 16
        with pytest.raises(BusError, match="latency timer of 16 ms.*echo 1 \\| sudo tee"):
            open_port(port, 1_000_000, latency_timer_ms=1.0, sysfs_root=tmp_path)
        (device_dir / "latency_timer").write_text("1\n")
        open_port(port, 1_000_000, latency_timer_ms=1.0, sysfs_root=tmp_path).closePort()
    finally:
        os.close(master)
        os.close(slave)
