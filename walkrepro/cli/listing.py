"""``walkrepro list``: every experiment, as a terminal table or one line each."""

from __future__ import annotations

import dataclasses
import re
import sys
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from walkrepro.cli.common import friendly_errors, make_console

if TYPE_CHECKING:
    from walkrepro.specs.models import ExperimentSpec


@friendly_errors
def list_cmd(
    long: Annotated[
        bool,
        typer.Option("--long", "-l", help="Also the robot, the controller and the description."),
    ] = False,
) -> None:
    """List every experiment: its name, paper, figures and what it runs.

    Your own folder's experiments are listed too, with --experiments DIR. On a terminal the
    list is a table that fits its width; piped, it is one line per experiment. --long adds
    the robot, the controller and the whole description.
    """
    from walkrepro.specs.files import all_experiment_names, load_spec

    rows = [ListRow.of(name, load_spec(name).spec) for name in all_experiment_names()]
    if sys.stdout.isatty():
        console = make_console()
        if long:
            console.print(*experiments_long(rows), sep="\n")
        else:
            console.print(experiments_table(rows, console.width))
    else:
        for line in list_lines(rows, long):
            print(line)


@dataclasses.dataclass(frozen=True)
class ListRow:
    """One experiment as ``walkrepro list`` shows it.

    Attributes:
        name: the experiment's name.
        paper: the paper's key (``lee2021``, ``faraji``, ``jo_oh``; ``walkrepro``: its own).
        figure: the paper's figures (``6, 7, 8, 15``), or ``-``.
        summary: the description's first sentence, without a leading citation the other
            columns repeat.
        robot: the robot's name.
        controller: the controller's type.
        description: the whole description.
    """

    name: str
    paper: str
    figure: str
    summary: str
    robot: str
    controller: str
    description: str

    @classmethod
    def of(cls, name: str, spec: ExperimentSpec) -> ListRow:
        """The row of experiment ``name`` with spec ``spec``."""
        description = " ".join(spec.description.split())
        return cls(
            name=name,
            paper=spec.paper.key,
            figure=spec.paper.figure or "-",
            summary=_summary(description),
            robot=spec.robot,
            controller=spec.controller.type,
            description=description,
        )


#: A leading citation of a description ("Paper II Fig. 14 B: ", "Lee et al. 2021 §VI-A
#: (Figs. 6–8): "), which the paper and figure columns already show.
_CITATION = re.compile(r"^(Paper [IV]+|Lee et al\. 2021)\b[^:]{0,40}:\s+")


#: Abbreviations whose full stop ends no sentence.
_ABBREVIATIONS = ("al.", "Fig.", "Figs.", "Eq.", "Eqs.", "e.g.", "i.e.", "vs.", "cf.", "approx.")
#: Longest summary of piped ``walkrepro list`` [characters].
SUMMARY_CHARS = 100


def _summary(description: str) -> str:
    """The description's first sentence without its leading citation, at most
    :data:`SUMMARY_CHARS` characters (cut at a word, ending in an ellipsis)."""
    text = _CITATION.sub("", description, count=1)
    for match in re.finditer(r"[.;] ", text):
        end = match.start() + 1
        if not text[:end].endswith(_ABBREVIATIONS):
            text = text[:end] if match.group()[0] == "." else text[: end - 1]
            break
    if len(text) > SUMMARY_CHARS:
        text = text[: SUMMARY_CHARS - 1].rsplit(" ", 1)[0].rstrip(",;:") + "…"
    return text


def experiments_table(rows: list[ListRow], width: int) -> Table:
    """The terminal table of ``walkrepro list`` for a terminal ``width`` columns wide: name,
    paper and figures never shrink, the summary takes what is left and ends in an ellipsis."""
    # One space after each column, none before the first or after the last.
    table = Table(box=None, padding=(0, 1, 0, 0), pad_edge=False, header_style="bold")
    used = 0
    for header, values in (
        ("experiment", [r.name for r in rows]),
        ("paper", [r.paper for r in rows]),
        ("fig.", [r.figure for r in rows]),
    ):
        column_width = max(len(header), *(len(v) for v in values))
        table.add_column(header, no_wrap=True, width=column_width)
        used += column_width + 1  # one space between columns
    rest = max(10, width - used)  # at least 10 characters of text on a very narrow terminal
    table.add_column("what it runs", no_wrap=True, overflow="ellipsis", width=rest)
    for row in rows:
        table.add_row(row.name, row.paper, row.figure, row.summary)
    return table


def experiments_long(rows: list[ListRow]) -> list[Any]:
    """``walkrepro list --long`` on a terminal: per experiment, a line with its name, paper,
    figures, robot and controller, then its whole description, indented and wrapped to the
    terminal's width (a table would squeeze it to a few characters on 80 columns)."""
    from rich.padding import Padding
    from rich.text import Text

    out: list[Any] = []
    for row in rows:
        head = Text.assemble(
            (row.name, "bold"),
            f"  {row.paper} · fig. {row.figure} · {row.robot} · {row.controller}",
        )
        out += [head, Padding(Text(row.description), (0, 0, 1, 4))]
    return out


def list_lines(rows: list[ListRow], long: bool = False) -> list[str]:
    """``walkrepro list`` piped: one line per experiment, columns aligned by spaces (name,
    paper, figures, then the summary, or with ``long`` the robot, controller and whole
    description), so ``grep``, ``head`` and ``cut`` read it."""
    if not rows:
        return []
    fields = [
        (r.name, r.paper, r.figure, r.robot, r.controller) if long else (r.name, r.paper, r.figure)
        for r in rows
    ]
    widths = [max(len(f[i]) for f in fields) for i in range(len(fields[0]))]
    return [
        "  ".join(f.ljust(w) for f, w in zip(field, widths, strict=True))
        + "  "
        + (r.description if long else r.summary)
        for field, r in zip(fields, rows, strict=True)
    ]
