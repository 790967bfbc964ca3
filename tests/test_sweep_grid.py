"""Tests of the sweep grid: parsing FIELD=VALUES, ranges, sweep parameters, and cell validation."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from walkrepro import EXPERIMENTS_DIR
from walkrepro.errors import WalkreproError
from walkrepro.specs.sweeps import Affine
from walkrepro.studies.sweep.grid import Axis, parse_grid_item, parse_values, plan_cells, unit_of


def test_comma_list_parses_each_item_as_yaml() -> None:
    """A comma list gives numbers, booleans and names as YAML would read them."""
    assert parse_grid_item("controller.params.kp=300, 400").values == (300, 400)
    assert parse_grid_item("controller.params.impedance=true,false").values == (True, False)
    assert parse_grid_item("sim.duration=0.5").values == (0.5,)


def test_range_is_inclusive_and_evenly_spaced() -> None:
    """start:stop:count includes both ends and has count values, free of float fuzz."""
    assert parse_values("0.02:0.06:3", "x") == (0.02, 0.04, 0.06)
    assert parse_values("0:1:5", "x") == (0.0, 0.25, 0.5, 0.75, 1.0)
    assert parse_values("60:20:3", "x") == (60.0, 40.0, 20.0)


@pytest.mark.parametrize(
    ("item", "words"),
    [
        ("sim.duration", "expected FIELD=VALUES"),
        ("=1,2", "empty field"),
        ("sim.duration=1,,2", "empty value"),
        ("sim.duration=1:2", "bad range"),
        ("sim.duration=1:2:1", "whole number >= 2"),
        ("sim.duration=1:2:x", "whole number >= 2"),
        ("sim.duration=a:2:3", "bad range"),
        ("sim.duration=1:1:3", "start and stop are equal"),
        ("sim.duration=1,1", "repeated"),
        ("sim.duration=[1,2]", "not a single number"),
    ],
)
def test_malformed_grid_items_are_user_errors(item: str, words: str) -> None:
    """Each malformed --grid item raises a WalkreproError that says what is wrong."""
    with pytest.raises(WalkreproError, match=words.replace("[", r"\[")):
        parse_grid_item(item)


def test_cells_are_the_cartesian_product_first_axis_slowest() -> None:
    """Two axes of 2 give 4 cells in row-major order, each with its override applied."""
    axes = [
        parse_grid_item("sim.duration=0.2,0.3"),
        parse_grid_item("controller.params.kp=300,400"),
    ]
    cells = plan_cells("stand_dyros_red", axes)
    assert [c.index for c in cells] == [0, 1, 2, 3]
    assert [(c.spec.sim.duration, c.spec.controller.params["kp"]) for c in cells] == [
        (0.2, 300),
        (0.2, 400),
        (0.3, 300),
        (0.3, 400),
    ]


def test_list_elements_are_sweepable() -> None:
    """A list element path (an obstacle's tilt) can be a grid field, as with --set."""
    cells = plan_cells("obstacle_4cm", [parse_grid_item("world.obstacles.0.tilt_x_deg=0,10")])
    assert [c.spec.world.obstacles[0].tilt_x_deg for c in cells] == [0.0, 10.0]


@pytest.mark.parametrize(
    ("item", "words"),
    [
        ("controller.params.kpp=300,400", "unknown field"),
        ("sim.duratoin=1,2", "unknown field"),
        ("sim.duration=1,-1", "greater than 0"),
        ("controller.params.kp=300,abc", "valid number"),
        ("world.obstacles.0.size.2=0.1", "no list item"),
        ("nosuchthing=1,2", "unknown sweep field"),
    ],
)
def test_a_bad_cell_fails_before_anything_runs(item: str, words: str) -> None:
    """A bad field or value in any cell fails planning, naming the cell and the field."""
    with pytest.raises(WalkreproError, match=words):
        plan_cells("stand_dyros_red", [parse_grid_item(item)])


def test_sweep_parameter_sets_several_fields_affinely(tmp_path: Path) -> None:
    """A declared sweep parameter sets each of its fields to scale·x + offset."""
    spec = yaml.safe_load((EXPERIMENTS_DIR / "obstacle_4cm.yaml").read_text())
    # Replaces the spec's own sweep parameters (a second `sweep_parameters:` key is an error).
    spec["sweep_parameters"] = {
        "block_height": {
            "unit": "m",
            "sets": {
                "world.obstacles.0.size.2": 1,
                "world.obstacles.0.position.2": {"scale": 0.5, "offset": 0.001},
            },
        }
    }
    path = tmp_path / "obstacle_4cm.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    cells = plan_cells(path, [Axis("block_height", (0.02, 0.06))])
    boxes = [c.spec.world.obstacles[0] for c in cells]
    assert [b.size[2] for b in boxes] == [0.02, 0.06]
    assert [b.position[2] for b in boxes] == [0.011, 0.031]
    assert cells[0].spec.sweep_parameters == {}  # a cell's run never sees the sweep sections
    assert unit_of("block_height", {"block_height": type("P", (), {"unit": "m"})()}) == "m"
    with pytest.raises(WalkreproError, match="must be numbers"):
        plan_cells(path, [Axis("block_height", (True,))])


def test_affine_rounds_to_twelve_digits() -> None:
    """scale·x + offset is rounded so 0.1·3 is 0.3 in the spec, not 0.30000000000000004."""
    assert Affine(scale=0.1).apply(3) == 0.3


def test_units_come_from_field_names() -> None:
    """Axis units follow the spec's naming: forces in N, times in s, tilts in degrees."""
    assert unit_of("disturbances.0.force.0") == "N"
    assert unit_of("disturbances.0.start") == "s"
    assert unit_of("world.obstacles.0.tilt_x_deg") == "deg"
    assert unit_of("controller.params.kp") == ""
