"""The emulator process: the virtual testbed served on its two buses until interrupted.

One single-threaded event loop owns everything, so nothing depends on thread scheduling:

    the Dynamixel chain    a pty speaking Protocol 2.0 (`DynamixelLine`)
    the CAN segment        link-encoder nodes (+ the force sensor) behind an emulated serial-line
                           CAN adapter on a second pty (`SlcanPty`; python-can's `slcan`)
    the physics            one MuJoCo plant per joint behind its H54 firmware (`VirtualTestbed`)

Clocks:
- lockstep: the plant advances exactly one loop period per CAN SYNC it receives (the first SYNC
  samples t = 0). Before stepping, the loop drains the Dynamixel line, so the goals the host
  wrote before that SYNC act over the period that follows it: a run is deterministic whatever the
  machine's load. The host must read the Dynamixel state only after the SYNC's TPDOs arrived
  (our driver does).
- realtime: the plant follows the wall clock (1 ms physics steps), the Dynamixel line models wire
  time and Return Delay Time, nothing waits for SYNC: the emulated testbed behaves like the
  hardware, for ROBOTIS's SDK or any other client.

The first line on stdout is one JSON object telling a host how to reach the buses.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import select
import signal
import sys
import time
from typing import Any, TextIO

import can

from sim_backend.canbus import CanSegment, SlcanPty
from sim_backend.dynamixel import (
    DynamixelChain,
    DynamixelLine,
)
from sim_backend.hardware import sensor_nodes
from sim_backend.robots import build_hardware
from sim_backend.scenario import FaultSchedule
from sim_backend.spec import (  # re-exported: the emulator's spec is built by hil
    CLOCKS,
    ROBOTS,
    EmulatedJointSpec,
    EmulatorSpec,
    HumanoidSpec,
    SensorNoise,
)
from sim_backend.truth_log import TruthLog

__all__ = [
    "CLOCKS",
    "ROBOTS",
    "EmulatedJointSpec",
    "Emulator",
    "EmulatorSpec",
    "HumanoidSpec",
    "SensorNoise",
    "serve",
]

SYNC_COB_ID = 0x080
IDLE_WAIT_S = 0.05  # the longest the loop sleeps in select() with nothing due (stop() wakes it)
MAX_PHYSICS_STEPS_PER_TURN = 2  # realtime: physics between two looks at the buses (1 ms steps)


class Emulator:
    """The virtual testbed on its buses. `run()` serves until `stop()` or a signal."""

    def __init__(self, spec: EmulatorSpec) -> None:
        self.spec = spec
        self.realtime = spec.clock == "realtime"
        self.hardware = build_hardware(spec)
        self.devices = self.hardware.devices
        self.encoders = self.hardware.encoders
        nodes = sensor_nodes(self.hardware)
        self.testbed = self.hardware
        # one chain and one pty per RS-485 chain of the spec, its joints' devices on it
        self.chains = [
            DynamixelChain(
                [d for d, j in zip(self.devices, spec.joints, strict=True) if j.chain == chain],
                enforce_baud=True,
            )
            for chain in range(len(spec.chain_bauds))
        ]
        self.lines = [
            DynamixelLine(
                chain,
                realtime=self.realtime,
                adapter_latency_s=spec.usb_latency_timer_s if self.realtime else 0.0,
                hold_reads=not self.realtime,
            )
            for chain in self.chains
        ]
        self.chain, self.line = self.chains[0], self.lines[0]  # the first (one-chain robots)
        self.segment = CanSegment(nodes, bitrate=spec.can_bitrate)
        self.slcan = SlcanPty(bus_bitrate=spec.can_bitrate)
        # The nodes were powered before any host connected: their power-on boot-ups go out now,
        # to the closed channel (later, one could pass for the answer to a host's first reset).
        self.slcan.send_frames(self.segment.poll(self._node_time()))
        self.sync_count = 0
        self._node_faults_changed = False
        self.fault_schedule = FaultSchedule(spec.scenario.faults, len(spec.joints))
        # False once stop() was called, even before run(): a host's SIGTERM may come right
        # after the endpoints line, before the loop starts, and must end it all the same
        self._running = True
        # stop() (a signal handler) writes here: the loop's select wakes at once instead of at
        # its next timeout (up to 50 ms, which every run's end waited for)
        self._wake_read, self._wake_write = os.pipe()
        os.set_blocking(self._wake_read, False)
        os.set_blocking(self._wake_write, False)
        self.truth = TruthLog(spec.truth_log, self.hardware.truth_columns, self.hardware.truth_row)
        self._wall_origin = time.monotonic()
        self._step_cost_s = 0.0  # realtime: what a physics step takes here (a running mean)

    # --- what a host needs -----------------------------------------------------------------
    def endpoints(self) -> dict[str, Any]:
        return {
            "dynamixel_port": self.line.port_path,
            "baudrate": self.spec.baudrate,
            "ids": [j.dxl_id for j in self.spec.joints],
            # every chain, in the spec's order (the first is dynamixel_port's)
            "dynamixel_ports": [line.port_path for line in self.lines],
            "baudrates": list(self.spec.chain_bauds),
            "can": {
                "interface": "slcan",
                "channel": self.slcan.port_path,
                "bitrate": self.spec.can_bitrate,
                "sleep_after_open": 0,
                # python-can's slcan reads its serial port with this timeout: every empty read
                # blocks this long, and 0 makes every waiting client (canopen's Notifier, any
                # recv loop) spin a core (measured: an idle canopen client used 49-59 % of a
                # core with 0, 4.6 % with 0.001, 1.5 % with 0.01, where an empty poll costs
                # 0.02, 1.1 and 9 ms). 0.001 is python-can's own default. Our driver does not
                # depend on it: it waits in select() on the port (drivers/canbus).
                "timeout": 0.001,
            },
            "encoder_node_ids": [j.encoder_node_id for j in self.spec.joints],  # 0: none
            "force_sensor_node_id": self.spec.force_sensor_node_id or None,
            "clock": self.spec.clock,
            "period_s": self.spec.period_s,
            "seed": self.spec.seed,
        }

    def fault_counts(self) -> dict[str, Any]:
        """How often each injected fault acted: a run can show that every fault it injected
        really happened. Scenario fault events are numbered as in `spec.scenario.faults`."""
        return {
            "scenario_faults_started": [
                number for number, fired in enumerate(self.fault_schedule.fired) if fired
            ],
            "dynamixel": _summed([dataclasses.asdict(c.faults.fired) for c in self.chains]),
            "encoders": {
                str(node.node_id): dataclasses.asdict(node.fault_counts) for node in self.encoders
            },
        }

    # --- the event loop --------------------------------------------------------------------
    def stop(self, *_: object) -> None:
        self._running = False
        with contextlib.suppress(OSError):  # full (a stop is pending already) or closed
            os.write(self._wake_write, b"\0")

    def run(self) -> None:
        lines, slcan = self.lines, self.slcan
        fds = [slcan.fileno(), *(line.fileno() for line in lines), self._wake_read]
        next_physics = time.monotonic()
        while self._running:
            now = time.monotonic()
            timeout = IDLE_WAIT_S
            due = self._next_line_due_s()
            if due is not None:
                timeout = min(timeout, max(0.0, due - now))
            can_due = self.segment.next_due_s()  # boot-up, heartbeat: on the nodes' clock
            if can_due is not None:
                timeout = min(timeout, max(0.0, can_due - self._node_time()))
            if self.realtime:
                timeout = min(timeout, max(0.0, next_physics - now))
            try:
                readable, _, _ = select.select(fds, [], [], timeout)
            except InterruptedError:
                continue
            if self._wake_read in readable:
                with contextlib.suppress(BlockingIOError):
                    os.read(self._wake_read, 64)
            # CAN first: a SYNC must step the plant before a later Dynamixel read is answered.
            if slcan.fileno() in readable:
                self._on_host_frames(slcan.read_frames(flush=False))
            for line in lines:
                if line.fileno() in readable:
                    line.on_readable()
                else:
                    line.on_idle()
            if any(line.holds_reads for line in lines):
                # lock-step: a SYNC sent before the read steps the plant first
                self._on_host_frames(slcan.read_frames(flush=False))
                for line in lines:
                    if line.holds_reads:
                        line.release_held_reads()
            for line in lines:
                line.flush_due()
            if self.realtime:
                next_physics = self._follow_wall_clock()
            # the nodes' own frames (boot-up, heartbeat) and their reaction to a changed fault;
            # otherwise a poll would find nothing to do
            node_time = self._node_time()
            due = self.segment.next_due_s()
            if self._node_faults_changed or (due is not None and due <= node_time):
                every_node = self._node_faults_changed  # (a changed fault acts on a poll)
                self._node_faults_changed = False
                slcan.send_frames(self.segment.poll(node_time, due_only=not every_node))

    def _next_line_due_s(self) -> float | None:
        """The soonest any chain's line needs attention (None: none does)."""
        due = [t for line in self.lines if (t := line.next_due_s()) is not None]
        return min(due) if due else None

    def _on_host_frames(self, frames: list[can.Message]) -> None:
        """The host's frames on the bus; the adapter's answers and the nodes' replies go back
        in one write (one wake-up of the host per SYNC, not one per frame)."""
        replies: list[can.Message] = []
        for frame in frames:
            if frame.arbitration_id == SYNC_COB_ID and not frame.is_remote_frame:
                self._on_sync()
            replies += self.segment.deliver(frame, self._node_time())
        self.slcan.send_frames(replies)

    def _on_sync(self) -> None:
        if self.sync_count == 0:
            self.testbed.start_scenario()
        if self.realtime:  # the encoders latch now, between two physics steps
            self.hardware.sample_instant.after_step_s = self._time_past_last_step()
        else:
            for line in self.lines:  # goals written before this SYNC act over the coming period
                line.drain()
            if self.sync_count > 0:
                self.testbed.advance(self.spec.period_s)
        self.truth.write(self.sync_count, self.testbed.time_s)
        self.sync_count += 1
        self._apply_faults()

    def _follow_wall_clock(self) -> float:
        """Step the plant up to the wall clock; returns when the next step is due."""
        dt = self.testbed.physics_timestep_s
        if self.sync_count == 0 and self.hardware.held_until_started:
            self._wall_origin = time.monotonic() - self.testbed.time_s  # still in its gantry
            return self._wall_origin + self.testbed.time_s + dt
        elapsed = time.monotonic() - self._wall_origin
        behind = elapsed - self.testbed.time_s
        if behind > 0.1:  # we were stopped (debugger, suspended): do not replay the gap
            self._wall_origin += behind - dt
            behind = dt
        if behind >= dt:
            # a few steps per turn of the event loop, so the buses are served between them
            # even when the plant cannot keep up with the wall clock (12 joints on a loaded
            # machine): replies stay on time, the state they report lags instead
            steps = min(math.floor(behind / dt), MAX_PHYSICS_STEPS_PER_TURN)
            reply_due = self._next_line_due_s()
            start = time.monotonic()
            if reply_due is not None and reply_due - start < steps * self._step_cost_s:
                return reply_due  # a reply falls due first: out with it, then the steps
            self.testbed.advance(steps * dt)
            cost = (time.monotonic() - start) / steps
            self._step_cost_s += (cost - self._step_cost_s) / 8  # (a running mean)
            self._apply_faults()
        return self._wall_origin + self.testbed.time_s + dt

    def _time_past_last_step(self) -> float:
        """Wall time since the plant's last step, at most one step (behind by more, the
        plant is lagging: extrapolating further would invent motion)."""
        dt = self.testbed.physics_timestep_s
        if self.sync_count == 0 and self.hardware.held_until_started:
            return 0.0  # still in its gantry: the plant does not follow the wall clock
        past = time.monotonic() - self._wall_origin - self.testbed.time_s
        return min(max(past, 0.0), dt)

    def _node_time(self) -> float:
        return time.monotonic()

    # --- faults ----------------------------------------------------------------------------
    def _apply_faults(self) -> None:
        if not self.fault_schedule.faults and self.sync_count > 1:
            return  # no fault injected: the first SYNC's application holds for the run
        active = self.fault_schedule.at(self.testbed.scenario_time_s)
        joints = self.spec.joints
        for chain, line_chain in enumerate(self.chains):
            faults = line_chain.faults
            mine = {j for j, joint in enumerate(joints) if joint.chain == chain}
            faults.drop_next_replies += sum(1 for j in active.drop_next if j in mine)
            faults.corrupt_next_replies += sum(1 for j in active.corrupt_next if j in mine)
            for target, chosen in (
                (faults.silent_ids, active.silent),
                (faults.drop_reply_ids, active.dropped),
                (faults.corrupt_crc_ids, active.corrupted),
            ):
                target.clear()
                target.update(joints[j].dxl_id for j in chosen if j in mine)
        sensed = [j for j, joint in enumerate(joints) if joint.encoder_node_id]  # the nodes'
        for node, mode, noise in zip(
            self.encoders,
            [active.encoder_mode[j] for j in sensed],
            [active.encoder_noise_counts_rms[j] for j in sensed],
            strict=True,
        ):
            if node.fault.mode != mode or node.fault.noise_counts_rms != noise:
                node.fault.mode = mode
                node.fault.noise_counts_rms = noise
                self._node_faults_changed = True

    def close(self) -> None:
        self.truth.close()
        for line in self.lines:
            line.close()
        self.slcan.close()
        for fd in (self._wake_read, self._wake_write):
            with contextlib.suppress(OSError):
                os.close(fd)


def _summed(counts: list[dict[str, int]]) -> dict[str, int]:
    """Per-key sums of the chains' fault counters."""
    return {key: sum(count[key] for count in counts) for key in counts[0]}


def serve_spec_file(path: str) -> int:
    """`python -m sim_backend --spec-file PATH`, and each emulator the fork server starts for
    `hil run` (sim_backend/fork_server.py): serve the spec `spec_to_json` wrote, loading nothing
    but sim_backend (the CLI's imports cost seconds of every run's start-up). Exit status as
    the `hil` command's: 0, or 1 with the reason."""
    from sim_backend.spec_json import spec_from_json

    try:
        with open(path, encoding="utf-8") as spec_file:
            spec = spec_from_json(spec_file.read())
        serve(spec)
    except KeyboardInterrupt:
        print("hil: interrupted", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - as `hil`: the reason, not a traceback
        print(f"hil emulate: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


def serve(spec: EmulatorSpec, out: TextIO = sys.stdout, extra: dict | None = None) -> None:
    """Build the emulator, print its endpoints as one JSON line, serve until SIGINT/SIGTERM,
    then print one more JSON line, {"fault_counts": Emulator.fault_counts()}."""
    emulator = Emulator(spec)
    previous = {sig: signal.signal(sig, emulator.stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        out.write(json.dumps({**emulator.endpoints(), **(extra or {})}) + "\n")
        out.flush()
        emulator.run()
        with contextlib.suppress(OSError, ValueError):  # nobody reads any more: fine
            out.write(json.dumps({"fault_counts": emulator.fault_counts()}) + "\n")
            out.flush()
    finally:
        emulator.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
