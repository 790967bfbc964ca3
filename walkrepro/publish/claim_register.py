"""The papers' claims, counted: each register claim's status from the rows that test it.

A row of a spec (``expect:``) or a map claim tests one claim of its paper's register
(``claim: <id>``, :mod:`walkrepro.specs.claims`) or is walkrepro's own (``own: <kind>``). A
claim's status is read off the verdicts of its rows (docs/claims.md):

- ``failed``: a row fails;
- ``deviating``: else, a row is a known deviation;
- ``calibrated``: else, a row served as a calibration criterion;
- ``reproduced``: every row holds as a prediction;
- ``not covered``: no row tests it; ``uncheckable``: the register says why none can.

The committed references give the status the README, ``walkrepro claims`` and the report
show; ``walkrepro check`` counts the claims its own batch tested.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from walkrepro.evaluation.checks import CALIBRATED, FAIL, KNOWN, PASS, Counts, Verdict
from walkrepro.specs.claims import Claim, Register

REPRODUCED, DEVIATING, FAILED = "reproduced", "deviating", "failed"
NOT_COVERED, UNCHECKABLE = "not covered", "uncheckable"
#: A claim's statuses, in the order the counts print them.
STATUSES = (REPRODUCED, CALIBRATED, DEVIATING, FAILED, NOT_COVERED, UNCHECKABLE)
#: Separates an experiment's name from a map's in a verdict's name.
MAP_MARK = " · map "


@dataclass(frozen=True)
class RowVerdict:
    """One row's verdict, with what it tests.

    Attributes:
        experiment: the experiment (``name · map MAP`` for a map claim).
        metric: the row's metric (a map claim: its label).
        status: ``pass``, ``calibrated``, ``known deviation`` or ``fail``.
        measured: the row's measured value (NaN or None when not measured).
        claim: the register id it tests, or None.
        own: walkrepro's own kind, or None.
    """

    experiment: str
    metric: str
    status: str
    measured: float | None
    claim: str | None
    own: str | None

    @property
    def text(self) -> str:
        """``experiment metric = value (status)``; a map claim: ``exp · map MAP: claim =
        contradicting cells (status)``."""
        value = self.measured
        shown = "not measured" if value is None or value != value else f"{value:.4g}"
        metric = self.metric
        if MAP_MARK in self.experiment:  # the label repeats the map's name: "map NAME: ..."
            metric = metric.split(": ", 1)[-1]
            return f"{self.experiment}: {metric} = {shown} ({self.status})"
        return f"{self.experiment} {metric} = {shown} ({self.status})"


@dataclass(frozen=True)
class ClaimResult:
    """A register claim, its status and the rows behind it."""

    claim: Claim
    status: str
    rows: tuple[RowVerdict, ...]


@dataclass
class ClaimTotals:
    """One paper's claims by status, and walkrepro's own rows apart.

    Attributes:
        paper: the paper key.
        by_status: number of register claims per status (:data:`STATUSES`).
        own: walkrepro's own rows by verdict.
        untagged: rows that carry no tag (a shipped spec has none: tests/test_claims.py).
        unknown: ``experiment: id`` of tags naming no register claim.
    """

    paper: str
    by_status: dict[str, int] = field(default_factory=lambda: dict.fromkeys(STATUSES, 0))
    own: Counts = field(default_factory=lambda: Counts(0, 0, 0, 0))
    untagged: int = 0
    unknown: list[str] = field(default_factory=list)

    @property
    def total(self) -> int:
        """Every claim of the register (M)."""
        return sum(self.by_status.values())

    def claims_text(self) -> str:
        """``R reproduced, C calibrated, D deviating, F failed, N not covered, U uncheckable,
        of M``."""
        parts = ", ".join(f"{self.by_status[s]} {s}" for s in STATUSES)
        return f"{parts}, of {self.total}"


def claim_status(claim: Claim, rows: Sequence[RowVerdict]) -> str:
    """The status of ``claim`` given the rows that test it (the module docstring's rules)."""
    statuses = {r.status for r in rows}
    if not rows:
        return UNCHECKABLE if claim.uncheckable else NOT_COVERED
    if FAIL in statuses:
        return FAILED
    if KNOWN in statuses:
        return DEVIATING
    if CALIBRATED in statuses:
        return CALIBRATED
    return REPRODUCED


def evaluate_register(register: Register, rows: Iterable[RowVerdict]) -> list[ClaimResult]:
    """Every claim of ``register`` with its status from ``rows`` (rows of other claims and
    walkrepro's own rows are ignored)."""
    by_id: dict[str, list[RowVerdict]] = {c.id: [] for c in register.claims}
    for r in rows:
        if r.claim in by_id:
            by_id[r.claim].append(r)
    return [
        ClaimResult(c, claim_status(c, by_id[c.id]), tuple(by_id[c.id])) for c in register.claims
    ]


def totals(register: Register, rows: Sequence[RowVerdict]) -> ClaimTotals:
    """Count ``register``'s claims by status and ``rows``' own rows by verdict."""
    out = ClaimTotals(register.paper)
    for result in evaluate_register(register, rows):
        out.by_status[result.status] += 1
    own = [r for r in rows if r.own is not None]
    out.own = Counts(
        reproduced=sum(r.status == PASS for r in own),
        calibrated=sum(r.status == CALIBRATED for r in own),
        known=sum(r.status == KNOWN for r in own),
        failed=sum(r.status == FAIL for r in own),
    )
    out.untagged = sum(r.claim is None and r.own is None for r in rows)
    ids = {c.id for c in register.claims}
    out.unknown = [f"{r.experiment}: {r.claim}" for r in rows if r.claim and r.claim not in ids]
    return out


def verdict_rows(verdict: Verdict) -> list[RowVerdict]:
    """The rows of one verdict (an experiment's or a map's), with their tags."""
    return [
        RowVerdict(verdict.experiment, r.metric, r.status, r.measured, r.claim, r.own)
        for r in verdict.rows
    ]


def experiment_of(verdict_name: str) -> str:
    """The experiment a verdict belongs to (a map's verdict is named ``exp · map MAP``)."""
    return verdict_name.split(MAP_MARK)[0]


# --------------------------------------------------------------------------------------
# The committed references


def reference_rows(results_dir: Path) -> dict[str, list[RowVerdict]]:
    """Every shipped experiment's and map's rows from the committed references, by paper.

    An experiment's rows come from ``results/<experiment>/check.json``, tagged by the spec's
    expectation at the same place; a reference whose rows no longer match the spec's (other
    metrics, or fewer) counts each of the spec's rows as failed (stale). The maps' claims are
    evaluated on the committed ``results/maps/<map>/cells.csv`` (no simulation).
    """
    from walkrepro.specs.files import load_spec, shipped_experiment_names
    from walkrepro.studies.sweep.command import map_verdicts

    found: dict[str, list[RowVerdict]] = {}
    for name in shipped_experiment_names():
        spec = load_spec(name).spec
        rows = found.setdefault(spec.paper.key, [])
        rows += _committed_rows(name, spec, results_dir)
        if spec.sweeps:
            for verdict in map_verdicts([name], False, results_dir, 1):
                rows += verdict_rows(verdict)
    return found


def _committed_rows(name: str, spec, results_dir: Path) -> list[RowVerdict]:  # noqa: ANN001
    """An experiment's committed rows, tagged from its spec."""
    path = results_dir / name / "check.json"
    committed = json.loads(path.read_text())["rows"] if path.is_file() else []
    same = len(committed) == len(spec.expect) and all(
        r["metric"] == e.metric for r, e in zip(committed, spec.expect, strict=False)
    )
    out = []
    for i, e in enumerate(spec.expect):
        row = committed[i] if same else None
        out.append(
            RowVerdict(
                name,
                e.metric,
                row["status"] if row else FAIL,
                row["measured"] if row else None,
                e.claim,
                e.own,
            )
        )
    return out


def paper_totals(results_dir: Path) -> dict[str, tuple[ClaimTotals, list[ClaimResult]]]:
    """Each paper with a register: its totals and claims, from the committed references.

    Papers without a register (walkrepro's own sanity checks) count their rows as own.
    """
    from walkrepro.specs.claims import find_register, register_papers

    rows = reference_rows(results_dir)
    papers = sorted(set(rows) | set(register_papers()))
    out = {}
    for key in papers:
        register = (
            find_register(key).model
            if key in register_papers()
            else Register.model_construct(paper=key, description="", claims=[])
        )
        paper_rows = rows.get(key, [])
        out[key] = (totals(register, paper_rows), evaluate_register(register, paper_rows))
    return out


# --------------------------------------------------------------------------------------
# A batch of verdicts (walkrepro check, walkrepro run)


def batch_lines(verdicts: Sequence[Verdict]) -> list[str]:
    """The count lines a batch leads with: per paper, the register claims its rows test, by
    status, and walkrepro's own rows apart.

    A claim none of the batch's rows tests is counted ``not covered`` (or ``uncheckable``)
    only when the batch ran every shipped experiment of its paper; otherwise the line says
    how many of the register's claims the batch tested.
    """
    from walkrepro.errors import WalkreproError
    from walkrepro.specs.claims import find_register, register_papers
    from walkrepro.specs.files import load_spec, shipped_experiment_names

    by_paper: dict[str, list[RowVerdict]] = {}
    ran: dict[str, set[str]] = {}
    for v in verdicts:
        name = experiment_of(v.experiment)
        try:
            key = load_spec(name).spec.paper.key
        except WalkreproError:
            continue  # a run of a spec no longer found: its rows count in the rows line only
        by_paper.setdefault(key, []).extend(verdict_rows(v))
        ran.setdefault(key, set()).add(name)
    shipped: dict[str, set[str]] = {}
    for name in shipped_experiment_names():
        shipped.setdefault(load_spec(name).spec.paper.key, set()).add(name)
    lines = []
    for key, rows in by_paper.items():
        if key not in register_papers():
            continue
        register = find_register(key).model
        t = totals(register, rows)
        whole = shipped.get(key, set()) <= ran[key]
        tested = t.total - t.by_status[NOT_COVERED] - t.by_status[UNCHECKABLE]
        shown = STATUSES if whole else STATUSES[:4]
        counts = ", ".join(f"{t.by_status[s]} {s}" for s in shown)
        scope = f"of {t.total}" if whole else f"{tested} of the register's {t.total} tested here"
        lines.append(f"{key}: the paper's claims: {counts}, {scope}; walkrepro's own rows: {t.own}")
    return lines
