"""Tests of a controller's signal declaration as a structured record (walkrepro.log.signals)."""

from __future__ import annotations

import numpy as np
import pytest

from walkrepro.log.signals import SignalLayout, Signals

FOOT = np.dtype([("fz", np.float64), ("refs", np.float64, (3,))])
RECORD = np.dtype([("t_plan", np.float64), ("left", FOOT), ("right", FOOT), ("com", "f8", (2,))])


def test_a_record_declares_its_signals_in_field_order() -> None:
    """Scalars, 1-D arrays and a nested record's fields (named record_field) make the layout,
    in the record's order."""
    layout = SignalLayout.of_record(RECORD)
    assert layout.fields == (
        ("t_plan", 0, False),
        ("left_fz", 0, False),
        ("left_refs", 3, False),
        ("right_fz", 0, False),
        ("right_refs", 3, False),
        ("com", 2, False),
    )
    assert layout.width * 8 == RECORD.itemsize


def test_a_record_written_by_name_is_the_signal_vector() -> None:
    """A record filled field by field, viewed as float64, reads back by the signals' names;
    a field left NaN is not defined at the tick."""
    layout = SignalLayout.of_record(RECORD)
    record = np.full(1, np.nan, dtype=RECORD)
    values = record[0]
    values["t_plan"] = 1.5
    values["left"]["fz"] = 300.0
    values["left"]["refs"] = (0.1, 0.2, 0.3)
    values["com"] = (0.0, -0.05)
    signals = Signals(layout, record.view(np.float64))
    assert dict(signals) == {
        "t_plan": 1.5,
        "left_fz": 300.0,
        "left_refs": [0.1, 0.2, 0.3],
        "com": [0.0, -0.05],
    }


@pytest.mark.parametrize(
    "dtype",
    [
        np.dtype([("k", np.int64)]),  # not a float
        np.dtype([("a", np.float32)]),
        np.dtype([("m", np.float64, (2, 2))]),  # 2-D
        np.dtype({"names": ["a", "b"], "formats": ["f8", "f8"], "offsets": [0, 16]}),  # a gap
        np.dtype({"names": ["a", "b"], "formats": ["f8", "f8"], "offsets": [8, 0]}),  # reordered
        np.dtype([("t", np.float64)]),  # the log's own time
    ],
)
def test_a_record_whose_float_view_would_not_match_is_refused(dtype: np.dtype) -> None:
    """A field that is not float64 (or a 1-D array of it), a gap or a reordering that would
    shift the float64 view, and a reserved name are refused."""
    with pytest.raises(ValueError):
        SignalLayout.of_record(dtype)
