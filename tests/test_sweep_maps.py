"""Tests of sweep maps and the cells table, on made-up sweep directories (no simulation)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import matplotlib.image as mpimg
import pytest

from walkrepro.studies.sweep import store
from walkrepro.studies.sweep.cells import CellResult
from walkrepro.studies.sweep.grid import Axis, Cell
from walkrepro.studies.sweep.maps import plot_sweep


def _fake_sweep(directory: Path, axes: list[Axis]) -> list[Cell]:
    """A sweep directory whose cells fall above 0.04 and error at one cell."""
    fields = [a.field for a in axes]
    info = {
        "experiment": "fake",
        "title": "fake (walkrepro): a claim about the fake map",
        "grid": [{"field": a.field, "values": list(a.values), "unit": "m"} for a in axes],
        "map_metric": "peak",
        "n_cells": math.prod(len(a.values) for a in axes),
        "columns": store.columns(fields, ["fell", "peak"]),
    }
    directory.mkdir(parents=True)
    store.write_info(directory, info)
    writer = store.CellsWriter(directory / store.CELLS_FILE, info["columns"])
    cells = []
    for k, combo in enumerate(itertools.product(*(a.values for a in axes))):
        cell = Cell(k, tuple(zip(fields, combo, strict=True)), (), None)
        falls = combo[0] > 0.04
        outcome = "error" if k == 1 else ("fell" if falls else "complete")
        result = CellResult(
            k,
            outcome,
            "boom" if k == 1 else "",
            fall_time=2.5 if falls else math.nan,
            metrics={} if k == 1 else {"fell": float(falls), "peak": 100.0 * k},
        )
        writer.append(cell, result)
        cells.append(cell)
    writer.close()
    return cells


@pytest.mark.parametrize(
    "axes",
    [
        [Axis("h", (0.02, 0.04, 0.06))],
        [Axis("h", (0.02, 0.04, 0.06)), Axis("tilt", (0, 10))],
        [Axis("h", (0.02, 0.04, 0.06)), Axis("tilt", (0, 10)), Axis("impedance", (True, False))],
    ],
)
def test_maps_are_drawn_for_one_two_and_three_fields(tmp_path: Path, axes: list[Axis]) -> None:
    """A line plot, a heat map and a panel per extra value are written as PNG and SVG."""
    directory = tmp_path / "sweep"
    _fake_sweep(directory, axes)
    written = plot_sweep(directory)
    assert [p.name for p in written] == ["map.png", "map.svg"]
    height, width, _ = mpimg.imread(written[0]).shape
    assert width > 500 and height > 300


def test_cells_table_round_trips_values_exactly(tmp_path: Path) -> None:
    """Grid values and metrics read back as written: booleans, ints and exact floats."""
    directory = tmp_path / "sweep"
    _fake_sweep(directory, [Axis("h", (0.1 + 0.2, 0.04)), Axis("impedance", (True, False))])
    table = store.read_cells(directory / store.CELLS_FILE)
    assert table.fields == ("h", "impedance")
    assert table.column("h") == [0.1 + 0.2, 0.1 + 0.2, 0.04, 0.04]
    assert table.column("impedance") == [True, False, True, False]
    assert table.rows[1]["outcome"] == "error" and math.isnan(table.rows[1]["peak"])
    assert table.column("peak")[3] == 300.0


def test_exponent_floats_round_trip_as_floats(tmp_path: Path) -> None:
    """A value JSON writes with an exponent only (5e-05) reads back as that float, not as
    the string YAML 1.1 would make of it (which broke --resume and the claims' selectors)."""
    directory = tmp_path / "sweep"
    _fake_sweep(directory, [Axis("lag", (5e-05, 0.0005)), Axis("impedance", (True, False))])
    assert "5e-05" in (directory / store.CELLS_FILE).read_text()
    table = store.read_cells(directory / store.CELLS_FILE)
    assert table.column("lag") == [5e-05, 5e-05, 0.0005, 0.0005]


def test_a_declared_success_region_sets_the_drawn_boundary() -> None:
    """With ``success:`` a cell that stood but missed the region is outside; without it, only falls are."""
    from walkrepro.studies.sweep.maps import _boundary_label, _inside

    success = {"metric": "stepped_on_off:right_foot", "op": "==", "value": 1}
    stood_slid = {"outcome": "complete", "fell": 0.0, "stepped_on_off:right_foot": 0.0}
    stepped = {**stood_slid, "stepped_on_off:right_foot": 1.0}
    assert _inside(stood_slid, None) is True
    assert _inside(stood_slid, success) is False and _inside(stepped, success) is True
    assert _inside({"outcome": "error"}, success) is None
    assert "stepped_on_off:right_foot == 1" in _boundary_label(success)


def test_a_reference_copy_of_the_cells_is_in_cell_order(tmp_path: Path) -> None:
    """Cells finished out of order (two jobs) are copied in cell order, values unchanged,
    and a torn last line is dropped; the sweep's own file keeps its finish order."""
    source, target = tmp_path / "cells.csv", tmp_path / "ref.csv"
    source.write_text("cell,h,outcome\n2,0.3,complete\n0,0.1,fell\n1,0.2,complete\n3,0.")
    store.copy_cells_sorted(source, target)
    assert target.read_text() == "cell,h,outcome\n0,0.1,fell\n1,0.2,complete\n2,0.3,complete\n"
    assert source.read_text().startswith("cell,h,outcome\n2,")


def test_a_map_labels_the_metric_with_its_value_unit_not_its_arguments() -> None:
    """A unit in the argument's parenthesis ("push time [s]") is not the value's unit."""
    from walkrepro.studies.sweep.maps import _metric_label

    assert _metric_label("recovery_steps:4.0") == "recovery_steps:4.0"
    assert _metric_label("mean_forward_speed:2-4") == "mean_forward_speed:2-4 [m/s]"
    assert _metric_label("max_footstep_adjustment") == "max_footstep_adjustment [m]"
