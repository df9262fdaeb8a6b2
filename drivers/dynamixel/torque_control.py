"""Torque on and off, REBOOT and the hardware error status of the devices of a `DynamixelChain`.

Protocol fact (ROBOTIS e-Manual, every PRO model): a hardware error whose bit is set in Shutdown
(PRO 48, PRO+ 63) clears Torque Enable (562 / 512), sets the Alert bit in every status packet and
latches Hardware Error Status (892 / 518); only a REBOOT (0x08) clears it. So `enable()` checks
the status first and says when a REBOOT is needed, and `reboot()` re-applies the RAM settings a
reboot resets.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

from dynamixel_sdk import COMM_SUCCESS

from drivers.dynamixel import configure
from drivers.dynamixel.device_io import DeviceIO
from drivers.dynamixel.errors import DeviceShutdownError, DynamixelReplyError, PortGoneError
from drivers.dynamixel.hardware_error import HardwareError
from drivers.dynamixel.state import HardwareErrorStatus
from drivers.dynamixel.units import position_to_rad
from drivers.joint_bus import BusError

REBOOT_POLL_INTERVAL_S = 0.01  # pause between PING rounds while devices reboot


class TorqueControl:
    """Torque, reboot and hardware-error transactions of `DynamixelChain`
    (drivers/dynamixel/chain.py), a mixin: they use the chain's port and joint configuration."""

    def enable(self, ids: Iterable[int] | None = None) -> None:
        """Torque on for the given Dynamixel IDs (all if None), without a jump.

        Checks first, for every target: Hardware Error Status must be 0 and the reply must not
        carry the Alert bit (else `DeviceShutdownError`: a REBOOT is needed), and Present
        Position must lie in the joint range. Then per device: Goal Position := Present
        Position, Torque Enable := 1, read back. If a later device fails, the earlier ones stay
        enabled (the caller decides; `disable()` is best effort).
        """
        io = self._require_writable("torque on")
        targets = self._select(ids)
        faulty = {}
        for dxl_id in targets:
            status = self.read_hardware_error(dxl_id)
            if status.bits or status.alert:
                faulty[dxl_id] = status.bits
        if faulty:
            details = "; ".join(
                f"{io.label(dxl_id)}: Hardware Error Status 0x{bits:02X} "
                f"({HardwareError.describe(bits)})"
                for dxl_id, bits in faulty.items()
            )
            raise DeviceShutdownError(
                f"cannot enable torque: {details}. The device is in shutdown (or has latched a "
                "hardware error); only a REBOOT clears it: remove the cause, then call "
                f"reboot({sorted(faulty)}).",
                hardware_errors=faulty,
            )
        spec_of = self._spec_of
        present = {
            dxl_id: io.read_item(dxl_id, spec_of[dxl_id].item("Present Position"))
            for dxl_id in targets
        }
        for dxl_id in targets:
            self._check_inside_limits(dxl_id, present[dxl_id])
        for dxl_id in targets:
            torque_item = spec_of[dxl_id].item("Torque Enable")
            io.write_item(dxl_id, spec_of[dxl_id].item("Goal Position"), present[dxl_id])
            try:
                io.write_item(dxl_id, torque_item, 1)
            except DynamixelReplyError as exc:
                bits = self.read_hardware_error(dxl_id).bits
                raise DeviceShutdownError(
                    f"{io.label(dxl_id)} refused Torque Enable = 1 ({exc}); a device in "
                    f"shutdown needs a REBOOT: call reboot([{dxl_id}])",
                    hardware_errors={dxl_id: bits},
                ) from exc
            if io.read_item(dxl_id, torque_item) != 1:
                bits = self.read_hardware_error(dxl_id).bits
                raise DeviceShutdownError(
                    f"{io.label(dxl_id)}: Torque Enable reads 0 after writing 1 (Hardware "
                    f"Error Status 0x{bits:02X}: {HardwareError.describe(bits)}); a device in "
                    f"shutdown needs a REBOOT: call reboot([{dxl_id}])",
                    hardware_errors={dxl_id: bits},
                )

    def disable(self, ids: Iterable[int] | None = None) -> None:
        """Torque off on every given device (all if None), best effort.

        Every device is tried even if one fails; afterwards one `BusError` lists the failures.
        A reply with only the Alert bit set counts as success (a device in shutdown).
        If the port itself has failed (or fails now), `PortGoneError` says so, names the devices
        whose torque could not be turned off and whether the command reached any of them:
        nothing is claimed that did not happen on the wire.
        """
        io = self._require_writable("torque off")
        targets = self._select(ids)
        if io.port.failure is not None:
            raise self._torque_off_lost(io, io.port.gone_error("write"), [], targets)
        failures = []
        confirmed: list[int] = []
        for position, dxl_id in enumerate(targets):
            torque_item = self._spec_of[dxl_id].item("Torque Enable")
            try:
                io.write_item(dxl_id, torque_item, 0)
                if io.read_item(dxl_id, torque_item) != 0:
                    failures.append(f"{io.label(dxl_id)}: Torque Enable still reads 1")
                else:
                    confirmed.append(dxl_id)
            except PortGoneError as exc:
                raise self._torque_off_lost(io, exc, confirmed, targets[position:]) from exc
            except BusError as exc:
                failures.append(str(exc))
        if failures:
            raise BusError("disable() could not turn torque off everywhere: " + "; ".join(failures))

    def _torque_off_lost(
        self,
        io: DeviceIO,
        error: PortGoneError,
        confirmed: list[int],
        lost: tuple[int, ...],
    ) -> PortGoneError:
        """The error of a disable() that the port's failure cut short (see disable)."""
        first, rest = lost[0], lost[1:]
        if error.packet_was_sent:
            in_flight = (
                f"Torque Enable = 0 was sent to {io.label(first)} but the port failed before "
                "its reply: its torque state is unknown"
            )
        else:
            in_flight = f"no Torque Enable = 0 reached {io.label(first)}"
        parts = [
            f"disable(): the Dynamixel port {error.port} is gone ({error.reason}); torque "
            f"could not be turned off: {in_flight}"
        ]
        if rest:
            parts.append("nothing was sent to " + ", ".join(io.label(dxl_id) for dxl_id in rest))
        if confirmed:
            parts.append(
                "torque off was confirmed on " + ", ".join(io.label(dxl_id) for dxl_id in confirmed)
            )
        parts.append(
            "devices that had torque on keep it until their power is cut or the port is back"
        )
        return PortGoneError(
            "; ".join(parts) + ".", port=error.port, reason=error.reason, operation=error.operation
        )

    def reboot(self, ids: Iterable[int] | None = None) -> dict[int, HardwareErrorStatus]:
        """REBOOT the given devices (all if None); returns their hardware error status after.

        Sends REBOOT (0x08) to each, then PINGs until every one answers again, bounded by
        `reboot_timeout_s` (else `BusError`); then re-applies the RAM settings (Status Return
        Level, gains). Torque is off after a reboot (RAM defaults): call `enable()` to resume.
        """
        io = self._require_writable("reboot")
        targets = self._select(ids)
        for dxl_id in targets:
            result, error = self._packet.reboot(io.port, dxl_id)
            io.check(dxl_id, "REBOOT", result, error)
        deadline = time.perf_counter() + self.config.reboot_timeout_s
        pending = list(targets)
        while True:
            pending = [dxl_id for dxl_id in pending if io.ping(dxl_id)[1] != COMM_SUCCESS]
            if not pending:
                break
            if time.perf_counter() > deadline:
                raise BusError(
                    f"after REBOOT, {', '.join(io.label(i) for i in pending)} did not answer "
                    f"PING within reboot_timeout_s={self.config.reboot_timeout_s} s on {io.where}"
                )
            time.sleep(REBOOT_POLL_INTERVAL_S)
        for dxl_id in targets:
            joint = self._joints[self._index_of[dxl_id]]
            configure.apply_ram_settings(io, joint, self._spec_of[dxl_id])
        return {dxl_id: self.read_hardware_error(dxl_id) for dxl_id in targets}

    def read_hardware_error(self, dxl_id: int) -> HardwareErrorStatus:
        """A single READ of Hardware Error Status, with the Alert bit of that reply."""
        io = self._settle()
        self._select([dxl_id])
        item = self._spec_of[dxl_id].item("Hardware Error Status")
        data, alert = io.read_bytes_with_alert(dxl_id, item.address, item.size, f"read {item.name}")
        return HardwareErrorStatus(dxl_id, data[0], alert)

    def _check_inside_limits(self, dxl_id: int, present_pulses: int) -> None:
        low, high = self._device_limits[dxl_id]
        if low <= present_pulses <= high:
            return
        index = self._index_of[dxl_id]
        units = self._spec_of[dxl_id].units
        angle = float(
            position_to_rad(present_pulses, units, self._direction[index], self._offset_rad[index])
        )
        raise BusError(
            f"cannot enable torque on {self._labels[dxl_id]}: its position {angle:.4f} rad is "
            f"outside the joint range [{float(self._min_rad[index])}, "
            f"{float(self._max_rad[index])}] rad; "
            "move it inside by hand (torque off) or widen the range in the configuration"
        )
