"""The searches of a declared calibration, independent of how a run is made.

A search asks an *evaluator* for the criterion metrics at a batch of candidate values (one
run each; the batch runs in parallel on the sweep engine, or in a test, on a fake function)
and never sees a simulator. Everything it computes is a function of the evaluations, so the
same file gives the same result on any engine and with any number of jobs.

- :func:`find_root`: a parallel bisection of ``r(x) = metric(x) - target`` on a bracket.
- :func:`measure`: one run; the value is the measured metric(s).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from walkrepro.errors import WalkreproError

#: Metrics of a batch of candidates: ``candidates -> [{metric: value}, ...]`` in order. A
#: candidate of ``None`` is a run without the parameter set (a ``measure``).
Evaluator = Callable[[Sequence[float | None]], Sequence[Mapping[str, float]]]
#: Rounds after which a root search gives up (a bracket shrinks at least 2× per round, so
#: even 1e300 / 1e-300 takes fewer).
MAX_ROUNDS = 2000


class CalibrationFailed(WalkreproError):
    """A calibration that cannot reach its target (or whose run gave no value)."""

    exit_code = 1


@dataclass(frozen=True)
class RootProblem:
    """A root search of ``metric(x) - target`` over ``x`` in ``bracket``.

    Attributes:
        metric: the criterion metric.
        target: the metric's target value.
        tolerance: largest accepted ``|metric - target|``.
        bracket: ``(low, high)`` in the parameter's unit; the residual must change sign.
        xtol: stop once the bracket is narrower than this [parameter unit].
        points: interior points evaluated per round.
    """

    metric: str
    target: float
    tolerance: float
    bracket: tuple[float, float]
    xtol: float
    points: int


@dataclass(frozen=True)
class SearchResult:
    """What a search found.

    Attributes:
        value: the parameter's value (a tuple for a ``measure`` of several metrics).
        measured: the criterion metric(s) at ``value``.
        evaluations: ``(x, metric)`` of every run of a root search, in evaluation order.
    """

    value: float | tuple[float, ...] | str
    measured: float | tuple[float, ...]
    evaluations: tuple[tuple[float, float], ...] = ()


def split(low: float, high: float, points: int) -> list[float]:
    """The ``points`` interior points that split ``[low, high]`` into ``points + 1`` equal
    parts, ascending (computed the same way on every machine)."""
    return [low + (high - low) * (k / (points + 1)) for k in range(1, points + 1)]


def find_root(problem: RootProblem, evaluate: Evaluator) -> SearchResult:
    """Parallel bisection: keep the first part of the bracket whose ends change sign.

    The first round evaluates both ends and ``points`` interior points; each later round
    the interior points of the part kept. It stops at a residual of exactly zero or when
    the bracket is narrower than ``xtol``. The result is the evaluated point with the
    smallest ``|metric - target|`` (the earliest evaluated on a tie).

    Raises:
        CalibrationFailed: a run gives no value, the residual does not change sign over the
            bracket, or the best point misses the target by more than the tolerance.
    """
    evaluations: list[tuple[float, float]] = []

    def residuals(xs: list[float]) -> list[float]:
        rows = evaluate(xs)
        ys = [float(row.get(problem.metric, math.nan)) for row in rows]
        for x, y in zip(xs, ys, strict=True):
            if not math.isfinite(y):
                raise CalibrationFailed(
                    f"the run at {x!r} gives no value of {problem.metric} ({y!r}); the "
                    "search needs a measurable criterion over the whole bracket."
                )
            evaluations.append((x, y))
        return [y - problem.target for y in ys]

    low, high = problem.bracket
    xs = [low, *split(low, high, problem.points), high]
    rs = residuals(xs)
    if _sign(rs[0]) * _sign(rs[-1]) > 0:
        raise CalibrationFailed(
            f"{problem.metric} - {problem.target:g} does not change sign over the bracket "
            f"[{low!r}, {high!r}] ({evaluations[0][1]:.6g} at {low!r}, {evaluations[-1][1]:.6g} "
            f"at {high!r}): widen or move the bracket."
        )
    for _ in range(MAX_ROUNDS):
        if 0.0 in rs:
            break
        k = next(i for i in range(len(rs) - 1) if _sign(rs[i]) != _sign(rs[i + 1]))
        low, high, r_low, r_high = xs[k], xs[k + 1], rs[k], rs[k + 1]
        if not high - low >= problem.xtol:
            break
        interior = split(low, high, problem.points)
        xs, rs = [low, *interior, high], [r_low, *residuals(interior), r_high]
    best = min(range(len(evaluations)), key=lambda i: abs(evaluations[i][1] - problem.target))
    x, y = evaluations[best]
    if abs(y - problem.target) > problem.tolerance:
        raise CalibrationFailed(
            f"the best point, {x!r}, gives {problem.metric} = {y:.6g}, {abs(y - problem.target):.3g}"
            f" from the target {problem.target:g} (tolerance {problem.tolerance:g}): the "
            "criterion cannot be met within the bracket's resolution (xtol)."
        )
    return SearchResult(value=x, measured=y, evaluations=tuple(evaluations))


def _sign(r: float) -> int:
    """-1, 0 or 1 (a product of two tiny residuals could underflow to zero)."""
    return (r > 0) - (r < 0)


def measure_at(value: Any, metrics: Sequence[str], evaluate: Evaluator) -> SearchResult:
    """One run at a chosen ``value``; the measured criterion is recorded beside it.

    Raises:
        CalibrationFailed: a metric gives no value.
    """
    return SearchResult(value=value, measured=_measured(metrics, evaluate, value))


def measure(metrics: Sequence[str], evaluate: Evaluator) -> SearchResult:
    """One run; the value is the measured metric, or the tuple of several.

    Raises:
        CalibrationFailed: a metric gives no value.
    """
    value = _measured(metrics, evaluate, None)
    return SearchResult(value=value, measured=value)


def _measured(metrics: Sequence[str], evaluate: Evaluator, value: Any) -> float | tuple[float, ...]:
    """The criterion metric (or the tuple of several) of one run at ``value`` (None: the
    spec's own)."""
    (row,) = evaluate([value])
    values = tuple(float(row.get(m, math.nan)) for m in metrics)
    bad = [m for m, v in zip(metrics, values, strict=True) if not math.isfinite(v)]
    if bad:
        raise CalibrationFailed(f"the run gives no value of {', '.join(bad)}.")
    return values[0] if len(values) == 1 else values
