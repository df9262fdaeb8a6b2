"""The log's cells: a per-joint column formatted in one pass (`format_column`) reads exactly as
its cells one by one (`format_value`), for every dtype the loop logs: the CSV of a lock-step run
must not change with how it is written."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hil.output.runlog import format_column, format_value
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
