"""What a row tests: a paper's claim (``claim: <id>``) or walkrepro's own (``own: <kind>``).

Shared by expectations (``expect:``) and map claims (``sweeps:``); the ids live in the
paper's claim register (:mod:`walkrepro.specs.claims`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field, model_validator

#: Why a row is walkrepro's own rather than a paper's claim: a variant the paper did not run
#: (``generalisation``), a map over a modelling choice (``sensitivity``), a controller or
#: model departure (``ablation``), or a check of walkrepro itself (``sanity``).
OwnKind = Literal["generalisation", "sensitivity", "ablation", "sanity"]
OWN_KINDS: tuple[str, ...] = OwnKind.__args__  # type: ignore[attr-defined]


class ClaimTag(BaseModel):
    """The tag of a row: at most one of ``claim`` and ``own`` (the shipped experiments carry
    exactly one, which tests/test_claims.py enforces; a user's own spec may carry none)."""

    claim: str | None = Field(
        None,
        min_length=1,
        description="the id of the paper claim this row tests, in experiments/claims/<paper>.yaml",
    )
    own: OwnKind | None = Field(
        None,
        description="walkrepro's own claim, not the paper's: generalisation, sensitivity, "
        "ablation or sanity",
    )

    @model_validator(mode="after")
    def _one_tag(self) -> ClaimTag:
        if self.claim is not None and self.own is not None:
            raise ValueError(
                "a row tests one paper claim (claim: <id>) or is walkrepro's own (own: <kind>), "
                "not both"
            )
        return self

    @property
    def tag(self) -> str:
        """``claim <id>``, ``own <kind>`` or ``untagged``."""
        if self.claim is not None:
            return f"claim {self.claim}"
        return f"own {self.own}" if self.own is not None else "untagged"
