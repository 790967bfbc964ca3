"""Write the report: an index, one page per paper, the robots' pages and the copied assets.

Layout of the output directory (every link relative, so it opens from ``file://``)::

    index.html                 per paper: a frame of its robot, its headline figure and its
                               register's claims counted; rows by verdict; the user's runs
    style.css
    <paper>.html               every experiment of the paper: claims, figures, video, maps
    robots/<robot>.html        the robot model's README (its sources) and its robot.xml
    assets/<experiment>/...    copied figures and video
    assets/maps/<map>.png      copied maps
    assets/index/<paper>_*.png the index's robot frames and headline figures
"""

from __future__ import annotations

import re
import shutil
from collections import defaultdict
from dataclasses import dataclass, field
from html import escape
from pathlib import Path

from walkrepro import plugins
from walkrepro.errors import WalkreproError
from walkrepro.locations import IS_CHECKOUT, REFERENCES_DIR, RESULTS_DIR
from walkrepro.publish.ledger import counts
from walkrepro.publish.report import html
from walkrepro.publish.report.claims import Tally, experiment_claims, tally
from walkrepro.publish.report.currency import Currency, currency
from walkrepro.publish.report.maps import MapResult, experiment_maps
from walkrepro.publish.report.overview import (
    COUNTS_EXPLAINED,
    STATUS_CSS,
    PaperClaims,
    headline_pictures,
    paper_card,
    paper_claims,
    user_runs,
    user_runs_section,
)
from walkrepro.publish.report.robots import markdown_to_html, robot_readme
from walkrepro.publish.report.sources import ExperimentResult, find_results
from walkrepro.runs import results
from walkrepro.runtime import outdir

#: The maps' directory inside a results tree.
MAPS_DIR = "maps"
#: The papers' order in the index; walkrepro's own sanity experiments come last.
SANITY = "walkrepro"


@dataclass(frozen=True)
class ReportSite:
    """A written report.

    Attributes:
        index: the index page.
        pages: every page written (index, papers, robots).
        tallies: rows by verdict per paper key (experiments and maps together).
        notes: what was skipped, and why.
        claims: each paper's register claims as the index counts them (papers with a
            register only).
    """

    index: Path
    pages: tuple[Path, ...]
    tallies: dict[str, Tally]
    notes: tuple[str, ...]
    claims: dict[str, PaperClaims] = field(default_factory=dict)


def build_report(
    source: Path = REFERENCES_DIR,
    out: Path | None = None,
    runs_root: Path | None = None,
    force: bool = False,
) -> ReportSite:
    """Build the static site from ``source`` into ``out`` (default ``source/../report``; for an installed walkrepro's shipped references,
    ``./results/report``).

    ``source`` is ``results/`` (the committed references) or a ``walkrepro check --out``
    directory; the maps come from ``source/maps`` if it exists, else from ``results/maps``.
    The index's "your runs" lists the runs under ``runs_root`` (default: where
    ``walkrepro run`` writes, ``results/runs``). The output directory is replaced as a whole,
    atomically (:func:`walkrepro.runtime.outdir.replacing`): only when it is walkrepro's
    earlier report or empty, or with ``force``; a failure leaves it as it was.

    Raises:
        WalkreproError: ``source`` holds no results, or ``out`` cannot be written, or holds
            files walkrepro did not write (without ``force``).
    """
    source = source.resolve()
    if out is None:
        # An installed walkrepro's references sit inside the package: its report goes
        # beside the user's results instead.
        in_package = not IS_CHECKOUT and source == REFERENCES_DIR.resolve()
        out = RESULTS_DIR / "report" if in_package else source.parent / "report"
    out = out.resolve()
    if out == source or source.is_relative_to(out):
        raise WalkreproError(f"--out {out}: would overwrite the results it reads ({source}).")
    found, notes = find_results(source)
    maps_root = source / MAPS_DIR if (source / MAPS_DIR).is_dir() else REFERENCES_DIR / MAPS_DIR
    by_paper: dict[str, list[ExperimentResult]] = defaultdict(list)
    for r in found:
        by_paper[r.spec.paper.key].append(r)
    keys = [k for k in plugins.papers() if k in by_paper and k != SANITY] + (
        [SANITY] if SANITY in by_paper else []
    )

    claims = paper_claims(source, found)
    runs_root = runs_root if runs_root is not None else results.DEFAULT_ROOT
    with outdir.replacing(out, outdir.REPORT, force) as work:
        (work / html.CSS_FILE).write_text(html.CSS)
        pages, tallies, robots = [], {}, set()
        for key in keys:
            experiments = sorted(by_paper[key], key=_order)
            page, tallies[key] = _paper_page(work, key, experiments, maps_root, claims.get(key))
            pages.append(page)
            robots.update(r.spec.robot for r in experiments)
        for robot in sorted(robots):
            pages.append(_robot_page(work, robot))
        index = work / "index.html"
        index.write_text(
            _index(work, out, keys, by_paper, tallies, source, notes, claims, runs_root)
        )
    moved = tuple(out / p.relative_to(work) for p in [index, *pages])
    return ReportSite(out / "index.html", moved, tallies, tuple(notes), claims)


def _order(r: ExperimentResult) -> tuple:
    """Experiments in the paper's order: by first figure number, then the shorter name (the
    paper's own experiment before its variants), then name."""
    first = re.search(r"\d+", r.spec.paper.figure)
    return (int(first.group(0)) if first else 10**6, len(r.name), r.name)


def paper_title(key: str) -> str:
    """The paper's citation as the report shows it."""
    if key == SANITY:
        return "Sanity experiments (no paper figure)"
    paper = plugins.papers().get(key)
    return paper.citation if paper is not None else key


def _where(r: ExperimentResult) -> str:
    parts = []
    if r.spec.paper.section:
        parts.append(f"§{r.spec.paper.section}")
    if r.spec.paper.figure:
        parts.append(f"Fig. {r.spec.paper.figure}")
    return ", ".join(parts)


def _copy(path: Path, site: Path, rel: str) -> str:
    """Copy ``path`` to ``site/rel`` and return ``rel`` (a relative link)."""
    target = site / rel
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(path, target)
    return rel


def _reference_currency(r: ExperimentResult) -> Currency:
    """The commit ``r``'s result was made at (its ``run.json``) and whether that is the
    current code for its experiment."""
    return currency(r.run.get("commit"), f"experiments/{r.name}.yaml")


def _currency_cell(c: Currency) -> str:
    css = {True: "pass", False: "known", None: "none"}[c.current]
    return (
        f'<td><span class="verdict {css}">{escape(c.short)}</span> {escape(_currency_word(c))}</td>'
    )


def _currency_word(c: Currency) -> str:
    if c.current is None:
        return "unknown" if c.commit else ""
    return "current code" if c.current else "code changed since"


def _paper_page(
    site: Path,
    key: str,
    experiments: list[ExperimentResult],
    maps_root: Path,
    claims: PaperClaims | None = None,
) -> tuple[Path, Tally]:
    """One paper's page: its register's claims with the references behind them, then each
    experiment's claims next to its figures, its video and maps."""
    total = Tally()
    sections, toc = [], []
    currencies = {r.name: _reference_currency(r) for r in experiments}
    for r in experiments:
        claims_of = experiment_claims(r.check)
        maps = experiment_maps(r.spec, maps_root)
        numbers = _numbers_of(r.name)
        rows = tally(claims_of)
        mapped = sum((tally(m.claims) for m in maps), Tally())
        total = total + rows + mapped
        toc.append(
            f'<tr><td><a href="#{escape(r.name)}">{escape(r.name)}</a></td>'
            f"<td>{escape(_where(r))}</td>{_currency_cell(currencies[r.name])}"
            f'<td class="num">{html.tally_text(rows)}</td>'
            f'<td class="num">{html.tally_text(mapped) if maps else "—"}</td>'
            f"{html.provenance_cell(counts(numbers) if numbers is not None else None)}</tr>"
        )
        sections.append(_experiment_section(site, r, claims_of, maps, numbers, currencies[r.name]))
    robots = sorted({r.spec.robot for r in experiments})
    robot_links = ", ".join(
        f'<a href="robots/{escape(robot)}.html">{escape(robot)}</a>' for robot in robots
    )
    body = (
        '<nav><a href="index.html">← all papers</a></nav>\n'
        f"<h1>{escape(paper_title(key))}</h1>\n"
        f'<p class="muted">{len(experiments)} experiments · robot model and sources: '
        f"{robot_links} · rows and map claims: {total.reproduced} reproduced, "
        f"{total.calibrated} calibrated, {total.known} known deviations, {total.failed} "
        "failed</p>\n"
        + _register_section(key, claims, currencies)
        + '<h2 id="experiments">Experiments</h2>\n'
        '<p class="muted">Rows: the experiment\'s own rows, what <code>walkrepro run</code> '
        "prints; map claims: its maps' claims on the committed cells (<code>walkrepro sweep "
        "--map</code>); each as reproduced · calibrated · known deviation · failed. "
        "Reference: the commit the experiment's reference was made at, and whether the "
        "code (walkrepro/, robots/, the spec) is unchanged since.</p>\n"
        "<table>\n<tr><th>experiment</th><th>paper</th><th>reference</th>"
        f"<th>rows</th><th>map claims</th>{html.PROVENANCE_HEAD}</tr>\n"
        + "\n".join(toc)
        + "\n</table>\n"
        + "\n".join(sections)
    )
    page = site / f"{key}.html"
    page.write_text(html.page(paper_title(key), body))
    return page, total


def _map_currency(map_name: str, experiment: str) -> Currency:
    """The commit a committed map was swept at (``results/maps/<map>/sweep.yaml``) and
    whether that is the current code for its experiment."""
    import yaml

    path = REFERENCES_DIR / MAPS_DIR / map_name / "sweep.yaml"
    try:
        commit = (yaml.safe_load(path.read_text()).get("provenance") or {}).get("commit")
    except (OSError, yaml.YAMLError, AttributeError):
        commit = None
    return currency(commit, f"experiments/{experiment}.yaml")


def _register_section(key: str, claims: PaperClaims | None, currencies: dict[str, Currency]) -> str:
    """The paper's register: each claim with its status, the rows that test it and the
    commit each row's reference was made at (and whether that is the current code)."""
    head = '<h2 id="claims">The paper\'s claims</h2>\n'
    if claims is None or not claims.claims:
        return head + (
            f"<p>No claim register for this paper yet (<code>experiments/claims/"
            f"{escape(key)}.yaml</code>); its experiments' rows follow.</p>\n"
        )
    from walkrepro.publish.claim_register import MAP_MARK

    lines = []
    for result in claims.claims:
        c = result.claim
        rows = []
        for row in result.rows:
            experiment, _, map_name = row.experiment.partition(MAP_MARK)
            cur = _map_currency(map_name, experiment) if map_name else currencies.get(experiment)
            made = f" — reference {escape(cur.short)}, {escape(_currency_word(cur))}" if cur else ""
            rows.append(
                f'<li><a href="#{escape(experiment)}">{escape(row.experiment)}</a> '
                f"<code>{escape(row.metric)}</code> ({escape(row.status)}){made}</li>"
            )
        why = c.uncheckable or c.not_covered or ""
        detail = (
            f'<ul class="rows">{"".join(rows)}</ul>'
            if rows
            else f'<span class="muted">{escape(why)}</span>'
        )
        lines.append(
            f"<tr><td><code>{escape(c.id)}</code></td><td>{escape(c.where)}</td>"
            f"<td>“{escape(c.words)}”</td>"
            f'<td><span class="verdict {STATUS_CSS.get(result.status, "fail")}">'
            f"{escape(result.status)}</span></td><td>{detail}</td></tr>"
        )
    from walkrepro.publish.report.overview import counts_sentence

    return (
        head + f'<p>{counts_sentence(claims.totals)}. <span class="muted">'
        f"{escape(claims.scope)}</span></p>\n"
        '<table class="register"><tr><th>claim</th><th>where</th><th>the paper\'s words</th>'
        "<th>status</th><th>rows that test it (reference commit)</th></tr>\n"
        + "\n".join(lines)
        + "\n</table>\n"
    )


def _numbers_of(name: str) -> list | None:
    """The provenance ledger of experiment ``name`` (walkrepro provenance), or None where it
    cannot be built (a run of a spec that is no longer shipped)."""
    from walkrepro.publish.ledger import experiment_ledger

    try:
        return experiment_ledger(name)
    except WalkreproError:
        return None


def _experiment_section(
    site: Path,
    r: ExperimentResult,
    claims: list,
    maps: list[MapResult],
    numbers: list | None,
    made: Currency | None = None,
) -> str:
    """An experiment: what it reproduces, the claims table beside the redrawn figures, the
    video, and its maps."""
    assets = f"assets/{r.name}"
    figures = [(_copy(f, site, f"{assets}/{f.name}"), f.stem.replace("_", " ")) for f in r.figures]
    media = ""
    if r.video is not None:
        media = html.video_player(
            _copy(r.video, site, f"{assets}/{r.video.name}"), f"{r.name}, simulated time"
        )
    if r.recording is not None:
        media += html.recording_link(_copy(r.recording, site, f"{assets}/{r.recording.name}"))
    outcome = r.check.get("outcome", "")
    meta = (
        f"{escape(_where(r))} · robot "
        f'<a href="robots/{escape(r.spec.robot)}.html">{escape(r.spec.robot)}</a> · '
        f"controller <code>{escape(r.spec.controller.type)}</code> · run {escape(str(outcome))}"
    )
    missing = results.missing_outputs(r.run)  # a stage the run was stopped in, or lacked
    if made is not None:
        meta += f" · reference {escape(made.text)}"
    parts = [
        f'<h2 id="{escape(r.name)}">{escape(r.name)}</h2>',
        f'<p class="muted">{meta}</p>',
        f'<p class="missing">missing: {escape("; ".join(missing))}</p>' if missing else "",
        f"<p>{escape(r.spec.description.strip())}</p>",
        html.provenance_table(numbers) if numbers is not None else "",
        '<div class="experiment">',
        f"<div>{html.claims_table(claims)}</div>",
        f"<div>{media}{html.figure_gallery(figures)}</div>",
        "</div>",
    ]
    for m in maps:
        image = ""
        if m.image is not None:
            rel = _copy(m.image, site, f"assets/{MAPS_DIR}/{m.name}.png")
            image = html.figure_gallery([(rel, f"map {m.name}")])
        parts += [
            f'<h3 id="map-{escape(m.name)}">Map {escape(m.name)}</h3>',
            f'<p class="muted">{escape(m.description.strip())}</p>' if m.description else "",
            '<div class="experiment">',
            f"<div>{html.claims_table(m.claims)}</div>",
            f"<div>{image}</div>",
            "</div>",
        ]
    return "\n".join(p for p in parts if p)


def _robot_page(site: Path, robot: str) -> Path:
    """A robot's README (what every number is and where it comes from) and its MJCF."""
    readme = robot_readme(robot)
    body = ['<nav><a href="../index.html">← all papers</a></nav>']
    if readme is None:
        body.append(f"<h1>{escape(robot)}</h1><p>No README for this robot.</p>")
    else:
        body.append(f'<div class="robot">{markdown_to_html(readme.read_text())}</div>')
        xml = readme.parent / "robot.xml"
        if xml.is_file():
            rel = _copy(xml, site, f"robots/{robot}/robot.xml")
            body.append(
                f'<p>The MuJoCo model: <a href="{escape(rel.removeprefix("robots/"))}">'
                "robot.xml</a>.</p>"
            )
    page = site / "robots" / f"{robot}.html"
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(html.page(f"{robot}: robot model", "\n".join(body), f"../{html.CSS_FILE}"))
    return page


def _index(
    work: Path,
    out: Path,
    keys: list[str],
    by_paper: dict[str, list[ExperimentResult]],
    tallies: dict[str, Tally],
    source: Path,
    notes: list[str],
    claims: dict[str, PaperClaims],
    runs_root: Path,
) -> str:
    """The index: each paper's robot, headline figure and claims counted; what the counts
    include; the rows by verdict per paper; the user's runs."""
    cards = [
        paper_card(
            k,
            paper_title(k),
            f"{k}.html#claims",
            claims.get(k),
            headline_pictures(work, k, source),
            tallies[k],
        )
        for k in keys
        if k != SANITY
    ]
    rows = [
        f'<tr><td><a href="{escape(k)}.html">{escape(paper_title(k))}</a></td>'
        f'<td class="num">{len(by_paper[k])}</td>{html.tally_cells(tallies[k])}</tr>'
        for k in keys
    ]
    total = sum((tallies[k] for k in keys), Tally())
    rows.append(
        f'<tr><th>all</th><td class="num">{sum(len(by_paper[k]) for k in keys)}</td>'
        f"{html.tally_cells(total)}</tr>"
    )
    robots = sorted({r.spec.robot for k in keys for r in by_paper[k]})
    robot_links = ", ".join(
        f'<a href="robots/{escape(robot)}.html">{escape(robot)}</a>' for robot in robots
    )
    made = [_reference_currency(r) for k in keys for r in by_paper[k]]
    commits = sorted({c.short for c in made if c.commit})
    current = sum(c.current is True for c in made)
    stale = sum(c.current is False for c in made)
    provenance = (
        f" The {len(made)} references were made at {len(commits)} commit(s); {current} at "
        f"the current code, {stale} at code that has changed since (each paper's page says "
        "which)."
    )
    skipped = (
        "<h2>Skipped</h2><ul>" + "".join(f"<li>{escape(n)}</li>" for n in notes) + "</ul>"
        if notes
        else ""
    )
    body = (
        "<h1>walkrepro: reproduction report</h1>\n"
        "<p>Three biped-walking papers reproduced in MuJoCo, each on its lab's robot model. "
        "Each paper's claims are counted below; its page lists every claim with the rows "
        "that test it, then every experiment: the paper's value, the measured value and the "
        "verdict, next to the redrawn figures, a video of the run and the maps.</p>\n"
        f'<div class="cards">{"".join(cards)}</div>\n'
        + COUNTS_EXPLAINED
        + '<h2 id="rows">Rows and map claims by verdict</h2>\n'
        f"<table>\n<tr><th>paper</th><th>experiments</th>{html.TALLY_HEAD}</tr>\n"
        + "\n".join(rows)
        + "\n</table>\n"
        f"<p>Robot models, with the source of every number: {robot_links}.</p>\n"
        f'<p class="muted">Built from {escape(str(source))} (nothing re-run).{provenance}</p>\n'
        + user_runs_section(out, runs_root, user_runs(runs_root))
        + skipped
    )
    return html.page("walkrepro: reproduction report", body)
