"""Tests of map claims in `walkrepro check`: from the committed reference maps, and re-run."""

from __future__ import annotations

from pathlib import Path

import pytest

from walkrepro import EXPERIMENTS_DIR, RESULTS_DIR
from walkrepro.evaluation.checks import FAIL, KNOWN, PASS
from walkrepro.specs.files import experiment_names, load_spec
from walkrepro.studies.sweep import store
from walkrepro.studies.sweep.command import _stale, map_verdicts

DECLARING = [n for n in experiment_names() if load_spec(n).spec.sweeps]


def test_every_paper_has_a_declared_map() -> None:
    """Each of the three papers declares at least one map with claims."""
    papers = {load_spec(n).spec.paper.key for n in DECLARING}
    assert papers == {"lee2021", "faraji", "jo_oh"}
    assert all(s.claims for n in DECLARING for s in load_spec(n).spec.sweeps)


@pytest.mark.parametrize("name", DECLARING)
def test_committed_maps_hold_and_are_current(name: str, tmp_path: Path) -> None:
    """Each declared map's claims hold (or are declared deviations) on its committed cells.csv,
    which was made with the grid the spec declares now; nothing is simulated."""
    for declared in load_spec(name).spec.sweeps:
        directory = RESULTS_DIR / "maps" / declared.name
        assert (directory / store.CELLS_FILE).is_file() and (directory / "map.png").is_file()
        assert _stale(store.read_info(directory), declared) == ""
    verdicts = map_verdicts([name], False, tmp_path, 1)
    assert verdicts and all(r.status in (PASS, KNOWN) for v in verdicts for r in v.rows)
    assert not (tmp_path / "sweeps").exists()


def test_a_changed_grid_makes_the_reference_stale() -> None:
    """A committed map made with other grid values than the spec's is reported as stale."""
    declared = load_spec("obstacle_4cm").spec.sweeps[0]
    info = store.read_info(RESULTS_DIR / "maps" / declared.name)
    info["grid"][0]["values"] = [0.02, 0.03]
    assert "grid differs" in _stale(info, declared)


TINY = """
sweeps:
  - name: tiny_stand_map
    grid: {sim.duration: "0.1,0.15"}
    claims:
      - kind: everywhere
        region: {metric: fell, op: "==", value: 0}
        source: "stands"
"""


@pytest.mark.slow
def test_check_sweeps_reruns_a_declared_map(tmp_path: Path) -> None:
    """With rerun the map is swept again and its claims evaluated on the new cells; without a
    committed reference the claim fails and says how to make one."""
    spec = tmp_path / "tiny.yaml"
    spec.write_text((EXPERIMENTS_DIR / "stand_dyros_red.yaml").read_text() + TINY)
    (missing,) = map_verdicts([str(spec)], False, tmp_path, 1)
    assert missing.rows[0].status == FAIL and "--update-reference" in missing.rows[0].note
    (rerun,) = map_verdicts([str(spec)], True, tmp_path, 2)
    assert [r.status for r in rerun.rows] == [PASS]
    assert "2 of 2 selected cells" in rerun.rows[0].note
    (directory,) = (tmp_path / "sweeps" / "stand_dyros_red").glob("*/")
    assert (directory / "map.png").is_file()
