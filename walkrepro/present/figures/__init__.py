"""Figure registry: which figures a run gets, by the paper its spec reproduces.

Every run gets the generic overview (:mod:`walkrepro.present.figures.overview`); the module a plugin
declares for the run's paper key (:mod:`walkrepro.plugins`; walkrepro's own are
``walkrepro/papers/<paper>/figures.py``) adds the figures that redraw that paper's plots.
Figures read only the log.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: figures are files, never windows

from walkrepro import plugins  # noqa: E402
from walkrepro.evaluation.metrics import LogData  # noqa: E402
from walkrepro.present.figures import style  # noqa: E402

style.use()  # one style for every paper's figures

#: A figure function draws from one log and returns the written files.
FigureFn = Callable[[LogData, Path], list[Path]]
#: A comparison figure draws from two logs (e.g. with and without impedance).
CompareFn = Callable[[LogData, LogData, Path], list[Path]]


def _paper_figures(paper: str) -> tuple[list[FigureFn], list[CompareFn]]:
    """The FIGURES and COMPARE lists of the module a plugin declares for ``paper``."""
    modules = plugins.figure_modules()
    if paper not in modules:
        return [], []
    module = plugins.load(modules[paper])
    return list(getattr(module, "FIGURES", [])), list(getattr(module, "COMPARE", []))


def plot_run(log_path: Path, out_dir: Path, partial: bool = False) -> list[Path]:
    """Draw every figure registered for the run's paper, plus the overview.

    A cut or damaged log is refused unless ``partial``; every figure's title then says
    ``PARTIAL`` and what the log holds (:mod:`walkrepro.log.integrity`).
    """
    from walkrepro.log.integrity import partial_title
    from walkrepro.present.figures import overview, style

    data = LogData.from_path(log_path, partial)
    out_dir.mkdir(parents=True, exist_ok=True)
    with style.title_note(partial_title(data.integrity)):
        written = overview.overview(data, out_dir)
        for fn in _paper_figures(data.spec.paper.key)[0]:
            written += fn(data, out_dir)
    return written


def plot_compare(log_a: Path, log_b: Path, out_dir: Path, partial: bool = False) -> list[Path]:
    """Draw the paper's comparison figures for two runs (and the overview of both); a
    damaged log as :func:`plot_run`."""
    from walkrepro.log.integrity import partial_title
    from walkrepro.present.figures import overview, style

    a, b = LogData.from_path(log_a, partial), LogData.from_path(log_b, partial)
    out_dir.mkdir(parents=True, exist_ok=True)
    note = " ".join(x for x in (partial_title(a.integrity), partial_title(b.integrity)) if x)
    with style.title_note(note):
        written = overview.compare(a, b, out_dir)
        for fn in _paper_figures(a.spec.paper.key)[1]:
            written += fn(a, b, out_dir)
    return written
