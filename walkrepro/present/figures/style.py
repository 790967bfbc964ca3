"""One figure style for the three papers: titles, legends, colours, E-FSM states, saving.

Every figure module draws with these helpers, so a figure of any paper reads the same way:

- the title names the paper and its figure (``Lee et al. 2021, Fig. 7``), then what is
  shown, with the experiment on a second line;
- panels are tagged as in the paper (``(a)``, ``(b)``) at their top left;
- legends sit outside the axes, to the right, never on the data;
- one colour-blind-safe palette (Okabe-Ito) for every line;
- yes/no outcomes in two colours with a legend, never a continuous colour bar.
"""

from __future__ import annotations

import contextvars
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np

if TYPE_CHECKING:
    from walkrepro.evaluation.metrics import LogData

#: Okabe-Ito colours (colour-blind safe), in the order lines take them.
PALETTE = (
    "#0072B2",  # blue
    "#E69F00",  # orange
    "#009E73",  # bluish green
    "#D55E00",  # vermillion
    "#CC79A7",  # reddish purple
    "#56B4E9",  # sky blue
    "#F0E442",  # yellow
    "#000000",  # black
)
#: Matplotlib settings shared by every figure.
RC: Mapping[str, Any] = {
    "axes.prop_cycle": mpl.cycler(color=PALETTE),
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.titlesize": "medium",
    "axes.titlelocation": "left",
    "axes.labelsize": "medium",
    "axes.spines.top": False,
    "axes.spines.right": False,
    "legend.fontsize": "small",
    "legend.frameon": False,
    "figure.titlesize": "large",
    "font.size": 10,
}
#: E-FSM states by the ``efsm_phase`` code the controller logs (Lee et al. 2021, Table I).
EFSM_STATES: Mapping[float, str] = {0.0: "SSD", 1.0: "SSA", 2.0: "DS"}
#: Height of each E-FSM state on a state axis: the cycle DS → SSD → SSA reads upward.
EFSM_LEVELS: Mapping[str, int] = {"DS": 0, "SSD": 1, "SSA": 2}
#: Support side by the ``fsm_state`` value the controller logs (1 left, −1 right, 0 both).
SUPPORT_SIDES: Mapping[float, str] = {1.0: "left support", -1.0: "right support"}
#: Colours of a yes/no map: (no, yes), apart from a map's grey "no value".
YES_NO_COLOURS = (PALETTE[1], PALETTE[0])
#: Colours of a fall map: (no fall, fell), light tints of bluish green and vermillion, so
#: the map's crimson fall marks and boundary stay visible on them.
FALL_COLOURS = ("#9AD5BF", "#F2B28C")


def use() -> None:
    """Apply :data:`RC` to matplotlib (every figure module calls it when it draws)."""
    mpl.rcParams.update(RC)


def paper_name(key: str) -> str:
    """The paper as a figure title names it, e.g. ``Lee et al. 2021`` (its plugin's
    :attr:`walkrepro.plugins.Paper.title`; the key itself for an undeclared one)."""
    from walkrepro import plugins

    paper = plugins.papers().get(key)
    return paper.title if paper is not None else key


def title(fig: plt.Figure, paper: str, figure: str, what: str, experiment: str = "") -> None:
    """The figure's title: ``<paper>, <figure>: <what>``, the experiment on a second line.

    Args:
        fig: the figure.
        paper: the spec's paper key (``lee2021``), or ``walkrepro`` for no paper figure.
        figure: the paper's figure, e.g. ``Fig. 7`` (empty for none).
        what: what the figure shows.
        experiment: the experiment (or ``a vs b``) the figure is drawn from.
    """
    head = ", ".join(x for x in (paper_name(paper), figure) if x)
    text = f"{head}: {what}" + (f"\n{experiment}" if experiment else "")
    fig.suptitle(text)


def panel(ax: plt.Axes, tag: str, what: str = "") -> None:
    """Tag a panel as the paper does, ``(a)``, with what it shows, at its top left."""
    ax.set_title(f"({tag}) {what}".strip() if tag else what, loc="left")


def legend(ax: plt.Axes, **kwargs: Any) -> None:
    """A legend outside the axes, to their right, so it never hides data (no-op without
    labelled artists)."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    ax.legend(
        handles,
        labels,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0.0,
        **kwargs,
    )


def efsm_states(ax: plt.Axes, t: np.ndarray, phase: np.ndarray) -> None:
    """The E-FSM state over time as a step line on a named axis (DS, SSD, SSA).

    Args:
        ax: the axes.
        t: times [s], shape (N,).
        phase: ``efsm_phase`` codes (0 SSD, 1 SSA, 2 DS), shape (N,).
    """
    levels = np.array([EFSM_LEVELS[EFSM_STATES.get(float(p), "DS")] for p in phase], dtype=float)
    ax.step(t, levels, where="post", color=PALETTE[0], label="E-FSM state")
    ax.set_yticks(list(EFSM_LEVELS.values()), list(EFSM_LEVELS))
    ax.set_ylim(-0.5, len(EFSM_LEVELS) - 0.5)
    ax.set_ylabel("state")


def support_sides(ax: plt.Axes, t: np.ndarray, state: np.ndarray) -> None:
    """Shade the single-support spans by side (``fsm_state``: 1 left, −1 right).

    Args:
        ax: the axes.
        t: times [s], shape (N,).
        state: ``fsm_state`` values, shape (N,).
    """
    if not t.size:
        return
    colours = {1.0: PALETTE[5], -1.0: PALETTE[1]}
    for value, name in SUPPORT_SIDES.items():
        on = state == value
        ax.fill_between(
            t,
            0,
            1,
            where=on,
            step="post",
            color=colours[value],
            alpha=0.18,
            lw=0,
            transform=ax.get_xaxis_transform(),
            label=name if np.any(on) else None,
        )


_TITLE_NOTE: contextvars.ContextVar[str] = contextvars.ContextVar("title_note", default="")


@contextmanager
def title_note(note: str) -> Iterator[None]:
    """Inside, every figure :func:`save` writes gets ``note`` as the last line of its title
    (a figure drawn from a damaged log says ``PARTIAL (...)``, whichever module drew it)."""
    token = _TITLE_NOTE.set(note)
    try:
        yield
    finally:
        _TITLE_NOTE.reset(token)


#: An artist with more vertices than this is drawn as pixels inside the SVG (the axes, text
#: and sparse lines stay vectors): a 2 kHz log's line of 33 000 points, or a state band's
#: thousands of polygons, would otherwise make an SVG of megabytes for a 30 kB PNG.
DENSE_VERTICES = 2000
#: Resolution [dpi] of the rasterized artists of an SVG (the PNG's 120, a little sharper).
SVG_RASTER_DPI = 150


def _vertices(artist: object) -> int:
    """How many vertices an artist draws (a line's points, a collection's paths')."""
    from matplotlib.collections import Collection
    from matplotlib.image import AxesImage
    from matplotlib.lines import Line2D

    if isinstance(artist, Line2D):
        return len(artist.get_xdata())
    if isinstance(artist, Collection):
        return sum(len(path.vertices) for path in artist.get_paths())
    if isinstance(artist, AxesImage):
        return DENSE_VERTICES + 1  # an image is pixels already
    return 0


def rasterize_dense(fig: plt.Figure) -> int:
    """Mark every artist of ``fig`` with more than :data:`DENSE_VERTICES` vertices
    rasterized (vector output draws it as an image); returns how many were marked."""
    marked = 0
    for ax in fig.axes:
        for artist in (*ax.lines, *ax.collections, *ax.images):
            if _vertices(artist) > DENSE_VERTICES:
                artist.set_rasterized(True)
                marked += 1
    return marked


def save(fig: plt.Figure, stem: Path) -> list[Path]:
    """Write ``stem.png`` and ``stem.svg`` and close the figure (legends outside the axes
    are kept in the picture). In the SVG, dense artists are pixels (:func:`rasterize_dense`)
    so that it stays the size of the PNG, not megabytes."""
    note = _TITLE_NOTE.get()
    if note:
        head = fig._suptitle.get_text() if fig._suptitle is not None else ""  # noqa: SLF001
        fig.suptitle(f"{head}\n{note}" if head else note, color="#b00000")
    stem.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    fig.savefig(paths[0], dpi=120, bbox_inches="tight")
    rasterize_dense(fig)
    fig.savefig(paths[1], dpi=SVG_RASTER_DPI, bbox_inches="tight")
    plt.close(fig)
    return paths


def save_titled(fig: plt.Figure, d: LogData, figure: str, what: str, stem: Path) -> list[Path]:
    """:func:`title` from the run ``d`` (its paper, its experiment), then :func:`save`."""
    title(fig, d.spec.paper.key, figure, what, d.spec.name)
    return save(fig, stem)
