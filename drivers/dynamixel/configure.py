"""Bring-up of a chain at `open()`: identify every device, then configure only what differs.

EEPROM items (address < 562 on the PRO, < 512 on PRO+) are writable only while Torque Enable = 0
(e-Manual, every model's "EEPROM Area" caution; otherwise Access Error 7), so they are planned
first and written by the chain only once it knows the torque state. RAM items return to defaults
on every reboot, so they are re-applied after `reboot()`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from dynamixel_sdk import COMM_SUCCESS

from drivers.dynamixel.config import DynamixelChainConfig, DynamixelJointConfig
from drivers.dynamixel.control_table import MODELS, ModelSpec, model_name
from drivers.dynamixel.device_io import ERROR_NUMBER_MASK, DeviceIO, encode
from drivers.dynamixel.state_block import StateBlockLayout
from drivers.dynamixel.units import current_limit_a_to_raw, return_delay_us_to_raw
from drivers.joint_bus import BusError

STATUS_RETURN_ALL = 2  # Status Return Level 2: every instruction is answered


@dataclass(frozen=True)
class EepromWrite:
    """One planned EEPROM write: 'Operating Mode 4 -> 3' at `address` with `data`."""

    description: str
    address: int
    data: bytes


def identify(io: DeviceIO, specs: Mapping[int, ModelSpec]) -> dict[int, tuple[int, int]]:
    """PING every ID of `specs` ({id: the model configured for it}): {id: (model number,
    firmware version)}, or one error naming every problem (missing ID, wrong model) with the
    port and baud, and a pointer to `hil scan`."""
    problems = []
    found = {}
    for dxl_id, spec in specs.items():
        expected = f"{spec.model_number} ({spec.model_name})"
        model_number, result = io.ping(dxl_id)
        if result != COMM_SUCCESS:
            problems.append(
                f"{io.label(dxl_id)}: no answer to PING ({io.packet.getTxRxResult(result)}); "
                f"expected model {expected}"
            )
        elif model_number != spec.model_number:
            found_name = model_name(model_number)
            hint = (
                f": configure this joint's model as {found_name!r}"
                if model_number in MODELS
                else ""
            )
            problems.append(
                f"{io.label(dxl_id)}: found model {model_number} ({found_name}), "
                f"expected {expected}{hint}"
            )
        else:
            found[dxl_id] = (model_number, io.read_item(dxl_id, spec.item("Firmware Version")))
    if problems:
        raise BusError(
            f"Dynamixel chain on {io.where}: "
            + "; ".join(problems)
            + ". Run `hil scan` to list the IDs and models that answer on this port "
            "(and check the baud rate and wiring)."
        )
    return found


def ensure_status_return_level(io: DeviceIO, dxl_id: int, spec: ModelSpec) -> None:
    """Status Return Level (RAM; 891 on the PRO, 516 on PRO+) := 2, so that every instruction
    is answered.

    A device at level 0 or 1 executes the WRITE without answering it (one timeout); the READ
    that follows then confirms the new level (level 1 answers reads, and the write made it 2).
    """
    item = spec.item("Status Return Level")
    result, error = io.packet.write1ByteTxRx(io.port, dxl_id, item.address, STATUS_RETURN_ALL)
    if result == COMM_SUCCESS and not error & ERROR_NUMBER_MASK:
        return
    level = io.read_item(dxl_id, item)
    if level != STATUS_RETURN_ALL:
        raise BusError(
            f"{io.label(dxl_id)}: could not set Status Return Level to {STATUS_RETURN_ALL} "
            f"(reads {level})"
        )


def eeprom_plan(
    io: DeviceIO,
    joint: DynamixelJointConfig,
    config: DynamixelChainConfig,
    layout: StateBlockLayout,
) -> list[EepromWrite]:
    """The EEPROM writes this device needs (read its values, compare with the configuration):
    Operating Mode = position, Return Delay Time, Max/Min Position Limit from the joint range,
    Torque Limit if configured, and the indirect-address map of the state block."""
    spec = layout.spec
    low, high = joint.device_position_limits_pulses(spec.units)
    wanted: list[tuple[str, int]] = [
        ("Operating Mode", spec.position_mode),
        ("Return Delay Time", return_delay_us_to_raw(config.return_delay_time_us)),
        ("Max Position Limit", high),
        ("Min Position Limit", low),
    ]
    if joint.torque_limit_a is not None:
        wanted.append(("Torque Limit", current_limit_a_to_raw(joint.torque_limit_a, spec.units)))
    plan = []
    for name, value in wanted:
        item = spec.item(name)
        present = io.read_item(joint.dxl_id, item)
        if present != value:
            plan.append(
                EepromWrite(f"{name} {present} -> {value}", item.address, encode(item, value))
            )
    wanted_map = layout.indirect_address_bytes
    start = layout.indirect_address_start
    present_map = io.read_bytes(joint.dxl_id, start, len(wanted_map), "read indirect addresses")
    if present_map != wanted_map:
        description = f"Indirect Address {layout.first_index}..{layout.last_index} (state block)"
        plan.append(EepromWrite(description, start, wanted_map))
    return plan


def apply_eeprom_plan(io: DeviceIO, dxl_id: int, plan: list[EepromWrite]) -> None:
    """Write the planned items (torque must be off), then read each back."""
    for write in plan:
        io.write_bytes(dxl_id, write.address, write.data, f"write {write.description}")
    for write in plan:
        if io.read_bytes(dxl_id, write.address, len(write.data), "verify") != write.data:
            raise BusError(f"{io.label(dxl_id)}: {write.description} did not stick")


def apply_ram_settings(io: DeviceIO, joint: DynamixelJointConfig, spec: ModelSpec) -> None:
    """(Re)apply the RAM settings: Status Return Level 2 and the configured gains."""
    ensure_status_return_level(io, joint.dxl_id, spec)
    for name, value in joint.ram_gains():
        io.write_item(joint.dxl_id, spec.item(name), value)
