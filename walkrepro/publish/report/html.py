"""Pieces of the report's pages: the page frame, tables of claims, figures, the style sheet.

Plain HTML5 with one style sheet, no scripts: every link is relative, so the site works
from ``file://``. All text from specs and verdicts is escaped here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from html import escape
from typing import Any

from walkrepro.publish.report.claims import Claim, Tally

#: The style sheet's file name in the site.
CSS_FILE = "style.css"

CSS = """\
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0 auto;
       max-width: 1400px; padding: 1rem 2rem 3rem; color: #1d2329; line-height: 1.45; }
h1 { font-size: 1.6rem; margin-bottom: 0.2rem; }
h2 { font-size: 1.3rem; margin-top: 2.5rem; border-bottom: 1px solid #ccd3da;
     padding-bottom: 0.2rem; }
h3 { font-size: 1.05rem; margin: 1.2rem 0 0.4rem; }
a { color: #0b5cad; }
nav { font-size: 0.9rem; margin-bottom: 1rem; }
.muted { color: #5b6670; font-size: 0.88rem; }
table { border-collapse: collapse; width: 100%; font-size: 0.88rem; }
th, td { border: 1px solid #d5dbe1; padding: 0.3rem 0.45rem; text-align: left;
         vertical-align: top; }
th { background: #eef1f4; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
.verdict { display: inline-block; padding: 0.05rem 0.45rem; border-radius: 0.6rem;
           font-size: 0.8rem; white-space: nowrap; }
.pass { background: #d9f2df; color: #125c26; }
.calibrated { background: #dde8f7; color: #1b4a86; }
.known { background: #fcefcf; color: #6d4d00; }
.fail { background: #f8d7d7; color: #8a1414; }
table.claims { table-layout: fixed; }
table.claims col.c-claim { width: 15%; } table.claims col.c-source { width: 17%; }
table.claims col.c-value { width: 9%; } table.claims col.c-measured { width: 11%; }
table.claims col.c-verdict { width: 12%; } table.claims col.c-reason { width: 36%; }
table.claims td { overflow-wrap: anywhere; }
table.claims td.num, table.claims .verdict { white-space: normal; }
table.claims .verdict { overflow-wrap: normal; }
.experiment { display: grid; grid-template-columns: minmax(0, 2fr) minmax(0, 1fr);
              gap: 1.2rem; align-items: start; }
@media (max-width: 1100px) { .experiment { grid-template-columns: 1fr; } }
.figures { display: flex; flex-wrap: wrap; gap: 0.6rem; }
.figures figure { margin: 0; flex: 1 1 260px; max-width: 100%; }
.figures img { width: 100%; border: 1px solid #d5dbe1; background: #fff; }
figcaption { font-size: 0.8rem; color: #5b6670; }
video { width: 100%; max-width: 640px; background: #000; }
details summary { cursor: pointer; color: #5b6670; font-size: 0.82rem; }
.reason { font-size: 0.84rem; }
.robot table { width: auto; }
pre { white-space: pre-wrap; }
.none { background: #eceff2; color: #4a545d; }
.cards { display: grid; grid-template-columns: repeat(auto-fit, minmax(360px, 1fr));
         gap: 1rem; margin: 1rem 0; }
.card { border: 1px solid #d5dbe1; border-radius: 0.5rem; padding: 0.6rem 0.9rem; }
.card h2 { font-size: 1.05rem; margin: 0.2rem 0 0.6rem; border: 0; }
.card .verdict { margin: 0.1rem 0; }
.pictures { display: grid; grid-template-columns: minmax(0, 1fr) minmax(0, 2.4fr);
            gap: 0.5rem; align-items: center; }
.pictures figure { margin: 0; }
.pictures img { width: 100%; border: 1px solid #d5dbe1; background: #fff; }
table.register td:nth-child(3) { font-style: italic; }
ul.rows { margin: 0; padding-left: 1.1rem; font-size: 0.84rem; }
"""


def page(title: str, body: str, css_href: str = CSS_FILE) -> str:
    """A whole HTML page around ``body`` (already HTML)."""
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{escape(title)}</title>\n"
        f'<link rel="stylesheet" href="{escape(css_href)}">\n</head>\n<body>\n'
        f"{body}\n</body>\n</html>\n"
    )


def verdict_badge(claim: Claim) -> str:
    """The verdict as a coloured label."""
    css = {"pass": "pass", "calibrated": "calibrated", "known deviation": "known"}.get(
        claim.status, "fail"
    )
    return f'<span class="verdict {css}">{escape(claim.label)}</span>'


def claims_table(claims: Sequence[Claim]) -> str:
    """The claims of one experiment or map: the paper's source and value, the measured
    value (and a known deviation's observed band), the verdict and the reason."""
    head = (
        "<tr><th>claim</th><th>paper (section, figure)</th><th>paper's value</th>"
        "<th>measured</th><th>verdict</th><th>reason</th></tr>"
    )
    rows = []
    for c in claims:
        definition = (
            f"<details><summary>how it is measured</summary>"
            f'<span class="muted">{escape(c.definition)}</span></details>'
            if c.definition
            else ""
        )
        observed = (
            f'<br><span class="muted">observed {escape(c.observed)}</span>' if c.observed else ""
        )
        rows.append(
            f"<tr><td><code>{escape(c.metric)}</code>{definition}</td>"
            f"<td>{escape(c.source)}</td>"
            f'<td class="num">{escape(c.paper)}</td>'
            f'<td class="num">{escape(c.measured)}{observed}</td>'
            f"<td>{verdict_badge(c)}</td>"
            f'<td class="reason">{escape(c.reason)}</td></tr>'
        )
    cols = "".join(
        f'<col class="c-{c}">'
        for c in ("claim", "source", "value", "measured", "verdict", "reason")
    )
    return (
        f'<table class="claims">\n<colgroup>{cols}</colgroup>\n{head}\n'
        + "\n".join(rows)
        + "\n</table>"
    )


def tally_cells(t: Tally) -> str:
    """Four table cells: reproduced, calibrated, known deviations, failed."""
    return (
        f'<td class="num">{t.reproduced}</td><td class="num">{t.calibrated}</td>'
        f'<td class="num">{t.known}</td><td class="num">{t.failed}</td>'
    )


def tally_text(t: Tally) -> str:
    """One cell's text: reproduced · calibrated · known · failed."""
    return f"{t.reproduced} · {t.calibrated} · {t.known} · {t.failed}"


TALLY_HEAD = "<th>reproduced</th><th>calibrated</th><th>known deviation</th><th>failed</th>"
#: The provenance classes' column heads (walkrepro provenance: the numbers a run uses).
PROVENANCE_HEAD = (
    '<th title="numbers the run uses, by provenance class (walkrepro provenance)">'
    "numbers: paper · source · assumed · calibrated</th>"
)


def provenance_cell(counts: Mapping[str, int] | None) -> str:
    """One cell: how many numbers of the run are paper, source, assumed, calibrated (and
    unclassified, in red, if any)."""
    if counts is None:
        return '<td class="num">—</td>'
    text = " · ".join(str(counts[k]) for k in ("paper", "source", "assumed", "calibrated"))
    if counts.get("unclassified"):
        text += f' · <span class="fail">{counts["unclassified"]} unclassified</span>'
    return f'<td class="num">{text}</td>'


def provenance_table(numbers: Sequence[Any]) -> str:
    """Every number a run uses with its class and source, folded under a summary line."""
    rows = [
        f"<tr><td>{escape(n.group)}</td><td>{escape(n.name)}</td><td>{escape(n.value)}</td>"
        f"<td>{escape(n.klass)}</td><td>{escape(n.source)}</td></tr>"
        for n in numbers
    ]
    return (
        f"<details><summary>Every number this run uses ({len(numbers)}), with its provenance "
        "(walkrepro provenance)</summary><table><tr><th>group</th><th>parameter</th>"
        "<th>value</th><th>class</th><th>source</th></tr>" + "".join(rows) + "</table></details>"
    )


def figure_gallery(figures: Iterable[tuple[str, str]]) -> str:
    """Thumbnails ``(href, caption)`` linking to the full-size image."""
    items = [
        f'<figure><a href="{escape(href)}"><img src="{escape(href)}" alt="{escape(caption)}" '
        f'loading="lazy"></a><figcaption>{escape(caption)}</figcaption></figure>'
        for href, caption in figures
    ]
    return '<div class="figures">' + "".join(items) + "</div>" if items else ""


def video_player(href: str, caption: str) -> str:
    """An HTML5 video of a run, with a direct link to the file."""
    return (
        f'<figure><video controls preload="metadata" muted>'
        f'<source src="{escape(href)}" type="video/mp4"></video>'
        f'<figcaption>{escape(caption)} (<a href="{escape(href)}">MP4</a>)</figcaption></figure>'
    )


def recording_link(href: str) -> str:
    """A link to a run's Rerun recording, with the command that opens it."""
    return (
        f'<p>Rerun recording: <a href="{escape(href)}">{escape(href.rsplit("/", 1)[-1])}</a> '
        f"(the robot, contact forces and the paper's plots on simulated time; open with "
        f"<code>rerun {escape(href.rsplit('/', 1)[-1])}</code>)</p>"
    )
