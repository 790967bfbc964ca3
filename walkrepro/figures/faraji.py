"""Figures that redraw the faraji paper's plots from a run's log."""

from __future__ import annotations

from walkrepro.figures import CompareFn, FigureFn

#: Figures drawn from one run.
FIGURES: list[FigureFn] = []
#: Figures comparing two runs (`walkrepro plot RUN_A RUN_B`).
COMPARE: list[CompareFn] = []
