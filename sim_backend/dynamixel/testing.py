"""Run an emulated chain in a separate process, for tests that drive it with dynamixel-sdk.

Why a process: dynamixel-sdk busy-waits while it receives, so an emulator thread in the same
interpreter is starved by the GIL. The child is started with the multiprocessing "spawn"
context and always stopped by the context manager.

    from sim_backend.dynamixel.testing import spawn_emulated_chain

    with spawn_emulated_chain(ids=(1, 2), baud_index=6) as emu:
        port = PortHandler(emu.port_path)
        port.openPort(); port.setBaudRate(4_000_000)
        ...
        emu.raise_hardware_error(1, 0x20)          # Overload on ID 1 (shutdown by default)
        emu.set_item(2, "Present Position", 1234)  # firmware-side write
        emu.item(2, "Goal Position")               # firmware-side read
        emu.faults(silent_ids={2})                 # line faults, see LineFaults
        emu.clear_faults()

    # a mixed chain: one model for all, or {id: model} (e-Manual names; default H54-200-S500-R)
    with spawn_emulated_chain(ids=(1, 2, 3), models={2: "H54-100-S500-R", 3: "H42-20-S300-R"}):
        ...

Stand-in firmware (`firmware=`):
- "ideal": before every instruction, Present Position := Goal Position on each device whose
  torque is on (a perfect servo). Other Present* values stay as set.
- "none": nothing moves; Present* values change only through `set_item`.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import select
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import asdict, dataclass, field
from typing import Any

from sim_backend.dynamixel.chain import DynamixelChain
from sim_backend.dynamixel.control_table import HARDWARE_ERROR_BITS_MASK
from sim_backend.dynamixel.device import (
    DEFAULT_FIRMWARE_VERSION,
    DEFAULT_REBOOT_TIME_S,
    DynamixelProDevice,
)
from sim_backend.dynamixel.line import DynamixelLine, request_realtime_scheduling
from sim_backend.dynamixel.models import DEFAULT_MODEL

FIRMWARES = ("ideal", "none")
_COMMAND_TIMEOUT_S = 10.0
_LOOP_MAX_WAIT_S = 0.05


class IdealFirmware:
    """Present Position follows Goal Position at once while torque is on (tick listener)."""

    def __init__(self, devices: Sequence[DynamixelProDevice]) -> None:
        self.devices = tuple(devices)

    def __call__(self, now_s: float) -> None:
        for device in self.devices:
            if device.torque_enabled:
                goal = device.item("Goal Position")
                if device.item("Present Position") != goal:
                    device.set_item("Present Position", goal)


@dataclass(frozen=True)
class EmulatorOptions:
    """Everything the child needs to build the chain (picklable)."""

    ids: tuple[int, ...]
    baud_index: int
    realtime: bool
    firmware: str
    eeprom_overrides: dict[Any, Any] = field(default_factory=dict)
    enforce_baud: bool = False
    reboot_time_s: float = DEFAULT_REBOOT_TIME_S
    firmware_version: int = DEFAULT_FIRMWARE_VERSION
    realtime_scheduling: bool = True
    models: dict[int, str] = field(default_factory=dict)  # by ID; absent: DEFAULT_MODEL

    def overrides_for(self, dxl_id: int) -> dict[str, int]:
        """`eeprom_overrides` is either {name: value} for all devices or {id: {name: value}}."""
        if any(isinstance(key, int) for key in self.eeprom_overrides):
            return dict(self.eeprom_overrides.get(dxl_id, {}))
        return dict(self.eeprom_overrides)


class _ChildEmulator:
    """The child's state and its single-threaded loop."""

    def __init__(self, options: EmulatorOptions) -> None:
        self.sched_fifo = options.realtime_scheduling and request_realtime_scheduling()
        self.devices = [
            DynamixelProDevice(
                dxl_id,
                model=options.models.get(dxl_id, DEFAULT_MODEL),
                baud_index=options.baud_index,
                firmware_version=options.firmware_version,
                eeprom_overrides=options.overrides_for(dxl_id),
                reboot_time_s=options.reboot_time_s,
            )
            for dxl_id in options.ids
        ]
        self.chain = DynamixelChain(self.devices, enforce_baud=options.enforce_baud)
        if options.firmware == "ideal":
            self.chain.add_tick_listener(IdealFirmware(self.devices))
        self.line = DynamixelLine(self.chain, realtime=options.realtime)
        self.scheduled_errors: list[tuple[float, int, int]] = []  # (due, id, bits)
        self.running = True

    def device(self, dxl_id: int) -> DynamixelProDevice:
        """By the ID it was created with, even after its ID item changed."""
        for device in self.devices:
            if device.dxl_id == dxl_id:
                return device
        return self.chain.device(dxl_id)

    # Commands (name -> method cmd_<name>); each returns a picklable result.
    def cmd_raise_hardware_error(self, dxl_id: int, bits: int, delay_s: float = 0.0) -> None:
        device = self.device(dxl_id)  # fail now for a wrong ID
        if not 0 <= bits <= HARDWARE_ERROR_BITS_MASK:
            raise ValueError(f"hardware error bits must be within 0x3F, got 0x{bits:X}")
        if delay_s <= 0:
            device.raise_hardware_error(bits)
        else:
            self.scheduled_errors.append((self.line.clock() + delay_s, dxl_id, bits))
            self.scheduled_errors.sort()

    def cmd_clear_hardware_error(self, dxl_id: int, bits: int) -> None:
        self.device(dxl_id).clear_hardware_error(bits)

    def cmd_set_item(self, dxl_id: int, name: str, value: int) -> None:
        self.device(dxl_id).set_item(name, value)

    def cmd_item(self, dxl_id: int, name: str) -> int:
        return self.device(dxl_id).item(name)

    def cmd_in_shutdown(self, dxl_id: int) -> bool:
        return self.device(dxl_id).in_shutdown

    def cmd_set_silenced(self, dxl_id: int, silenced: bool = True) -> None:
        self.device(dxl_id).silenced = silenced

    def cmd_faults(self, **fields: Any) -> None:
        faults = self.chain.faults
        for name, value in fields.items():
            if not hasattr(faults, name):
                raise AttributeError(f"LineFaults has no field {name!r}")
            setattr(faults, name, set(value) if name.endswith("_ids") else int(value))

    def cmd_clear_faults(self) -> None:
        self.chain.faults.clear()

    def cmd_fault_counts(self) -> dict[str, int]:
        return asdict(self.chain.faults.fired)

    def cmd_stats(self) -> dict[str, int]:
        return {
            **asdict(self.line.stats),
            **asdict(self.line.parser.stats),
            "sched_fifo": int(self.sched_fifo),
        }

    def cmd_stop(self) -> None:
        self.running = False

    def run(self, conn: multiprocessing.connection.Connection) -> None:
        line = self.line
        line_fd = line.fileno()
        while self.running:
            deadlines = [t for t in (line.next_due_s(),) if t is not None]
            if self.scheduled_errors:
                deadlines.append(self.scheduled_errors[0][0])
            timeout_s = _LOOP_MAX_WAIT_S
            if deadlines:
                timeout_s = min(timeout_s, max(0.0, min(deadlines) - line.clock()))
            readable, _, _ = select.select([line_fd, conn], [], [], timeout_s)
            if line_fd in readable:
                line.on_readable()
            else:
                line.on_idle()
            line.flush_due()
            self._fire_scheduled_errors()
            if conn in readable:
                self._serve_command(conn)

    def _fire_scheduled_errors(self) -> None:
        now_s = self.line.clock()
        while self.scheduled_errors and self.scheduled_errors[0][0] <= now_s:
            _, dxl_id, bits = self.scheduled_errors.pop(0)
            self.device(dxl_id).raise_hardware_error(bits)

    def _serve_command(self, conn: multiprocessing.connection.Connection) -> None:
        try:
            name, args, kwargs = conn.recv()
        except EOFError:  # the parent is gone
            self.running = False
            return
        try:
            result = getattr(self, f"cmd_{name}")(*args, **kwargs)
        except Exception as error:  # noqa: BLE001 - reported to the parent, loop lives on
            conn.send(("error", f"{type(error).__name__}: {error}"))
        else:
            conn.send(("ok", result))


def _child_main(conn: multiprocessing.connection.Connection, options: EmulatorOptions) -> None:
    try:
        emulator = _ChildEmulator(options)
    except Exception as error:  # noqa: BLE001 - the parent raises it
        conn.send(("error", f"{type(error).__name__}: {error}"))
        return
    conn.send(("ok", emulator.line.port_path))
    try:
        emulator.run(conn)
    finally:
        emulator.line.close()


class EmulatorCommandError(RuntimeError):
    """The emulator child refused a command or could not start."""


class EmulatedChain:
    """Parent-side handle of an emulator child: the pty path and a few commands."""

    def __init__(
        self,
        process: multiprocessing.process.BaseProcess,
        conn: multiprocessing.connection.Connection,
        port_path: str,
    ) -> None:
        self._process = process
        self._conn = conn
        self.port_path = port_path

    def command(self, name: str, *args: Any, **kwargs: Any) -> Any:
        """Run `cmd_<name>` in the child and return its result (EmulatorCommandError if it
        failed, TimeoutError if the child does not answer)."""
        if not self._process.is_alive():
            raise EmulatorCommandError(
                f"emulator process is not running (exit code {self._process.exitcode})"
            )
        self._conn.send((name, args, kwargs))
        if not self._conn.poll(_COMMAND_TIMEOUT_S):
            raise TimeoutError(
                f"emulator did not answer command {name!r} in {_COMMAND_TIMEOUT_S} s"
            )
        try:
            status, result = self._conn.recv()
        except EOFError:
            raise EmulatorCommandError(
                f"emulator process died while running {name!r} (exit code {self._process.exitcode})"
            ) from None
        if status != "ok":
            raise EmulatorCommandError(f"emulator command {name!r} failed: {result}")
        return result

    def raise_hardware_error(self, dxl_id: int, bits: int, *, delay_s: float = 0.0) -> None:
        """OR `bits` into Hardware Error Status of `dxl_id` now or `delay_s` from now."""
        self.command("raise_hardware_error", dxl_id, bits, delay_s)

    def clear_hardware_error(self, dxl_id: int, bits: int) -> None:
        self.command("clear_hardware_error", dxl_id, bits)

    def set_item(self, dxl_id: int, name: str, value: int) -> None:
        """Firmware-side write (no access rules), e.g. set_item(1, "Present Position", 100)."""
        self.command("set_item", dxl_id, name, value)

    def item(self, dxl_id: int, name: str) -> int:
        """Firmware-side read of an item's decoded value."""
        return self.command("item", dxl_id, name)

    def in_shutdown(self, dxl_id: int) -> bool:
        return self.command("in_shutdown", dxl_id)

    def set_silenced(self, dxl_id: int, silenced: bool = True) -> None:
        """Device-side silence (dead electronics): hears nothing, answers nothing."""
        self.command("set_silenced", dxl_id, silenced)

    def faults(self, **fields: Any) -> None:
        """Set `LineFaults` fields, e.g. faults(silent_ids={2}, corrupt_next_replies=1)."""
        self.command("faults", **fields)

    def clear_faults(self) -> None:
        self.command("clear_faults")

    def stats(self) -> dict[str, int]:
        """Line and parser counters (bytes, replies, CRC errors, byte timeouts, ...)."""
        return self.command("stats")

    def fault_counts(self) -> dict[str, int]:
        """How often each line fault fired so far (`FaultCounts`: replies_dropped,
        replies_corrupted, instructions_unheard): a test asserts its fault really happened."""
        return self.command("fault_counts")

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the child (politely, then by force). Safe to call twice."""
        if self._process.is_alive():
            with suppress(OSError):
                self._conn.send(("stop", (), {}))
            self._process.join(timeout_s)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(timeout_s)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout_s)
        self._conn.close()


@contextmanager
def spawn_emulated_chain(
    ids: Sequence[int] = (1, 2),
    baud_index: int = 6,
    realtime: bool = False,
    firmware: str = "ideal",
    eeprom_overrides: Mapping[Any, Any] | None = None,
    *,
    enforce_baud: bool = False,
    reboot_time_s: float = DEFAULT_REBOOT_TIME_S,
    firmware_version: int = DEFAULT_FIRMWARE_VERSION,
    realtime_scheduling: bool = True,
    start_timeout_s: float = 20.0,
    models: str | Mapping[int, str] = DEFAULT_MODEL,
) -> Iterator[EmulatedChain]:
    """Start an emulated chain in a child process; yield its handle; always stop it.

    models: every device's model (an e-Manual name, e.g. "H42-20-S300-R(A)"), or {id: model}
    (IDs not named: the H54-200-S500-R).
    ids: the device IDs on the line. baud_index: Baud Rate (8) of every device (6 = 4 Mbps;
    the SDK must then use setBaudRate(4_000_000) if enforce_baud is on, or for realtime timing).
    realtime: reply at wire-model times instead of at once. eeprom_overrides: {name: value} for
    every device or {id: {name: value}} per device, e.g. {"Return Delay Time": 0}.
    realtime_scheduling: run the child under SCHED_FIFO when permitted (it then answers within
    ~0.1 ms far more reliably on a loaded machine; see `request_realtime_scheduling`);
    `stats()["sched_fifo"]` says whether it was granted.
    """
    if firmware not in FIRMWARES:
        raise ValueError(f"firmware must be one of {FIRMWARES}, got {firmware!r}")
    options = EmulatorOptions(
        ids=tuple(int(i) for i in ids),
        baud_index=baud_index,
        realtime=realtime,
        firmware=firmware,
        eeprom_overrides={
            k: (dict(v) if isinstance(v, Mapping) else v)
            for k, v in (eeprom_overrides or {}).items()
        },
        enforce_baud=enforce_baud,
        reboot_time_s=reboot_time_s,
        firmware_version=firmware_version,
        realtime_scheduling=realtime_scheduling,
        models=(
            dict.fromkeys((int(i) for i in ids), models)
            if isinstance(models, str)
            else {int(k): str(v) for k, v in models.items()}
        ),
    )
    context = multiprocessing.get_context("spawn")
    parent_conn, child_conn = context.Pipe()
    process = context.Process(
        target=_child_main, args=(child_conn, options), name="dxl-emulator", daemon=True
    )
    process.start()
    child_conn.close()
    handle: EmulatedChain | None = None
    try:
        if not parent_conn.poll(start_timeout_s):
            raise TimeoutError(
                f"emulator process did not start within {start_timeout_s} s "
                f"(alive: {process.is_alive()}, exit code {process.exitcode})"
            )
        try:
            status, result = parent_conn.recv()
        except EOFError:
            process.join(5.0)
            raise EmulatorCommandError(
                f"emulator process exited during start-up (exit code {process.exitcode}); "
                "with the 'spawn' start method the parent's __main__ must be an importable "
                "file (not stdin or -c); see the child's traceback above"
            ) from None
        if status != "ok":
            raise EmulatorCommandError(f"emulator could not start: {result}")
        handle = EmulatedChain(process, parent_conn, result)
        yield handle
    finally:
        if handle is not None:
            handle.stop()
        else:
            process.kill()
            process.join(5.0)
            parent_conn.close()
