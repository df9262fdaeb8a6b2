"""The log's cells: a per-joint column formatted in one pass (`format_column`) reads exactly as
its cells one by one (`format_value`), for every dtype the loop logs: the CSV of a lock-step run
must not change with how it is written."""

from __future__ import annotations

import json

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hil.output.channels import BOOL_COLUMNS, INTEGER_COLUMNS
from hil.output.runlog import PER_JOINT_COLUMNS, RunLog, format_column, format_value
from tests.support.fuzzing import examples

SPECIAL = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e-12, 5e-10, -5e-10, 1e300, 0.1 + 0.2])


def _cells(values: np.ndarray) -> list[str]:
    return [format_value(value) for value in values]


def test_special_floats_read_as_before() -> None:
    assert format_column(SPECIAL) == _cells(SPECIAL)
    assert format_column(SPECIAL)[:4] == ["nan", "inf", "-inf", "-0.0"]


@examples(200)
@given(hnp.arrays(np.float64, st.integers(1, 24), elements=st.floats(allow_subnormal=True)))
def test_float_columns(values: np.ndarray) -> None:
    assert format_column(values) == _cells(values)


@examples(200)
@given(
    st.sampled_from([np.bool_, np.int8, np.uint8, np.int32, np.int64, np.uint16]).flatmap(
        lambda dtype: hnp.arrays(dtype, st.integers(1, 24))
    )
)
def test_flag_and_integer_columns(values: np.ndarray) -> None:
    assert format_column(values) == _cells(values)


class _Collect:
    def __init__(self) -> None:
        self.messages: dict[int, list[bytes]] = {}

    def add_channel(self, channel) -> None:
        self.messages[channel.id] = []

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        self.messages[channel_id].append(data)

    def close(self) -> None:
        pass


def _refuse(constant: str) -> None:
    raise ValueError(f"not JSON: {constant}")


def test_the_joints_message_holds_the_rows_values(tmp_path) -> None:
    """/joints is built from the CSV's cells: strict JSON, the log's numbers, flags as
    booleans, a value not read as null."""
    names = ("a", "b", "c")
    sink = _Collect()
    log = RunLog(tmp_path, names, {}, mcap=False, sinks=[sink])
    rng = np.random.default_rng(1)
    joints = []
    for column in PER_JOINT_COLUMNS:
        if column in BOOL_COLUMNS:
            joints.append(np.array([True, False, True]))
        elif column in INTEGER_COLUMNS:
            joints.append(np.array([0, 32, 1], dtype=np.int64))
        else:
            joints.append(np.array([rng.normal(), np.nan, -np.inf]))
    log.write_row(7, 0.035, [1.5], "ok", "experiment", 0, joints, 0.001, 0.005)
    log.close()
    message = json.loads(sink.messages[log.channels.joints.id][0], parse_constant=_refuse)
    assert (message["tick"], message["time_s"]) == (7, 0.035)
    for column, values in zip(PER_JOINT_COLUMNS, joints, strict=True):
        if column in BOOL_COLUMNS:
            assert message[column] == [True, False, True]
        elif column in INTEGER_COLUMNS:
            assert message[column] == [0, 32, 1]
        else:
            assert message[column] == [round(float(values[0]), 9), None, None]
