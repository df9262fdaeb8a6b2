"""Configuration of the CAN sensors: one frozen dataclass per node, validated on creation."""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.canbus.units import RLC2IC_MR075_COUNTS_PER_REV


@dataclass(frozen=True)
class LinkEncoderConfig:
    """One joint's link encoder on CAN.

    node_id: CANopen node ID (1..127). counts_per_rev: must equal the node's 0x6001.
    offset_rad: the encoder's reading (rad, before `direction`) when the link is at its zero:
        angle = direction * (reading - offset_rad), as for the actuator's motor offset.
    direction: +1 or -1, the sign between the encoder's count and the joint's angle.
    stale_after_s: age beyond which the last value must not be used (`LinkReading.stale`).
    heartbeat_ms: producer heartbeat time written to 0x1017 (0 = no heartbeat).
    tpdo: which TPDO (1..4) carries the position; CiA 406 devices use TPDO1 or TPDO2.
    name: the joint it measures (for messages and for a bus's joint layout).
    """

    node_id: int
    counts_per_rev: int = RLC2IC_MR075_COUNTS_PER_REV
    offset_rad: float = 0.0
    direction: int = +1
    stale_after_s: float = 0.02
    heartbeat_ms: int = 100
    tpdo: int = 1
    name: str = ""

    def __post_init__(self) -> None:
        _check_common(
            self.node_id, self.direction, self.stale_after_s, self.heartbeat_ms, self.tpdo
        )
        if not 1 <= self.counts_per_rev <= 0xFFFF_FFFF:
            raise ValueError(f"counts_per_rev must be 1..2**32-1, got {self.counts_per_rev}")
        if not math.isfinite(self.offset_rad):
            raise ValueError(f"offset_rad must be finite, got {self.offset_rad}")


@dataclass(frozen=True)
class ForceSensorConfig:
    """The contact force sensor on CAN (CiA 404, one analogue input, force in its PV).

    offset_n: the reading (after `direction`) at zero force. Other fields as LinkEncoderConfig.
    """

    node_id: int
    offset_n: float = 0.0
    direction: int = +1
    stale_after_s: float = 0.02
    heartbeat_ms: int = 100
    tpdo: int = 1

    def __post_init__(self) -> None:
        _check_common(
            self.node_id, self.direction, self.stale_after_s, self.heartbeat_ms, self.tpdo
        )
        if not math.isfinite(self.offset_n):
            raise ValueError(f"offset_n must be finite, got {self.offset_n}")


@dataclass(frozen=True)
class ForceTorqueSensorConfig:
    """A six-axis force/torque sensor on CAN (CiA 404, six analogue inputs Fx Fy Fz Mx My Mz).

    The forces come in one TPDO (`force_tpdo`, channels 1-3) and the moments in another
    (`torque_tpdo`, channels 4-6), both answering the same SYNC.
    label: a name for messages and logs (e.g. "left foot").
    force_offset_n / torque_offset_nm: the readings at zero load (a tare), subtracted after
        the unit conversion. Other fields as LinkEncoderConfig.
    """

    node_id: int
    label: str = "force/torque sensor"
    force_offset_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque_offset_nm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    stale_after_s: float = 0.02
    heartbeat_ms: int = 100
    force_tpdo: int = 1
    torque_tpdo: int = 2

    def __post_init__(self) -> None:
        _check_common(self.node_id, +1, self.stale_after_s, self.heartbeat_ms, self.force_tpdo)
        _check_common(self.node_id, +1, self.stale_after_s, self.heartbeat_ms, self.torque_tpdo)
        if self.force_tpdo == self.torque_tpdo:
            raise ValueError("force_tpdo and torque_tpdo must be two different TPDOs")
        for name in ("force_offset_n", "torque_offset_nm"):
            values = getattr(self, name)
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                raise ValueError(f"{name} needs three finite values, got {values}")


def _check_common(
    node_id: int, direction: int, stale_after_s: float, heartbeat_ms: int, tpdo: int
) -> None:
    if not 1 <= node_id <= 127:
        raise ValueError(f"node_id must be a CANopen node ID 1..127, got {node_id}")
    if direction not in (+1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}")
    if not stale_after_s > 0.0:
        raise ValueError(f"stale_after_s must be > 0 s, got {stale_after_s}")
    if not 0 <= heartbeat_ms <= 0xFFFF:
        raise ValueError(
            f"heartbeat_ms must be 0..65535 (0x1017 is UNSIGNED16), got {heartbeat_ms}"
        )
    if tpdo not in (1, 2, 3, 4):
        raise ValueError(f"tpdo must be 1..4 (TPDO number), got {tpdo}")
