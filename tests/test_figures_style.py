"""The shared figure style: titles, legends, E-FSM states by name, yes/no maps, fall messages."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import to_rgb  # noqa: E402

from walkrepro.present.figures import style  # noqa: E402
from walkrepro.studies.sweep import store  # noqa: E402
from walkrepro.studies.sweep.cells import CellResult  # noqa: E402
from walkrepro.studies.sweep.grid import Cell  # noqa: E402
from walkrepro.studies.sweep.maps import plot_sweep  # noqa: E402


def test_title_names_the_paper_the_figure_and_the_experiment() -> None:
    """A figure title reads "<paper>, <figure>: <what>" with the experiment below it."""
    fig = plt.figure()
    style.title(fig, "lee2021", "Fig. 7", "CoM and foot motion", "forward_walk")
    assert fig._suptitle.get_text() == "Lee et al. 2021, Fig. 7: CoM and foot motion\nforward_walk"
    style.title(fig, "walkrepro", "", "run overview")
    assert fig._suptitle.get_text() == "walkrepro: run overview"
    plt.close(fig)


def test_legend_sits_outside_the_axes() -> None:
    """The legend is anchored right of the axes (x > 1 in axes coordinates), off the data."""
    fig, ax = plt.subplots()
    style.legend(ax)
    assert ax.get_legend() is None  # nothing labelled, no empty legend box
    ax.plot([0, 1], [0, 1], label="line")
    style.legend(ax)
    anchor = ax.get_legend().get_bbox_to_anchor().transformed(ax.transAxes.inverted())
    assert anchor.x0 > 1.0
    plt.close(fig)


def test_efsm_states_are_named_in_cycle_order() -> None:
    """E-FSM phase codes (0 SSD, 1 SSA, 2 DS) are drawn on a DS < SSD < SSA axis, by name."""
    fig, ax = plt.subplots()
    t = np.array([0.0, 0.1, 0.2, 0.3])
    style.efsm_states(ax, t, np.array([2.0, 0.0, 1.0, 2.0]))
    assert [tick.get_text() for tick in ax.get_yticklabels()] == ["DS", "SSD", "SSA"]
    (line,) = ax.get_lines()
    assert list(line.get_ydata()) == [0.0, 1.0, 2.0, 0.0]
    plt.close(fig)


def _binary_sweep(directory: Path, metric: str) -> None:
    """A 2 × 2 sweep whose cells fell at h = 0.06 (``fell``) and carry ``peak``."""
    info = {
        "experiment": "fake",
        "title": "fake (walkrepro): a claim",
        "grid": [
            {"field": "h", "values": [0.02, 0.06], "unit": "m"},
            {"field": "tilt", "values": [0, 10], "unit": "deg"},
        ],
        "map_metric": metric,
        "n_cells": 4,
        "columns": store.columns(["h", "tilt"], ["fell", "peak"]),
    }
    directory.mkdir(parents=True)
    store.write_info(directory, info)
    writer = store.CellsWriter(directory / store.CELLS_FILE, info["columns"])
    for k, (h, tilt) in enumerate([(0.02, 0), (0.06, 0), (0.02, 10), (0.06, 10)]):
        falls = h > 0.04
        result = CellResult(
            k,
            "fell" if falls else "complete",
            "",
            fall_time=2.5 if falls else math.nan,
            metrics={"fell": float(falls), "peak": 100.0 + 50.0 * k},
        )
        writer.append(Cell(k, (("h", h), ("tilt", tilt)), (), None), result)
    writer.close()


def _has_colour(png: Path, colour: str) -> bool:
    image = mpimg.imread(png)[..., :3]
    return bool(np.any(np.all(np.abs(image - np.array(to_rgb(colour))) < 0.02, axis=-1)))


@pytest.mark.parametrize(("metric", "binary"), [("fell", True), ("peak", False)])
def test_yes_no_map_has_two_colours(tmp_path: Path, metric: str, binary: bool) -> None:
    """A yes/no metric is drawn in its two colours (no colour bar); a continuous one is not."""
    directory = tmp_path / "sweep"
    _binary_sweep(directory, metric)
    png = next(p for p in plot_sweep(directory) if p.suffix == ".png")
    no_fall, fell = style.FALL_COLOURS
    assert _has_colour(png, no_fall) is binary
    assert _has_colour(png, fell) is binary


def test_fall_message_is_readable() -> None:
    """A fall by pelvis height says how far the pelvis dropped against its standing height."""
    from walkrepro.sim.contact_reader import FallDetector
    from walkrepro.sim.robot import load_robot
    from walkrepro.sim.world import build_scene
    from walkrepro.specs.files import load_spec

    spec = load_spec("stand_dyros_red").spec
    robot = load_robot(spec.robot)
    model = build_scene(robot, spec).model
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home_qpos
    mujoco.mj_kinematics(model, data)
    detector = FallDetector(robot, model, spec)
    assert detector.check(data) == ""  # standing at home
    data.qpos[2] = 0.55 * robot.home_qpos[2]
    mujoco.mj_kinematics(model, data)
    message = detector.check(data)
    z = float(data.xpos[model.body("pelvis").id, 2])
    assert message == (
        f"the pelvis dropped to {z:.2f} m, under 60% of its standing height of "
        f"{robot.home_qpos[2]:.2f} m"
    )


def test_an_svg_draws_dense_artists_as_pixels_and_stays_small(tmp_path: Path) -> None:
    """A 2 kHz line of 40 000 points and a band of thousands of polygons are pixels in the
    SVG (an embedded image, the file a few hundred kB at most); a short line stays a vector."""
    from walkrepro.present.figures.style import DENSE_VERTICES, save

    t = np.linspace(0.0, 20.0, 40_000)
    fig, ax = plt.subplots()
    dense = ax.plot(t, np.sin(t))[0]
    band = ax.fill_between(t, 0, 1, where=np.sin(40 * t) > 0, step="post", alpha=0.2)
    sparse = ax.plot([0, 10, 20], [0, 1, 0])[0]
    paths = save(fig, tmp_path / "dense")
    svg = paths[1].read_text()
    assert dense.get_rasterized() and band.get_rasterized() and not sparse.get_rasterized()
    assert len(sparse.get_xdata()) < DENSE_VERTICES
    assert "<image" in svg
    assert paths[1].stat().st_size < 400_000, paths[1].stat().st_size
