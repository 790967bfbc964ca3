"""A sweep directory: ``<out>/sweeps/<experiment>/<UTC>-<id>/``.

- ``sweep.yaml``: the experiment, the grid, the ``--set`` overrides, the extra metrics, the
  map's metric and claims (for a declared map), the cells.csv columns, provenance;
- ``base.yaml``: the experiment's spec file as it was when the sweep started (``--resume``
  re-plans from it, so a later edit of the experiment cannot mix two specs in one sweep);
- ``planned.json``: the grid, the ``--set`` overrides and the digest of ``base.yaml`` as the
  sweep was planned; ``--resume`` refuses a ``sweep.yaml`` or ``base.yaml`` edited since, so
  one sweep never mixes two grids;
- ``cells.csv``: one row per finished cell, appended and flushed as cells finish (in finish
  order; readers sort by ``cell``), so an interrupted sweep keeps every finished cell. A cell
  whose worker died has a ``crashed`` row until ``--resume`` runs it again;
- ``map.png`` / ``map.svg``; ``cells/<index>/`` with each cell's run under ``--keep-logs``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from walkrepro.errors import WalkreproError
from walkrepro.specs import yamlload
from walkrepro.studies.sweep.cells import CRASHED, CellResult
from walkrepro.studies.sweep.grid import Cell, value_text

SWEEP_FILE, BASE_FILE, CELLS_FILE, CELLS_DIR = "sweep.yaml", "base.yaml", "cells.csv", "cells"
PLANNED_FILE = "planned.json"
#: Columns after the grid fields and before the metrics, and after the metrics.
HEAD = ("outcome", "message", "fall_time")
TAIL = ("passed", "known_deviations", "failed", "wall_time", "run_wall_time", "engine_time")


def columns(fields: Sequence[str], metric_names: Sequence[str]) -> list[str]:
    """The cells.csv header."""
    metric_cols = [m for m in metric_names if m not in ("fall_time",)]
    return ["cell", *fields, *HEAD, *metric_cols, *TAIL]


def new_sweep_dir(out: Path, experiment: str) -> Path:
    """A fresh sweep directory (never an earlier sweep's)."""
    from walkrepro.runs import results

    return results.new_run_dir(out / "sweeps", experiment).finish()


def is_sweep_dir(path: Path) -> bool:
    """Whether ``path`` holds a sweep (a ``sweep.yaml``)."""
    return (path / SWEEP_FILE).is_file()


def write_info(directory: Path, info: dict[str, Any]) -> None:
    """Write ``sweep.yaml``."""
    (directory / SWEEP_FILE).write_text(yaml.safe_dump(info, sort_keys=False, allow_unicode=True))


def read_info(directory: Path) -> dict[str, Any]:
    """Read ``sweep.yaml``.

    Raises:
        WalkreproError: not a sweep directory.
    """
    path = directory / SWEEP_FILE
    if not path.is_file():
        raise WalkreproError(
            f"{directory}: not a sweep directory (no {SWEEP_FILE}); sweeps are written under "
            "<out>/sweeps/<experiment>/."
        )
    return yamlload.load(path.read_text())


def planned(info: dict[str, Any], directory: Path) -> dict[str, Any]:
    """What fixes a sweep's cells: its grid (fields and values), its ``--set`` overrides
    and the SHA-256 of its ``base.yaml``."""
    return {
        "grid": [{"field": g["field"], "values": list(g["values"])} for g in info["grid"]],
        "set": list(info["set"]),
        "base_sha256": hashlib.sha256((directory / BASE_FILE).read_bytes()).hexdigest(),
    }


def write_planned(directory: Path, info: dict[str, Any]) -> None:
    """Record :func:`planned` in ``planned.json`` (once, when the sweep is created)."""
    text = json.dumps(planned(info, directory), indent=2) + "\n"
    (directory / PLANNED_FILE).write_text(text)


def check_planned(directory: Path, info: dict[str, Any]) -> None:
    """Refuse a sweep whose ``sweep.yaml`` grid, ``--set`` or ``base.yaml`` changed since it
    was planned (a sweep made before ``planned.json`` existed is checked row by row only).

    Raises:
        WalkreproError: what changed, and how to go on.
    """
    path = directory / PLANNED_FILE
    if not path.is_file():
        return
    try:
        recorded = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise WalkreproError(f"{path}: unreadable ({exc}); this sweep cannot be resumed.") from None
    now = planned(info, directory)
    changes = []
    was = {g["field"]: g["values"] for g in recorded.get("grid", [])}
    is_ = {g["field"]: g["values"] for g in now["grid"]}
    if list(was) != list(is_):
        changes.append(f"the grid fields were {', '.join(was)} and are now {', '.join(is_)}")
    else:
        changes += [
            f"{name} was {_listed(was[name])} and is now {_listed(is_[name])}"
            for name in was
            if [value_text(v) for v in was[name]] != [value_text(v) for v in is_[name]]
        ]
    if recorded.get("set") != now["set"]:
        changes.append(f"set was {recorded.get('set')} and is now {now['set']}")
    if recorded.get("base_sha256") != now["base_sha256"]:
        changes.append(f"{BASE_FILE} was edited")
    if changes:
        raise WalkreproError(
            f"{directory / SWEEP_FILE}: this sweep no longer matches the grid it was started "
            f"with ({'; '.join(changes)}); resuming would mix two grids in one sweep. Put "
            f"{SWEEP_FILE} back as it was, or start a new sweep with the new grid."
        )


def _listed(values: Sequence[Any]) -> str:
    return "[" + ", ".join(value_text(v) for v in values) + "]"


def drop_rows(path: Path, outcome: str) -> list[int]:
    """Remove the rows of ``cells.csv`` with ``outcome`` (atomically); returns their cells."""
    text = path.read_text() if path.is_file() else ""
    lines = list(csv.reader(io.StringIO(text)))
    if not lines:
        return []
    header, body = lines[0], lines[1:]
    column = header.index("outcome")
    dropped = [int(r[0]) for r in body if len(r) == len(header) and r[column] == outcome]
    if dropped:
        kept = [r for r in body if not (len(r) == len(header) and r[column] == outcome)]
        tmp = path.with_name(f".{path.name}.tmp")
        with tmp.open("w", newline="") as f:
            csv.writer(f, lineterminator="\n").writerows([header, *kept])
        os.replace(tmp, path)
    return dropped


class CellsWriter:
    """Appends rows to ``cells.csv``, one flushed line per finished cell."""

    def __init__(self, path: Path, header: Sequence[str]) -> None:
        self.header = list(header)
        new = not path.exists() or path.stat().st_size == 0
        self._file = path.open("a", newline="")
        if new:
            self._write(self.header)

    def append(self, cell: Cell, result: CellResult) -> None:
        """Write one cell's row and flush it to disk."""
        row: dict[str, Any] = {"cell": cell.index}
        row.update({f: value_text(v) for f, v in cell.values})
        row.update(outcome=result.outcome, message=result.message, fall_time=result.fall_time)
        row.update(result.metrics)
        row.update(
            passed=result.counts[0],
            known_deviations=result.counts[1],
            failed=result.counts[2],
            wall_time=result.wall_time,
            run_wall_time=result.run_wall_time,
            engine_time=result.engine_time,
        )
        self._write([_cell_text(row.get(c, math.nan)) for c in self.header])

    def _write(self, values: Sequence[str]) -> None:
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(values)
        self._file.write(buf.getvalue())  # one write per row: a row is never half-flushed
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def _cell_text(value: Any) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)  # exact, like the log
    return str(value)


@dataclass(frozen=True)
class CellsTable:
    """A read ``cells.csv``: rows sorted by cell, values parsed.

    Attributes:
        fields: the grid fields (columns after ``cell``, before ``outcome``).
        rows: one dict per cell: grid values (parsed as YAML), ``outcome``, ``message``,
            numbers as floats.
    """

    fields: tuple[str, ...]
    rows: tuple[dict[str, Any], ...]

    def column(self, name: str) -> list[Any]:
        """One column's values, in cell order."""
        return [r.get(name, math.nan) for r in self.rows]


def copy_cells_sorted(source: Path, target: Path) -> None:
    """Copy ``cells.csv`` with its whole rows in cell order (a reference's rows then do not
    depend on which job finished first; the values are copied as text, unchanged)."""
    lines = list(csv.reader(io.StringIO(source.read_text())))
    header, body = (lines[0], lines[1:]) if lines else ([], [])
    whole = sorted((r for r in body if len(r) == len(header)), key=lambda r: int(r[0]))
    with target.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows([header, *whole] if header else [])


def read_cells(path: Path, repair: bool = False) -> CellsTable:
    """Parse ``cells.csv`` (a torn last line from a killed sweep is dropped).

    Args:
        path: the file.
        repair: rewrite the file without a torn last line.
    """
    text = path.read_text() if path.is_file() else ""
    lines = list(csv.reader(io.StringIO(text)))
    if not lines:
        return CellsTable((), ())
    header, body = lines[0], lines[1:]
    whole = [r for r in body if len(r) == len(header)]
    if repair and len(whole) != len(body):
        with path.open("w", newline="") as f:
            csv.writer(f, lineterminator="\n").writerows([header, *whole])
    fields = tuple(header[1 : header.index("outcome")])
    rows = []
    for raw in whole:
        row: dict[str, Any] = {}
        for name, text_value in zip(header, raw, strict=True):
            if name in fields:
                row[name] = yamlload.load(text_value)
            elif name in ("outcome", "message"):
                row[name] = text_value
            elif name == "cell":
                row[name] = int(text_value)
            else:
                row[name] = float(text_value) if text_value else math.nan
        rows.append(row)
    # One row per cell: a resumed cell that was somehow written twice counts once (the first),
    # except that a crashed row gives way to a later row of the same cell.
    unique: dict[int, dict[str, Any]] = {}
    for row in rows:
        if unique.get(row["cell"], {}).get("outcome", CRASHED) == CRASHED:
            unique[row["cell"]] = row
    return CellsTable(fields, tuple(unique[k] for k in sorted(unique)))
