"""Spec sections for sweeps: named sweep parameters, and declared maps with paper claims.

They are optional fields of an experiment spec (``sweep_parameters:`` and ``sweeps:``). A
sweep cell's run never sees them: a cell's spec is the experiment with these two cleared.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from walkrepro.specs.deviation import KnownDeviation
from walkrepro.specs.tags import ClaimTag

Op = Literal["<", "<=", ">", ">=", "==", "between"]
#: A grid's values: ``"20,40,60"``, a range ``"start:stop:count"``, a number or a YAML list.
GridValues = str | float | bool | list[Any]


class _Strict(BaseModel):
    """Unknown fields are errors (as in every spec section)."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class Affine(_Strict):
    """``field = scale · x + offset`` for a sweep parameter's value ``x``."""

    scale: float = 1.0
    offset: float = 0.0

    def apply(self, x: float) -> float:
        """The field's value for parameter value ``x`` (12 significant digits, so a sweep
        over 0.02:0.06:3 gives 0.03, not 0.030000000000000002)."""
        return float(f"{self.scale * x + self.offset:.12g}")


class SweepParameter(_Strict):
    """A named sweep axis that sets one or more spec fields, each an affine map of its value.

    For things placed in space: an obstacle's height also moves its centre, e.g.
    ``obstacle_height: {unit: m, sets: {world.obstacles.0.size.2: 1, world.obstacles.0.position.2: 0.5}}``.
    A plain number is the scale (offset 0).
    """

    sets: dict[str, float | Affine] = Field(min_length=1)
    unit: str = ""
    description: str = ""

    def affine(self, path: str) -> Affine:
        """The map of one field."""
        a = self.sets[path]
        return a if isinstance(a, Affine) else Affine(scale=float(a))


class Condition(_Strict):
    """``value op threshold`` on a cells-table column (a metric or a grid field)."""

    op: Op
    value: float | tuple[float, float]


class Region(_Strict):
    """The cells where ``metric op value`` holds, e.g. ``fell == 0`` (errored cells: unknown)."""

    metric: str
    op: Op
    value: float | tuple[float, float]

    def __str__(self) -> str:
        v = self.value
        return (
            f"{self.metric} in [{v[0]:g}, {v[1]:g}]"  # type: ignore[index]
            if self.op == "between"
            else f"{self.metric} {self.op} {v:g}"
        )


class SweepClaim(ClaimTag, _Strict):
    """A paper claim about a region of a sweep's map.

    Kinds:
        ``contains``: the region among cells matching ``where`` contains the region among
            cells matching ``contains`` (cells paired by the other grid fields), e.g. "the
            region where fell == 0 with impedance contains the one without it".
        ``exceeds``: as ``contains``, and the region among ``where`` cells is larger: at
            least one ``where`` cell lies in it whose partner does not, e.g. "with impedance
            the robot overcomes every obstacle it overcomes without, and more".
        ``everywhere``: every cell matching ``where`` lies in the region, e.g. "every push
            up to 6 N·s is recovered at every phase" (with region ``stepped_on_off == 0``:
            "fails everywhere there").
        ``paired``: at every cell matching ``where``, ``region.metric op region.value ×``
            the same metric at its partner, the cell matching ``than`` with the same values
            of the fields ``than`` does not name, e.g. "with stepping the same drag gives a
            lower mean speed" (``mean_speed < 1 ×`` its value with stepping off).

    ``where``/``contains``/``than`` map a grid field to a value (equality) or a condition
    ``{op, value}``.

    ``mirror`` names a numeric grid field whose sign the two sides of a ``contains``,
    ``exceeds`` or ``paired`` claim take opposite: a cell is paired with the one of the
    opposite value there (and the same values of the other fields), e.g. a forward push of
    6 N·s with the backward push of 6 N·s at the same onset ("forward pushes are recovered
    wherever backward ones are, and stronger ones").
    """

    kind: Literal["contains", "exceeds", "everywhere", "paired"]
    region: Region
    where: dict[str, Any] = Field(default_factory=dict)
    contains: dict[str, Any] | None = None
    than: dict[str, Any] | None = None
    mirror: str | None = None
    source: str
    note: str = ""
    known_deviation: KnownDeviation | None = None

    @model_validator(mode="after")
    def _fits_kind(self) -> SweepClaim:
        if self.kind in ("contains", "exceeds") and not self.contains:
            raise ValueError(f"a '{self.kind}' claim needs contains: {{field: value}}")
        if self.kind in ("everywhere", "paired") and self.contains is not None:
            raise ValueError("'contains' applies to kinds contains and exceeds only")
        if self.kind == "paired":
            if not self.than:
                raise ValueError("a 'paired' claim needs than: {field: value}")
            if self.region.op == "between":
                raise ValueError("a 'paired' claim needs a single-number op (<, <=, >, >=, ==)")
        elif self.than is not None:
            raise ValueError("'than' applies to kind paired only")
        if self.mirror is not None and self.kind == "everywhere":
            raise ValueError("'mirror' pairs cells: kinds contains, exceeds and paired only")
        return self


class SweepSpec(_Strict):
    """A declared map: the sweep to run and the paper's claims about its result.

    Its reference result is committed under ``results/maps/<name>/``.
    """

    name: str = Field(pattern=r"^[A-Za-z0-9_\-]+$")
    description: str = ""
    grid: dict[str, GridValues] = Field(min_length=1)
    set: dict[str, Any] = Field(default_factory=dict, description="extra overrides for every cell")
    metric: str | None = Field(None, description="the metric the map colours")
    success: Region | None = Field(
        None, description="the region whose edge the map draws (default: the cells with no fall)"
    )
    claims: list[SweepClaim] = Field(default_factory=list)

    @model_validator(mode="after")
    def _mirror_is_a_grid_field(self) -> SweepSpec:
        for claim in self.claims:
            if claim.mirror is not None and claim.mirror not in self.grid:
                raise ValueError(
                    f"claim mirror {claim.mirror!r} is not a grid field of map {self.name!r} "
                    f"({', '.join(self.grid)})"
                )
        return self

    def grid_items(self) -> list[str]:
        """The grid as ``--grid`` strings."""
        return [f"{k}={_values_text(v)}" for k, v in self.grid.items()]

    def set_items(self) -> list[str]:
        """The extra overrides as ``--set`` strings."""
        import json

        return [f"{k}={json.dumps(v)}" for k, v in self.set.items()]


def _values_text(v: GridValues) -> str:
    import json

    if isinstance(v, list):
        return ",".join(json.dumps(x) for x in v)
    if isinstance(v, bool):
        return json.dumps(v)
    return str(v)
