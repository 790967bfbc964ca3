"""Tests of sweep engines: same cells, same metrics, whatever the engine, job count or order."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from walkrepro.errors import WalkreproError
from walkrepro.studies.sweep.cells import CRASHED, CellResult, CellTask, run_cell
from walkrepro.studies.sweep.engines import ProcessEngine, RayEngine, import_ray, make_engine
from walkrepro.studies.sweep.grid import parse_grid_item, plan_cells

GRID = ["sim.duration=0.1,0.15", "controller.params.kp=300,400"]


def _tasks(tmp: Path, reverse: bool = False) -> list[CellTask]:
    cells = plan_cells("stand_dyros_red", [parse_grid_item(g) for g in GRID])
    tasks = [
        CellTask(c.index, c.spec, tmp / f"{c.index}", metrics=("footsteps:left_foot",))
        for c in cells
    ]
    return tasks[::-1] if reverse else tasks


def _fingerprint(results: list[CellResult]) -> dict[int, tuple]:
    """What a cell computes (outcome, message, fall time, metrics, verdict), exactly."""
    return {
        r.index: (
            r.outcome,
            r.message,
            repr(r.fall_time),
            repr(sorted(r.metrics.items())),
            r.counts,
        )
        for r in results
    }


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[int, tuple]:
    """The cells run one by one in this process."""
    tmp = tmp_path_factory.mktemp("serial")
    return _fingerprint([run_cell(t) for t in _tasks(tmp)])


def test_serial_cells_complete_and_clean_up(reference: dict[int, tuple], tmp_path: Path) -> None:
    """Every cell completes, records the extra metric, and leaves no run directory behind."""
    assert {v[0] for v in reference.values()} == {"complete"}
    assert all("footsteps:left_foot" in v[3] for v in reference.values())
    task = _tasks(tmp_path)[0]
    run_cell(task)
    assert not task.work_root.exists()


@pytest.mark.parametrize(("jobs", "reverse"), [(1, False), (2, False), (2, True)])
def test_process_pool_gives_the_same_cells(
    reference: dict[int, tuple], tmp_path: Path, jobs: int, reverse: bool
) -> None:
    """A process pool with 1 or 2 reused workers, in either order, computes the same cells."""
    results = list(ProcessEngine(jobs).run(_tasks(tmp_path, reverse)))
    assert _fingerprint(results) == reference
    assert len({r.pid for r in results}) <= jobs  # workers are reused, not one per cell
    assert all(r.engine_time >= r.wall_time for r in results)


@pytest.mark.slow
def test_local_ray_gives_the_same_cells(reference: dict[int, tuple], tmp_path: Path) -> None:
    """Ray tasks on a local Ray compute the same cells as the process pool."""
    pytest.importorskip("ray")
    results = list(RayEngine(2).run(_tasks(tmp_path)))
    assert _fingerprint(results) == reference


def _crash_on_1(task: CellTask) -> CellResult:
    """A cell function whose worker dies on cell 1."""
    if task.index == 1:
        os._exit(3)
    return run_cell(task)


def _raise_on_2(task: CellTask) -> CellResult:
    """A cell function that breaks on cell 2 the way a bug in a cell would (inside run_cell)."""
    if task.index == 2:
        return run_cell(CellTask(task.index, None, task.work_root))
    return run_cell(task)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_dead_worker_marks_its_cell_crashed_and_the_sweep_goes_on(
    reference: dict[int, tuple], tmp_path: Path, jobs: int
) -> None:
    """Killing the worker of cell 1 records exactly that cell as crashed; the others finish."""
    results = {r.index: r for r in ProcessEngine(jobs, _crash_on_1).run(_tasks(tmp_path))}
    assert sorted(results) == [0, 1, 2, 3]
    assert results[1].outcome == CRASHED and "exit code 3" in results[1].message
    others = _fingerprint([r for i, r in results.items() if i != 1])
    assert others == {i: v for i, v in reference.items() if i != 1}


def test_a_failing_cell_is_recorded_with_its_message(tmp_path: Path) -> None:
    """An exception inside a cell becomes an error result with the exception's message."""
    results = {r.index: r for r in ProcessEngine(2, _raise_on_2).run(_tasks(tmp_path))}
    assert results[2].outcome == "error"
    assert "AttributeError" in results[2].message
    assert {results[i].outcome for i in (0, 1, 3)} == {"complete"}


def test_ray_missing_is_a_user_error_with_the_install_command(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Without Ray installed, --engine ray fails with the command that installs it."""
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(WalkreproError, match=r'pip install -e "\.\[ray\]"'):
        import_ray()
    with pytest.raises(WalkreproError, match="Valid engines: process, ray"):
        make_engine("dask", 2)
    with pytest.raises(WalkreproError, match="--engine ray only"):
        make_engine("process", 2, "auto")
