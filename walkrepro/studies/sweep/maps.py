"""Maps of a sweep, drawn from ``cells.csv`` alone (so ``walkrepro plot SWEEP_DIR`` redraws them).

- one grid field: the map's metric against the field, each cell marked by its outcome;
- two: a heat map of the metric (x = first field, y = second), the boundary between the cells
  that stood/recovered and those that fell (or, for a declared map with ``success:``, between
  the cells inside and outside that region) drawn as a thick line, fallen and failed cells
  marked;
- more: one heat-map panel per combination of the extra fields' values.

Axes are the grid's own values, evenly spaced (a grid is a list of values, not a mesh).
"""

from __future__ import annotations

import itertools
import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from walkrepro.studies.sweep import store
from walkrepro.studies.sweep.grid import value_text

FAILED = ("error", "crashed")


def plot_sweep(directory: Path, out: Path | None = None) -> list[Path]:
    """Draw ``map.png`` and ``map.svg`` for a sweep directory; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from walkrepro.present.figures import style

    style.use()

    info = store.read_info(directory)
    table = store.read_cells(directory / store.CELLS_FILE)
    out = out or directory
    out.mkdir(parents=True, exist_ok=True)
    fields = [g["field"] for g in info["grid"]]
    values = {g["field"]: list(g["values"]) for g in info["grid"]}
    units = {g["field"]: g.get("unit", "") for g in info["grid"]}
    metric = info["map_metric"]
    rows = {tuple(value_text(r[f]) for f in fields): r for r in table.rows}
    if len(fields) == 1:
        fig = _line(plt, fields[0], values[fields[0]], units, rows, metric)
    else:
        fig = _heat_panels(plt, fields, values, units, rows, metric, info.get("success"))
    done = len(table.rows)
    what = "metric" if len(fields) == 1 else "colour"
    subtitle = f"{what}: {metric} · {done} of {info['n_cells']} cells"
    if len(fields) > 1 and _yes_no(metric, [r.get(metric, math.nan) for r in table.rows]):
        subtitle = f"{what}: {metric} (yes/no) · {done} of {info['n_cells']} cells"
    fig.suptitle("\n".join(textwrap.wrap(info["title"], 90)) + f"\n{subtitle}", fontsize=10)
    written = []
    for ext in ("png", "svg"):
        path = out / f"map.{ext}"
        fig.savefig(path, dpi=130)
        written.append(path)
    plt.close(fig)
    return written


def _label(field: str, units: dict[str, str]) -> str:
    unit = units.get(field, "")
    return f"{field} [{unit}]" if unit else field


def _metric_label(metric: str) -> str:
    """The metric with the unit its registered description gives (``[N]``), if any: the
    last bracket outside parentheses (a parenthesis describes the argument, e.g. "(arg: push
    time [s])", not the value)."""
    import re

    from walkrepro.evaluation.metrics import metric_doc, split_metric

    try:
        doc = metric_doc(split_metric(metric)[0])
    except KeyError:
        doc = ""
    outside = None
    while outside != doc:
        outside, doc = doc, re.sub(r"\([^()]*\)", "", doc)
    units = re.findall(r"\[([^\]]+)\]", doc)
    return f"{metric} [{units[-1]}]" if units else metric


def _stood(row: dict[str, Any] | None) -> bool | None:
    """True: the run ended without a fall; False: it fell; None: no measurement."""
    if row is None or row["outcome"] in FAILED or row["outcome"] not in ("complete", "fell"):
        return None
    return row["outcome"] == "complete" and not row.get("fell", 0.0) == 1.0


def _line(plt: Any, field: str, xs: list[Any], units: dict[str, str], rows: dict, metric: str):
    fig, ax = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
    numeric = all(isinstance(x, int | float) and not isinstance(x, bool) for x in xs)
    pos = [float(x) for x in xs] if numeric else list(range(len(xs)))
    ys = [rows.get((value_text(x),), {}).get(metric, math.nan) for x in xs]
    ax.plot(pos, ys, "-", color="0.6", zorder=1)
    finite = [y for y in ys if not math.isnan(y)]
    floor = min(finite) if finite else 0.0
    for p, x, y in zip(pos, xs, ys, strict=True):
        row = rows.get((value_text(x),))
        stood = _stood(row)
        if row is None:
            continue
        if stood is None:
            ax.scatter([p], [floor], marker="s", color="0.5", s=60, zorder=3)
            ax.annotate(
                row["outcome"],
                (p, floor),
                textcoords="offset points",
                xytext=(0, 8),
                ha="center",
                fontsize=8,
            )
        elif stood:
            ax.scatter([p], [y], marker="o", color="tab:green", s=50, zorder=3)
        else:
            ax.scatter(
                [p],
                [y if not math.isnan(y) else floor],
                marker="X",
                color="tab:red",
                s=80,
                zorder=3,
            )
    ax.scatter([], [], marker="o", color="tab:green", label="no fall")
    ax.scatter([], [], marker="X", color="tab:red", label="fell")
    ax.scatter([], [], marker="s", color="0.5", label="error / crashed")
    ax.legend(fontsize=8, loc="best")
    if not numeric:
        ax.set_xticks(pos, [value_text(x) for x in xs])
    ax.set_xlabel(_label(field, units))
    ax.set_ylabel(_metric_label(metric))
    ax.grid(alpha=0.3)
    return fig


def _heat_panels(
    plt: Any,
    fields: Sequence[str],
    values: dict[str, list[Any]],
    units: dict[str, str],
    rows: dict,
    metric: str,
    success: dict | None = None,
):
    """The heat map of ``metric`` over the first two grid fields, one panel per combination
    of the others, with the success boundary and a legend."""
    fx, fy, extra = fields[0], fields[1], list(fields[2:])
    combos = list(itertools.product(*(values[f] for f in extra))) or [()]
    ncol = min(len(combos), 3)
    nrow = math.ceil(len(combos) / ncol)
    xs, ys = values[fx], values[fy]
    w = max(4.6, 0.95 * len(xs) + 2.2)
    h = max(3.6, 0.75 * len(ys) + 1.8)
    fig, axes = plt.subplots(
        nrow, ncol, figsize=(w * ncol + 1.2, h * nrow + 1.0), squeeze=False, layout="constrained"
    )
    grids = [_panel_grid(xs, ys, combo, rows, metric) for combo in combos]
    finite = np.concatenate([g[0][np.isfinite(g[0])] for g in grids]) if grids else np.zeros(0)
    binary, no_yes, cmap, norm = _colour_scale(metric, finite)
    mesh = None
    for k, (combo, (m, cells)) in enumerate(zip(combos, grids, strict=True)):
        ax = axes[k // ncol][k % ncol]
        ax.set_facecolor("0.85")
        mesh = ax.pcolormesh(
            np.arange(len(xs) + 1) - 0.5, np.arange(len(ys) + 1) - 0.5, m, cmap=cmap, norm=norm
        )
        ax.grid(False)
        for (i, j), row in cells.items():
            words = _yes_no_words(metric) if binary else None
            _annotate(ax, i, j, row, m[j, i], norm, (no_yes, words) if words else None)
        _boundary(ax, cells, len(xs), len(ys), success)
        ax.set_xticks(range(len(xs)), [_tick(x) for x in xs])
        ax.set_yticks(range(len(ys)), [_tick(y) for y in ys])
        ax.set_xlabel(_label(fx, units))
        ax.set_ylabel(_label(fy, units))
        if combo:
            ax.set_title(
                ", ".join(
                    f"{f} = {_tick(v)}{' ' + units.get(f, '') if units.get(f) else ''}"
                    for f, v in zip(extra, combo, strict=True)
                ),
                fontsize=9,
            )
    for k in range(len(combos), nrow * ncol):
        axes[k // ncol][k % ncol].axis("off")
    if mesh is not None and not binary:
        bar = fig.colorbar(mesh, ax=axes.ravel().tolist(), shrink=0.9)
        bar.set_label(_metric_label(metric))
    _legend(fig, metric, no_yes if binary else None, success)
    return fig


def _panel_grid(
    xs: Sequence[Any], ys: Sequence[Any], combo: tuple, rows: dict, metric: str
) -> tuple[np.ndarray, dict[tuple[int, int], dict | None]]:
    """One panel's values (rows ``ys``, columns ``xs``; NaN where no cell or it failed) and
    its cells by (column, row), the other fields at ``combo``."""
    m = np.full((len(ys), len(xs)), np.nan)
    cells: dict[tuple[int, int], dict | None] = {}
    for (i, x), (j, y) in itertools.product(enumerate(xs), enumerate(ys)):
        key = tuple(value_text(v) for v in (x, y, *combo))
        row = rows.get(key)
        cells[(i, j)] = row
        if row is not None and row["outcome"] not in FAILED:
            m[j, i] = row.get(metric, math.nan)
    return m, cells


def _colour_scale(metric: str, finite: np.ndarray) -> tuple[bool, Any, Any, Any]:
    """Whether the metric is yes/no, its two colours, the colour map and the norm: a yes/no
    metric (``fell``, ``stepped_on_off``) gets two colours and a legend; any other a
    continuous colour map over the measured values."""
    from matplotlib.colors import BoundaryNorm, ListedColormap, Normalize

    binary = _yes_no(metric, list(finite))
    no_yes = _yes_no_colours(metric)
    cmap: Any = ListedColormap(list(no_yes)) if binary else "viridis"
    norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0, 1))
    if finite.size and norm.vmin == norm.vmax:
        norm = Normalize(norm.vmin - 0.5, norm.vmax + 0.5)
    if binary:
        norm = BoundaryNorm([-0.5, 0.5, 1.5], 2)
    return binary, no_yes, cmap, norm


def _legend(fig: Any, metric: str, no_yes: Any, success: dict | None) -> None:
    """The figure's legend: the yes/no colours (``no_yes``, for a yes/no metric), the
    success boundary, a fall and a cell without a value."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = []
    if no_yes is not None:
        no_label, yes_label = _yes_no_labels(metric)
        handles += [
            Patch(facecolor=no_yes[1], label=yes_label),
            Patch(facecolor=no_yes[0], label=no_label),
        ]
    handles += [
        Line2D([], [], color="crimson", lw=3, label=_boundary_label(success)),
        Line2D([], [], color="crimson", marker="x", lw=0, markersize=9, mew=2.5, label="fell"),
        Line2D([], [], color="0.85", marker="s", lw=0, markersize=9, label="no value"),
    ]
    fig.legend(
        handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8, frameon=False
    )


def _yes_no(metric: str, values: Sequence[float]) -> bool:
    """Whether a map's metric is a yes/no outcome: its registered description reads "1 if
    …, else 0" and every measured value is 0 or 1."""
    from walkrepro.evaluation.metrics import metric_doc, split_metric

    try:
        doc = metric_doc(split_metric(metric)[0])
    except KeyError:
        return False
    finite = [float(v) for v in values if not math.isnan(float(v))]
    return doc.startswith("1 if") and all(v in (0.0, 1.0) for v in finite)


def _yes_no_colours(metric: str) -> tuple[str, str]:
    """The (no, yes) colours of a yes/no map: a fall in vermillion, no fall in green."""
    from walkrepro.present.figures import style

    return style.FALL_COLOURS if metric == "fell" else style.YES_NO_COLOURS


def _yes_no_words(metric: str) -> tuple[str, str]:
    """What a yes/no map writes in a (no, yes) cell (a fall is also marked, with its time)."""
    return ("stood", "") if metric == "fell" else ("no", "yes")


def _yes_no_labels(metric: str) -> tuple[str, str]:
    """The legend's (no, yes) labels of a yes/no map."""
    if metric == "fell":
        return "no fall (fell = 0)", "fell (fell = 1)"
    return f"no ({metric} = 0)", f"yes ({metric} = 1)"


def _dark(colour: str) -> bool:
    """Whether white text reads better than black on ``colour`` (its luminance)."""
    from matplotlib.colors import to_rgb

    r, g, b = to_rgb(colour)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.5


def _tick(v: Any) -> str:
    if isinstance(v, bool):
        return "on" if v else "off"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def _annotate(
    ax: Any,
    i: int,
    j: int,
    row: dict | None,
    value: float,
    norm: Any,
    yes_no: tuple[tuple[str, str], tuple[str, str]] | None = None,
) -> None:
    """The cell's value (on a yes/no map, ``yes_no`` = ((no, yes) colours, (no, yes)
    words): its word), and its outcome when it fell or failed."""
    if row is None:
        ax.text(i, j, "not run", ha="center", va="center", fontsize=8, color="0.3")
        return
    if row["outcome"] in FAILED:
        ax.text(
            i, j, row["outcome"], ha="center", va="center", fontsize=8, color="black", weight="bold"
        )
        return
    if yes_no is not None:
        (colours, words), k = yes_no, 0 if math.isnan(value) else int(value)
        dark = not math.isnan(value) and _dark(colours[k])
        text = "–" if math.isnan(value) else words[k]
    else:
        dark = not math.isnan(value) and norm(value) < 0.55
        text = "–" if math.isnan(value) else f"{value:.4g}"
    colour = "white" if dark else "black"
    if _stood(row) is False:
        # In the cell's corner, so the value stays readable.
        ax.scatter(
            [i + 0.34], [j + 0.3], marker="x", s=90, color="crimson", linewidths=2.5, zorder=3
        )
        t = row.get("fall_time", math.nan)
        text = (text + ("" if math.isnan(t) else f"\nfell {t:.2f} s")).strip()
    ax.text(i, j, text, ha="center", va="center", fontsize=8, color=colour, zorder=4)


def _boundary_label(success: dict | None) -> str:
    if success is None:
        return "no-fall / fall boundary"
    from walkrepro.specs.sweeps import Region

    return f"boundary of {Region.model_validate(success)}"


def _inside(row: dict[str, Any] | None, success: dict | None) -> bool | None:
    """Whether a cell lies in the map's success region (default: it did not fall)."""
    if success is None:
        return _stood(row)
    from walkrepro.specs.sweeps import Region
    from walkrepro.studies.sweep.claims import in_region

    return None if row is None else in_region(row, Region.model_validate(success))


def _boundary(
    ax: Any,
    cells: dict[tuple[int, int], dict | None],
    nx: int,
    ny: int,
    success: dict | None = None,
) -> None:
    """Thick segments on the edges between a cell inside the success region (default: it
    stood) and a neighbour outside it."""
    for i, j in itertools.product(range(nx), range(ny)):
        here = _inside(cells[(i, j)], success)
        if here is None:
            continue
        if i + 1 < nx:
            there = _inside(cells[(i + 1, j)], success)
            if there is not None and there != here:
                ax.plot([i + 0.5, i + 0.5], [j - 0.5, j + 0.5], color="crimson", lw=3, zorder=5)
        if j + 1 < ny:
            there = _inside(cells[(i, j + 1)], success)
            if there is not None and there != here:
                ax.plot([i - 0.5, i + 0.5], [j + 0.5, j + 0.5], color="crimson", lw=3, zorder=5)
