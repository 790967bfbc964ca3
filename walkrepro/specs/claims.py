"""Claim registers: ``experiments/claims/<paper>.yaml``, every result a paper reports.

A paper's claim register lists each result the paper reports that a reproduction could
check: a number, a figure's visible behaviour, a comparison between conditions, a "no fall".
Each claim has an id, where the paper states it, the paper's own words (short) and its kind.
A claim no reproduction here can check carries ``uncheckable: <why>``.

A spec's expectation row or map claim tests one register claim (``claim: <id>``, the id in
the register of the spec's ``paper.key``) or is walkrepro's own (``own: generalisation |
sensitivity | ablation | sanity``): :mod:`walkrepro.evaluation.claims` turns the committed
verdicts of those rows into each claim's status (TARGETS.md, Claims).

Loading reports errors as the spec loader does: file, line and field, no traceback.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.locations import EXPERIMENTS_DIR
from walkrepro.specs.models import (
    _check_plain_data,
    _display_path,
    _format_validation,
    _parse_yaml,
    _where,
    known_paper,
    require_unique,
)

if TYPE_CHECKING:
    from walkrepro.specs.models import ExperimentSpec

#: Where the shipped registers live: ``experiments/claims/<paper>.yaml``.
CLAIMS_DIR_NAME = "claims"
CLAIMS_DIR = EXPERIMENTS_DIR / CLAIMS_DIR_NAME

#: What kind of result a claim is.
ClaimKind = Literal["number", "behaviour", "comparison", "no_fall"]
#: A claim id: lowercase words joined by ``-``, ``_`` or ``.`` (e.g. ``walk.speed``).
ID_PATTERN = r"^[a-z0-9]+([._-][a-z0-9]+)*$"


class _Strict(BaseModel):
    """Unknown fields are errors: a typo must never be silently ignored."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class Claim(_Strict):
    """One result the paper reports.

    Attributes:
        id: the register's name for it, what rows cite with ``claim: <id>``.
        where: the section, figure, table or equation that states it.
        words: the paper's own words, short and verbatim (``...`` for a cut).
        kind: number, behaviour (a figure's visible behaviour), comparison (between
            conditions) or no_fall.
        uncheckable: why no reproduction here can check it (None: it is checkable, and a
            row must test it).
        not_covered: why a checkable claim has no row yet (what the row would need); it
            counts ``not covered``. A claim with neither reason must have a row.
    """

    id: str = Field(pattern=ID_PATTERN)
    where: str = Field(min_length=1)
    words: str = Field(min_length=1)
    kind: ClaimKind
    uncheckable: str | None = Field(None, min_length=1)
    not_covered: str | None = Field(None, min_length=1)

    @model_validator(mode="after")
    def _one_reason(self) -> Claim:
        if self.uncheckable and self.not_covered:
            raise ValueError("a claim is uncheckable or not covered, not both")
        return self


class Register(_Strict):
    """One paper's claim register."""

    paper: str = Field(description="paper key, as the specs' paper.key")
    description: str = ""
    claims: list[Claim] = Field(min_length=1)

    @field_validator("paper")
    @classmethod
    def _known_paper(cls, key: str) -> str:
        return known_paper(key)

    @field_validator("claims")
    @classmethod
    def _unique(cls, claims: list[Claim]) -> list[Claim]:
        require_unique("claim id", [c.id for c in claims])
        return claims

    def claim(self, claim_id: str) -> Claim:
        """The claim ``claim_id``.

        Raises:
            UnknownNameError: listing the register's ids.
        """
        for c in self.claims:
            if c.id == claim_id:
                return c
        raise UnknownNameError(f"claim of {self.paper}", claim_id, [c.id for c in self.claims])


class LoadedRegister(BaseModel):
    """A validated register plus where it came from, so errors can cite lines."""

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)

    model: Register
    path: Path
    source: str
    lines: dict[tuple[Any, ...], int]

    def where(self, path: tuple[Any, ...]) -> str:
        """``file, line N, field a.b.c`` for a field path (nearest known line)."""
        return _where(self.source, self.lines, path)


def register_path(paper: str, directory: Path | None = None) -> Path:
    """The register of ``paper`` in ``directory`` (default the shipped one)."""
    return (directory or CLAIMS_DIR) / f"{paper}.yaml"


def register_papers(directory: Path | None = None) -> list[str]:
    """The papers that have a register in ``directory`` (default the shipped one)."""
    return sorted(p.stem for p in (directory or CLAIMS_DIR).glob("*.yaml"))


def load_register(path: Path) -> LoadedRegister:
    """Parse and validate a claim register.

    Raises:
        SpecError: naming file, line and field for any problem.
    """
    source = _display_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SpecError(f"{source}: cannot read the claim register ({exc.strerror}).") from None
    except UnicodeDecodeError:
        raise SpecError(f"{source}: not UTF-8 text; save the file as UTF-8.") from None
    data, lines = _parse_yaml(text, source)
    _check_plain_data(data, source, lines, ())
    try:
        model = Register.model_validate(data)
    except ValidationError as exc:
        raise SpecError(_format_validation(exc, source, lines, ())) from None
    loaded = LoadedRegister(model=model, path=path, source=source, lines=lines)
    if model.paper != path.stem:
        raise SpecError(
            f"{loaded.where(('paper',))}: the register of paper {model.paper!r} must be named "
            f"{model.paper}.yaml (it is {path.name})."
        )
    return loaded


def find_register(paper: str, directory: Path | None = None) -> LoadedRegister:
    """The loaded register of ``paper``.

    Raises:
        UnknownNameError: no such register; lists the papers that have one.
    """
    path = register_path(paper, directory)
    if not path.is_file():
        raise UnknownNameError("claim register", paper, register_papers(directory))
    return load_register(path)


def tagging_problems(
    specs: Iterable[ExperimentSpec], registers: Mapping[str, Register]
) -> list[str]:
    """What keeps the specs and the registers from counting every claim (docs/claims.md).

    Returns one line per problem: a row or map claim with no tag; a ``claim:`` tag naming
    an id its paper's register lacks (or a paper with no register); a register claim that no
    row tests and that carries neither an ``uncheckable`` nor a ``not_covered`` reason. Empty
    when all is counted.

    Args:
        specs: the experiments (every shipped one, for the whole picture).
        registers: each paper's register by paper key.
    """
    problems: list[str] = []
    tested: set[tuple[str, str]] = set()
    for spec in specs:
        register = registers.get(spec.paper.key)
        ids = {c.id for c in register.claims} if register is not None else set()
        rows = [(f"expect row {i} ({e.metric})", e) for i, e in enumerate(spec.expect)]
        rows += [
            (f"map {s.name} claim {k} ({c.kind})", c)
            for s in spec.sweeps
            for k, c in enumerate(s.claims)
        ]
        for where, row in rows:
            if row.claim is None and row.own is None:
                problems.append(f"{spec.name}, {where}: untagged (claim: <id> or own: <kind>)")
            elif row.claim is not None and row.claim not in ids:
                problems.append(
                    f"{spec.name}, {where}: claim {row.claim!r} is not in the register of "
                    f"{spec.paper.key} (experiments/claims/{spec.paper.key}.yaml)"
                )
            elif row.claim is not None:
                tested.add((spec.paper.key, row.claim))
    for key, register in registers.items():
        for c in register.claims:
            if (key, c.id) not in tested and not (c.uncheckable or c.not_covered):
                problems.append(
                    f"{key}: claim {c.id!r} ({c.where}) is tested by no row and gives no "
                    "reason (uncheckable: <why> or not_covered: <why>)"
                )
    return problems
