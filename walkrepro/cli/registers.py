"""The commands over the committed results: ``provenance`` (every number a run uses),
``claims`` (the claim registers), ``report`` (the HTML site) and ``docs`` (the generated
documents)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from walkrepro.cli.common import (
    ForceOption,
    SetOption,
    friendly_errors,
    make_console,
    needs_checkout,
)
from walkrepro.locations import REFERENCES_DIR


@friendly_errors
def provenance(
    experiments: Annotated[
        list[str], typer.Argument(help="Experiment names or paths to spec YAML files.")
    ],
    set_: SetOption = None,
    unclassified_only: Annotated[
        bool, typer.Option("--unclassified", help="List only the numbers without a class.")
    ] = False,
) -> None:
    """List every number an experiment's run uses, with its provenance class and source.

    The numbers of the robot, the scene, the spec and the controller, each classed paper,
    source, assumed or calibrated, with where it comes from (docs/provenance.md). Exit 1
    when one has no class."""
    from walkrepro.publish.ledger import LISTED, UNCLASSIFIED, counts, experiment_ledger

    console = make_console()
    missing = 0
    for name in experiments:
        numbers = experiment_ledger(name, tuple(set_ or ()))
        table = Table(title=f"{name}: every number the run uses")
        for col in ("group", "parameter", "value", "class"):
            table.add_column(col, overflow="fold")
        table.add_column("source", overflow="fold")
        for n in numbers:
            if unclassified_only and n.klass != UNCLASSIFIED:
                continue
            style = "bold red" if n.klass == UNCLASSIFIED else None
            table.add_row(n.group, n.name, n.value, n.klass, n.source, style=style)
        console.print(table)
        c = counts(numbers)
        console.print(
            f"{name}: " + ", ".join(f"{c[k]} {k}" for k in LISTED if c[k] or k != "override"),
            highlight=False,
        )
        missing += c[UNCLASSIFIED]
    if missing:
        raise typer.Exit(code=1)


@friendly_errors
def claims(
    papers: Annotated[
        list[str] | None,
        typer.Argument(help="Paper keys (lee2021, faraji, jo_oh); default: every register."),
    ] = None,
    details: Annotated[
        bool, typer.Option("--details", help="Also print the paper's words and each row.")
    ] = False,
) -> None:
    """List each paper's claims with their status from the committed references.

    The claim register (experiments/claims/<paper>.yaml): every claim reproduced,
    calibrated, deviating, failed, not covered or uncheckable, with the rows that test it and
    their measured values (docs/claims.md). Exit 1 when a claim fails."""
    from walkrepro.locations import REFERENCES_DIR
    from walkrepro.publish.claim_register import FAILED, paper_totals
    from walkrepro.specs.claims import find_register, register_papers

    console = make_console()
    keys = list(papers or register_papers())
    for key in keys:
        find_register(key)  # an unknown paper lists the valid ones before anything runs
    found = paper_totals(REFERENCES_DIR)
    failed = False
    for key in keys:
        totals, results = found[key]
        console.print(f"[bold]{escape(_paper_label(key))}[/]", highlight=False)
        width = max((len(r.claim.id) for r in results), default=0)
        for r in results:
            colour = _CLAIM_COLOURS.get(r.status, "default")
            brief = "" if details else f"  {_rows_brief(r.rows)}"
            line = f"  [{colour}]{r.status:<11}[/] {escape(r.claim.id):<{width}}{escape(brief)}"
            console.print(
                line.rstrip(),
                highlight=False,
                soft_wrap=True,
            )
            if details:
                _print_claim_details(console, r)
        console.print(
            f"{key}: the paper's claims: {totals.claims_text()}; walkrepro's own rows: {totals.own}",
            highlight=False,
        )
        failed |= totals.by_status[FAILED] > 0
    if failed:
        raise typer.Exit(code=1)


def _print_claim_details(console: Console, result: Any) -> None:  # ClaimResult
    """A claim's where, words, uncheckable reason and every row, indented under it."""
    lines = [f"{result.claim.where} ({result.claim.kind}): “{result.claim.words}”"]
    if result.claim.uncheckable:
        lines.append(f"uncheckable: {result.claim.uncheckable}")
    if result.claim.not_covered:
        lines.append(f"not covered: {result.claim.not_covered}")
    lines += [f"row: {t.text}" for t in result.rows]
    for line in lines:
        console.print(f"      {escape(line)}", highlight=False, soft_wrap=True)


_CLAIM_COLOURS = {
    "reproduced": "green",
    "calibrated": "blue",
    "deviating": "yellow",
    "failed": "red",
    "not covered": "magenta",
}


def _paper_label(key: str) -> str:
    from walkrepro import plugins

    paper = plugins.papers().get(key)
    return f"{paper.label} ({key})" if paper is not None else key


def _rows_brief(rows: tuple) -> str:
    """The rows behind a claim, short: ``experiment metric = value`` for the first, and how
    many more."""
    if not rows:
        return ""
    first = rows[0].text
    return first if len(rows) == 1 else f"{first} (+{len(rows) - 1} rows)"


@friendly_errors
def report(
    source: Annotated[
        Path,
        typer.Option(
            "--from",
            help="results/ (the committed references) or a walkrepro check --out directory.",
        ),
    ] = REFERENCES_DIR,
    out: Annotated[
        Path | None,
        typer.Option(
            help="Site directory, replaced as a whole (default: next to --from, report/): a "
            "new or empty directory or an earlier report; any other is refused unless --force."
        ),
    ] = None,
    force: ForceOption = False,
) -> None:
    """Build the static HTML reproduction report.

    The index shows each paper's robot, headline figure and claims counted, and your own
    runs; a page per paper lists each claim with the paper's value, the measured value and
    the verdict, next to the figures, the video and the maps."""
    from walkrepro.publish.report import build_report

    site = build_report(source, out, force=force)
    for note in site.notes:
        make_console(stderr=True).print(f"[yellow]skipped:[/] {escape(note)}", highlight=False)
    for key, t in site.tallies.items():
        registered = key in site.claims and site.claims[key].totals.total > 0
        if registered:
            make_console().print(
                f"{key}: the paper's claims: {site.claims[key].totals.claims_text()}",
                highlight=False,
            )
        make_console().print(
            f"{key}: {'all ' if registered else ''}rows (maps' claims included): "
            f"{t.reproduced} reproduced, {t.calibrated} calibrated, {t.known} known "
            f"deviations, {t.failed} failed",
            highlight=False,
        )
    make_console().print(f"wrote {site.index.as_uri()}", highlight=False)


@friendly_errors
def docs_cmd(
    check_only: Annotated[
        bool,
        typer.Option("--check", help="Write nothing; exit 1 if a generated document is stale."),
    ] = False,
) -> None:
    """Regenerate the generated documents from the specs and the committed results.

    docs/ (the spec reference, the experiments, the known deviations) and the README's
    status table."""
    from walkrepro.publish.docsgen import generated_files, stale_files, write_docs

    needs_checkout("walkrepro docs")
    files = generated_files()
    if check_only:
        stale = stale_files(files)
        for path in stale:
            make_console().print(f"stale: {path} (run walkrepro docs)", highlight=False)
        if stale:
            raise typer.Exit(code=1)
        make_console().print(f"{len(files)} generated documents up to date")
        return
    written = write_docs(files)
    for path in written:
        make_console().print(f"wrote {path}", highlight=False)
    make_console().print(f"{len(files) - len(written)} of {len(files)} already up to date")


def update_docs() -> None:
    """Regenerate the documents made from the references (``walkrepro docs``): new
    references change the README's status table and the deviations' measured values."""
    from walkrepro.publish.docsgen import generated_files, write_docs

    needs_checkout("walkrepro docs")

    for path in write_docs(generated_files()):
        make_console().print(f"docs updated: {path}", highlight=False)
