"""An experiment's declared maps and their claims, from the committed cells.

Each map's claims are evaluated on its ``cells.csv`` exactly as ``walkrepro check`` does
without ``--sweeps`` (:func:`walkrepro.studies.sweep.claims.evaluate_sweep`); nothing is re-run.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from walkrepro.publish.report.claims import Claim, claim_from_row
from walkrepro.specs.models import ExperimentSpec

#: A map's picture in ``results/maps/<map>/``.
MAP_IMAGE = "map.png"


@dataclass(frozen=True)
class MapResult:
    """One declared map.

    Attributes:
        name: the map.
        description: the spec's description of the map.
        image: its picture, if the reference exists.
        claims: its claims, evaluated on the reference (one failed claim if it is missing).
    """

    name: str
    description: str
    image: Path | None
    claims: tuple[Claim, ...]


def experiment_maps(spec: ExperimentSpec, maps_root: Path) -> list[MapResult]:
    """The declared maps of ``spec`` with their references under ``maps_root``."""
    from walkrepro.studies.sweep import store
    from walkrepro.studies.sweep.claims import evaluate_sweep
    from walkrepro.studies.sweep.command import _stale

    out = []
    for declared in spec.sweeps:
        directory = maps_root / declared.name
        cells = directory / store.CELLS_FILE
        image = directory / MAP_IMAGE
        if not cells.is_file():
            missing = Claim(
                f"map {declared.name}", "", "", "no reference map", "", "fail", "",
                f"no reference map: run walkrepro sweep {spec.name} --map {declared.name} "
                "--update-reference",
            )  # fmt: skip
            out.append(MapResult(declared.name, declared.description, None, (missing,)))
            continue
        info = store.read_info(directory)
        table = store.read_cells(cells)
        rows = evaluate_sweep(table.rows, table.fields, declared, info["n_cells"])
        stale = _stale(info, declared)
        claims = []
        for r in rows:
            row = {
                "metric": r.metric,
                "source": r.source,
                "measured": r.measured,
                "observed": r.observed,
                "status": "fail" if stale else r.status,
                "note": f"stale reference map ({stale}). {r.note}" if stale else r.note,
            }
            claim = claim_from_row(row)
            cells = "cell" if r.measured == 1 else "cells"
            claims.append(
                replace(
                    claim,
                    metric=claim.metric.removeprefix(f"map {declared.name}: "),
                    paper="no contradicting cell",
                    measured=f"{claim.measured} contradicting {cells}",
                )
            )
        out.append(
            MapResult(
                declared.name,
                declared.description,
                image if image.is_file() else None,
                tuple(claims),
            )
        )
    return out
