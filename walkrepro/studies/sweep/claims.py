"""Paper claims about regions of a sweep's map, evaluated on a cells table.

Pure functions of the table (``store.CellsTable`` or any rows of dicts): no simulation, so
``walkrepro check`` evaluates them from the committed reference maps in milliseconds. Each
claim becomes one check row: ``measured`` is the number of cells that contradict the claim
(``== 0`` passes). A cell that errored, crashed or is missing cannot be placed in or out of the
region; a claim that depends on one fails (or is a known deviation) and says which.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from walkrepro.evaluation.checks import FAIL, KNOWN, PASS, CheckRow, holds
from walkrepro.specs.sweeps import Condition, Region, SweepClaim, SweepSpec
from walkrepro.studies.sweep.grid import value_text

#: Outcomes of cells whose metrics are measured (the run ended, with or without a fall).
MEASURED = ("complete", "fell")
Row = Mapping[str, Any]


def in_region(row: Row, claim: SweepClaim | Region) -> bool | None:
    """Whether a cell lies in the claim's region (or a region); None if the cell has no
    measurement."""
    region = claim if isinstance(claim, Region) else claim.region
    if row.get("outcome") not in MEASURED:
        return None
    value = row.get(region.metric, math.nan)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    if math.isnan(value):
        return None
    return holds(region.op, value, region.value)


def matches(row: Row, selector: Mapping[str, Any]) -> bool:
    """Whether a cell's grid values satisfy ``selector`` (field → value or ``{op, value}``)."""
    for field, want in selector.items():
        have = row.get(field)
        if isinstance(want, Mapping):
            cond = Condition.model_validate(want)
            if not isinstance(have, int | float) or not holds(cond.op, float(have), cond.value):
                return False
        elif isinstance(want, int | float) and not isinstance(want, bool):
            if isinstance(have, bool) or not isinstance(have, int | float):
                return False
            if not math.isclose(float(have), float(want), rel_tol=1e-9, abs_tol=1e-12):
                return False
        elif value_text(have) != value_text(want):
            return False
    return True


def evaluate_claim(
    rows: Sequence[Row],
    fields: Sequence[str],
    claim: SweepClaim,
    map_name: str,
    n_cells: int | None = None,
    origin: str = "",
) -> CheckRow:
    """One claim → one check row.

    Args:
        rows: the cells (each with its grid values, ``outcome`` and metrics).
        fields: the grid fields.
        claim: the claim.
        map_name: the map's name, for the row's label.
        n_cells: cells in the full grid (missing rows count as unknown).
        origin: where the table came from, appended to the source.
    """
    violations, unknown, note, label = _judged_cells(rows, fields, claim, map_name)
    # Cells that exist but whose region cannot be measured (a fall before the window) may
    # be a declared band of the known deviation; a selector over no cell, or a missing cell,
    # never is.
    unmeasured = [u for u in unknown if not u.startswith(_NO_CELL)]
    hard = [u for u in unknown if u.startswith(_NO_CELL)]
    if n_cells is not None and len(rows) < n_cells:
        hard.append(f"{n_cells - len(rows)} of {n_cells} cells missing")
        unknown.append(hard[-1])
    ok = not violations and not unknown
    parts = [note]
    if violations:
        parts.append("contradicted at " + "; ".join(violations))
    if unknown:
        parts.append("not measurable: " + "; ".join(unknown))
    if claim.note:
        parts.insert(0, claim.note)
    text = ". ".join(p for p in parts if p)
    measured = float(len(violations))
    status, text = _status(claim, measured, ok, hard, len(unmeasured), text)
    observed = claim.known_deviation.observed if claim.known_deviation is not None else None
    source = claim.source + (f" [from {origin}]" if origin else "")
    return CheckRow(
        metric=label,
        op="==",
        paper=0.0,
        measured=measured,
        status=status,
        source=source,
        note=text,
        observed=observed,
        claim=claim.claim,
        own=claim.own,
    )


def _judged_cells(
    rows: Sequence[Row], fields: Sequence[str], claim: SweepClaim, map_name: str
) -> tuple[list[str], list[str], str, str]:
    """The claim's contradicting cells, its unknown ones, a note, and the row's label."""
    if claim.kind in ("contains", "exceeds"):
        violations, unknown, note = _contains(rows, fields, claim)
        sign = "⊇" if claim.kind == "contains" else "⊋"
        label = f"map {map_name}: {claim.region} where {_sel(claim.where)} {sign} where {_sel(claim.contains or {})}"
        if claim.mirror:
            label += f", mirrored in {claim.mirror}"
    elif claim.kind == "paired":
        violations, unknown, note = _paired(rows, fields, claim)
        r = claim.region
        label = (
            f"map {map_name}: {r.metric} where {_sel(claim.where)} {r.op} {r.value:g} × "
            f"its value where {_sel(claim.than or {})}"
        ) + (f", mirrored in {claim.mirror}" if claim.mirror else "")
    else:
        violations, unknown, note = _everywhere(rows, fields, claim)
        label = f"map {map_name}: {claim.region} for every cell" + (
            f" where {_sel(claim.where)}" if claim.where else ""
        )
    return violations, unknown, note, label


def _status(
    claim: SweepClaim, measured: float, ok: bool, hard: list[str], n_unmeasured: int, text: str
) -> tuple[str, str]:
    """The row's status and its note: pass or fail, or, with a known deviation, known while
    the contradicting cells (and, where declared, the cells not measurable) stay in their
    bands; ``hard`` are the missing cells and selectors over no cell, never in a band."""
    dev = claim.known_deviation
    observed = dev.observed if dev is not None else None
    if dev is None:
        return (PASS if ok else FAIL), text
    if isinstance(observed, str):  # "not measurable": a claim always counts its cells
        return FAIL, (
            f"{text}. A claim's known deviation needs an observed band of contradicting cells"
        )
    if (
        observed is not None
        and not hard
        and observed[0] <= measured <= observed[1]
        and _in_band(n_unmeasured, dev.unmeasurable_cells)
    ):
        # A known deviation is a band of contradicting cells (and, where declared, of cells
        # not measurable): it fails when either count leaves its band.
        return KNOWN, f"{text}. Known deviation: {dev.reason}"
    if hard:
        side = "missing cells"
    elif not _in_band(n_unmeasured, dev.unmeasurable_cells):
        side = f"{n_unmeasured} cells not measurable, declared {dev.unmeasurable_cells or 0}"
    else:
        side = ("fewer" if ok or measured < observed[0] else "more") + " contradicting cells"
    return FAIL, (
        f"{text}. Left the known deviation's observed band ({side}"
        f"{': the deviation may be gone, update the spec' if ok else ''}). "
        f"Known deviation: {dev.reason}"
    )


def evaluate_sweep(
    rows: Sequence[Row],
    fields: Sequence[str],
    sweep: SweepSpec,
    n_cells: int | None = None,
    origin: str = "",
) -> list[CheckRow]:
    """Every claim of a declared map."""
    return [evaluate_claim(rows, fields, c, sweep.name, n_cells, origin) for c in sweep.claims]


_NO_CELL = "no cell of the map where"


def _in_band(count: int, band: tuple[int, int] | None) -> bool:
    """Whether ``count`` unmeasurable cells is what the known deviation declares (none
    when it declares no band)."""
    return count == 0 if band is None else band[0] <= count <= band[1]


def _selects_none(chosen: Sequence[Row], selector: Mapping[str, Any]) -> list[str]:
    """A claim over no cells would hold whatever the map shows: say so, so that it fails."""
    return [] if chosen else [f"{_NO_CELL} {_sel(selector)}"]


def _pairing(
    fields: Sequence[str], named: set[str], mirror: str | None = None
) -> tuple[list[str], Callable[[Row], tuple[str, ...]]]:
    """The grid fields that pair two cells (those no selector names, and the ``mirror``
    field by its magnitude: partners there have opposite signs), and a cell's key."""
    others = [f for f in fields if f not in named or f == mirror]

    def key(row: Row) -> tuple[str, ...]:
        return tuple(
            value_text(abs(row[f]) if f == mirror and _number(row.get(f)) else row.get(f))
            for f in others
        )

    return others, key


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _contains(
    rows: Sequence[Row], fields: Sequence[str], claim: SweepClaim
) -> tuple[list[str], list[str], str]:
    """Region(where) ⊇ region(contains), cells paired by the fields neither selector names."""
    inner_sel = claim.contains or {}
    others, key = _pairing(fields, set(claim.where) | set(inner_sel), claim.mirror)
    outer = {key(r): r for r in rows if matches(r, claim.where)}
    inner = [r for r in rows if matches(r, inner_sel)]
    violations = []
    unknown = _selects_none(list(outer.values()), claim.where) + _selects_none(inner, inner_sel)
    n_inner = n_outer = n_more = 0
    for r in inner:
        here = in_region(r, claim)
        partner = outer.get(key(r))
        there = None if partner is None else in_region(partner, claim)
        n_inner += here is True
        if here is None:
            unknown.append(f"{_at(r, others)} ({r.get('outcome')})")
        elif here and there is None:
            unknown.append(
                f"{_at(r, others)} where {_sel(claim.where)} "
                f"({'missing' if partner is None else partner.get('outcome')})"
            )
        elif here and not there:
            violations.append(_at(r, others))
        n_more += here is False and there is True
    n_outer = sum(in_region(r, claim) is True for r in outer.values())
    if claim.kind == "exceeds" and not n_more and not unknown:
        # "Larger": besides containing it, the region must hold somewhere the other does not.
        violations.append(
            f"no cell where {_sel(claim.where)} lies in the region and its partner does not"
        )
    note = (
        f"region {claim.region}: {n_outer} of {len(outer)} cells where {_sel(claim.where)}, "
        f"{n_inner} of {len(inner)} where {_sel(inner_sel)}"
    )
    if claim.kind == "exceeds":
        note += f"; {n_more} only where {_sel(claim.where)}"
    return violations, unknown, note


def _everywhere(
    rows: Sequence[Row], fields: Sequence[str], claim: SweepClaim
) -> tuple[list[str], list[str], str]:
    """Every cell matching ``where`` lies in the region."""
    chosen = [r for r in rows if matches(r, claim.where)]
    violations, unknown = [], _selects_none(chosen, claim.where)
    for r in chosen:
        inside = in_region(r, claim)
        if inside is None:
            unknown.append(f"{_at(r, fields)} ({r.get('outcome')})")
        elif not inside:
            violations.append(_at(r, fields))
    n_in = sum(in_region(r, claim) is True for r in chosen)
    return violations, unknown, f"region {claim.region}: {n_in} of {len(chosen)} selected cells"


def _measured(row: Row, metric: str) -> float | None:
    """A cell's metric, or None when the cell has no measurement of it."""
    if row.get("outcome") not in MEASURED:
        return None
    try:
        value = float(row.get(metric, math.nan))
    except (TypeError, ValueError):
        return None
    return None if math.isnan(value) else value


def _paired(
    rows: Sequence[Row], fields: Sequence[str], claim: SweepClaim
) -> tuple[list[str], list[str], str]:
    """metric(where cell) op value × metric(partner), the partner matching ``than`` with the
    same values of the fields ``than`` does not name."""
    region, than = claim.region, claim.than or {}
    others, key = _pairing(fields, set(than), claim.mirror)
    partners = {key(r): r for r in rows if matches(r, than)}
    chosen = [r for r in rows if matches(r, claim.where) and not matches(r, than)]
    violations, unknown = [], _selects_none(chosen, claim.where)
    n_hold = 0
    for r in chosen:
        partner = partners.get(key(r))
        here = _measured(r, region.metric)
        there = None if partner is None else _measured(partner, region.metric)
        if here is None or there is None:
            which = r if here is None else partner
            status = "missing" if which is None else which.get("outcome")
            side = "" if here is None else f" where {_sel(than)}"
            unknown.append(f"{_at(r, others)}{side} ({status}: no {region.metric})")
        elif holds(region.op, here, float(region.value) * there):  # type: ignore[arg-type]
            n_hold += 1
        else:
            violations.append(f"{_at(r, others)} ({here:.4g} against {there:.4g})")
    note = (
        f"{region.metric} {region.op} {region.value:g} × its value where {_sel(than)}: holds at "
        f"{n_hold} of {len(chosen)} cells where {_sel(claim.where)}"
    )
    return violations, unknown, note


def _sel(selector: Mapping[str, Any]) -> str:
    parts = []
    for f, v in selector.items():
        if isinstance(v, Mapping):
            parts.append(f"{f} {v.get('op')} {value_text(v.get('value'))}")
        else:
            parts.append(f"{f}={value_text(v)}")
    return ", ".join(parts) or "all cells"


def _at(row: Row, fields: Iterable[str]) -> str:
    return "(" + ", ".join(f"{f}={value_text(row.get(f))}" for f in fields) + ")"
