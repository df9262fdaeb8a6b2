"""Device units -> SI for the CAN sensors: the one place each conversion happens."""

from __future__ import annotations

import numpy as np

# RLS RLC2IC read head on an MR075 magnetic ring: 120 poles x 8192 counts per pole (RLS data
# sheets RLCD02 / MRD01). The testbed's and DYROS-JET's link encoders.
RLC2IC_MR075_COUNTS_PER_REV = 120 * 8192  # 983,040


def link_angle_rad_from_counts(
    raw_counts: np.ndarray | int,
    counts_per_rev: np.ndarray | int,
    direction: np.ndarray | int,
    offset_rad: np.ndarray | float,
    single_turn: np.ndarray | bool = False,
) -> np.ndarray | float:
    """Encoder count -> link angle (rad): the one place this conversion happens.

    offset_rad is the encoder's own reading (in rad) when the link is at its zero, the same
    convention as the actuator's motor_offset_rad (drivers/dynamixel/units.py):

        angle = direction * (2*pi * c / counts_per_rev - offset_rad)

    with c the signed count; for a single-turn device (count in [0, N)) c is first wrapped into
    [-N/2, N/2), so the link may move within +-half a turn of the encoder's zero.
    Works element-wise on numpy arrays.
    """
    counts = np.asarray(raw_counts, dtype=np.float64)
    per_rev = np.asarray(counts_per_rev, dtype=np.float64)
    if np.any(single_turn):  # (no multi-turn encoder needs the wrap)
        wrapped = np.mod(counts + per_rev // 2, per_rev) - per_rev // 2
        counts = np.where(single_turn, wrapped, counts)
    angle = np.asarray(direction) * ((2.0 * np.pi) * counts / per_rev - offset_rad)
    return float(angle) if np.ndim(angle) == 0 else angle


def force_n_from_counts(
    raw: int, newtons_per_count: float, direction: int, offset_n: float
) -> float:
    """Force-sensor process value -> force (N): direction * raw * newtons_per_count - offset_n."""
    return direction * raw * newtons_per_count - offset_n


def wrench_from_counts(
    raw: np.ndarray,
    si_per_count: np.ndarray,
    force_offset_n: np.ndarray,
    torque_offset_nm: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Six force/torque process values -> (force [N], moment [N m]), tare removed:
    value = raw * si_per_count - offset, channels Fx Fy Fz Mx My Mz."""
    values = np.asarray(raw, dtype=np.float64) * si_per_count
    return values[:3] - force_offset_n, values[3:] - torque_offset_nm
