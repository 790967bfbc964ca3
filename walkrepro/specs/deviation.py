"""A known deviation: where a reproduction misses its paper, what it measures, and why.

Shared by expectations (``expect:``) and map claims (``sweeps:``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

#: The observed result of a metric that the reproduction cannot measure today (e.g. a
#: behaviour after a push that the robot does not survive).
NOT_MEASURABLE = "not measurable"


class KnownDeviation(BaseModel):
    """What the reproduction measures today where it misses the paper, and why.

    A known deviation is an observed band, not an excuse: the expectation's row fails when
    the measured value leaves ``observed`` in either direction (worse is a regression;
    better means the deviation may be gone and the spec must be updated). ``observed: not
    measurable`` records that the metric cannot be measured today (its reason is shown); the
    row fails as soon as it can be, with the value to put in the spec.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    reason: str = Field(description="why the reproduction misses the paper, with the evidence")
    observed: tuple[float, float] | Literal["not measurable"] | None = Field(
        description="[low, high]: the band the reproduction measures today (closed interval), "
        "or 'not measurable'; required in every spec, None only in the spec of a log written "
        "before bands existed"
    )

    unmeasurable_cells: tuple[int, int] | None = Field(
        default=None,
        description="map claims only: [low, high], the band of selected cells in which the "
        "claim's region cannot be measured today (e.g. a cell that falls has no speed ratio); "
        "the claim fails when that count leaves the band; a missing cell or a selector that "
        "picks no cell still fails",
    )

    @model_validator(mode="before")
    @classmethod
    def _legacy_reason_only(cls, data: object) -> object:
        # Logs written before observed bands hold the reason alone. They still load, so an old
        # log can be re-checked, but such a row has no band and always fails.
        if isinstance(data, str):
            return {"reason": data, "observed": None}
        return data

    @model_validator(mode="after")
    def _band_is_ordered(self) -> KnownDeviation:
        if isinstance(self.observed, tuple) and not self.observed[0] <= self.observed[1]:
            raise ValueError("observed needs [low, high] with low <= high")
        band = self.unmeasurable_cells
        if band is not None and not 0 <= band[0] <= band[1]:
            raise ValueError("unmeasurable_cells needs [low, high] with 0 <= low <= high")
        return self
