"""A batch's verdicts as ``run`` and ``check`` print them: one line per experiment or
claim, failing rows in full, or the table of every row."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich.markup import escape
from rich.table import Table

from walkrepro.cli.common import make_console

if TYPE_CHECKING:
    from walkrepro.evaluation.checks import Verdict


def print_verdicts(
    verdicts: list[Verdict],
    details: bool = True,
    per_claim: bool = False,
) -> None:
    """Print a batch's verdicts and the count line ``N reproduced, C calibrated, M known
    deviations, K failed``.

    With ``details``, the table of every row (paper value, measured value and a known
    deviation's observed band side by side). Without, one line per experiment (with
    ``per_claim``, one line per claim: ``walkrepro run``), then the failing rows in full: a
    failure is never hidden.
    """
    from walkrepro.evaluation.checks import FAIL, claim_lines, count, failing_row_text, summary_line

    console = make_console()
    if details:
        console.print(verdict_table(verdicts))
    elif per_claim:
        for v in verdicts:
            for row, text in zip(v.rows, claim_lines(v), strict=True):
                colour = "red" if row.status == FAIL else "default"
                console.print(f"[{colour}]{escape(text)}[/]", highlight=False, soft_wrap=True)
        for v in verdicts:
            for text in failing_row_text(v):
                console.print(f"[red]{escape(text)}[/]", highlight=False, soft_wrap=True)
    else:
        width = max((len(v.experiment) for v in verdicts), default=0)
        for v in verdicts:
            colour = "green" if v.passed else "red"
            console.print(
                f"[{colour}]{escape(summary_line(v, width))}[/]", highlight=False, soft_wrap=True
            )
        for v in verdicts:
            for text in failing_row_text(v):
                console.print(f"[red]{escape(text)}[/]", highlight=False, soft_wrap=True)
    from walkrepro.publish.claim_register import batch_lines

    for line in batch_lines(verdicts):
        console.print(escape(line), highlight=False, soft_wrap=True)
    counts = count(verdicts)
    colour = "red" if counts.failed else ("yellow" if counts.known else "green")
    console.print(f"[bold {colour}]all rows: {counts}[/]")


def verdict_table(verdicts: list[Verdict]) -> Table:
    """Every row of ``verdicts`` as a table; long sources and notes fold, never cut."""
    from walkrepro.evaluation.checks import CALIBRATED, FAIL, KNOWN, PASS, tag_text

    label = {
        PASS: "[green]reproduced[/]",
        CALIBRATED: "[blue]calibrated[/]",
        FAIL: "[red]failed[/]",
        KNOWN: "[yellow]known deviation[/]",
    }
    table = Table(title="paper expectations")
    columns = ("experiment", "metric", "tests", "paper", "measured", "observed", "result")
    for col in (*columns, "source / note"):
        table.add_column(col, overflow="fold")
    for v in verdicts:
        if not v.run_ok:
            table.add_row(v.experiment, "run", "", "", v.outcome, "", label[FAIL], "")
        for r in v.rows:
            note = f" — {r.note}" if r.note else ""
            table.add_row(
                v.experiment,
                r.metric,
                tag_text(r),
                r.band,
                r.measured_text,
                r.observed_band,
                label[r.status],
                escape(f"{r.source}{note}"),
            )
    return table
