"""The report's index: a picture of each paper's robot and result, the paper's claims
counted, what the counts include, and the user's own runs.

- Each paper's card shows a frame of its robot (the middle frame of the headline
  experiment's ``figures/snapshots.png``), its headline figure (:attr:`Paper.headline`) and
  its register's claims by status (:mod:`walkrepro.publish.claim_register`): ``R
  reproduced, C calibrated, D deviating, F failed, N not covered, U uncheckable, of M``,
  with walkrepro's own rows apart.
- "Your runs" lists every run under the results root (``walkrepro run``'s default
  ``results/runs/``) with its outcome and verdict counts, its commit and whether that is the
  current code.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from html import escape
from pathlib import Path

from walkrepro import plugins
from walkrepro.publish.claim_register import (
    CALIBRATED,
    DEVIATING,
    FAILED,
    NOT_COVERED,
    REPRODUCED,
    STATUSES,
    UNCHECKABLE,
    ClaimResult,
    ClaimTotals,
)
from walkrepro.publish.report.currency import Currency, currency
from walkrepro.runs import results

#: The robot's frame and the headline figure in the site.
PICTURES_DIR = "assets/index"
#: A claim status's badge style (the claims table's).
STATUS_CSS = {
    REPRODUCED: "pass",
    CALIBRATED: "calibrated",
    DEVIATING: "known",
    FAILED: "fail",
    NOT_COVERED: "none",
    UNCHECKABLE: "none",
}


@dataclass(frozen=True)
class PaperClaims:
    """One paper's register claims as the report counts them.

    Attributes:
        totals: the register's claims by status and walkrepro's own rows.
        claims: every register claim with its status and rows.
        scope: what the counts include, in words.
    """

    totals: ClaimTotals
    claims: tuple[ClaimResult, ...]
    scope: str


@dataclass(frozen=True)
class UserRun:
    """One run under the results root.

    Attributes:
        experiment: the experiment's name.
        directory: the run directory.
        outcome: ``complete``, ``fell``, ``interrupted``, ``error``... (``run.json``).
        counts: the verdict counts (``check.json``), or None if not evaluated.
        currency: its commit and whether that is the current code.
        overrides: the ``--set`` overrides it ran with.
    """

    experiment: str
    directory: Path
    outcome: str
    counts: dict | None
    currency: Currency
    overrides: tuple[str, ...]


def robot_frame(snapshots: Path, target: Path) -> Path:
    """Crop the middle frame of a snapshot strip (frames side by side on white, a title
    above) into ``target``; the whole strip where no frame can be told apart."""
    import numpy as np
    from PIL import Image

    target.parent.mkdir(parents=True, exist_ok=True)
    image = Image.open(snapshots).convert("RGB")
    pixels = np.asarray(image).astype(int)
    ink = (pixels < 235).any(axis=2)  # not the white page
    columns = ink.mean(axis=0) > 0.5  # a frame's columns are mostly ink
    edges = np.flatnonzero(np.diff(np.r_[0, columns.astype(int), 0]))
    frames = list(zip(edges[::2], edges[1::2], strict=True))
    frames = [(a, b) for a, b in frames if b - a > 20]
    if not frames:
        shutil.copy2(snapshots, target)
        return target
    left, right = frames[len(frames) // 2]
    rows = np.flatnonzero(ink[:, left:right].mean(axis=1) > 0.9)
    top, bottom = (rows[0], rows[-1] + 1) if rows.size else (0, image.height)
    image.crop((int(left), int(top), int(right), int(bottom))).save(target)
    return target


def headline_pictures(site: Path, key: str, source: Path) -> list[tuple[str, str]]:
    """``(href, caption)`` of the paper's robot frame and headline figure, copied into the
    site; empty where the paper declares none or ``source`` lacks them."""
    paper = plugins.papers().get(key)
    if paper is None or paper.headline is None:
        return []
    experiment, figure = paper.headline
    figures = _figures_dir(source, experiment)
    if figures is None:
        return []
    out = []
    strip = figures / "snapshots.png"
    if strip.is_file():
        rel = f"{PICTURES_DIR}/{key}_robot.png"
        robot_frame(strip, site / rel)
        out.append((rel, f"{experiment}: the robot mid-run"))
    picture = figures / f"{figure}.png"
    if picture.is_file():
        rel = f"{PICTURES_DIR}/{key}_headline.png"
        (site / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(picture, site / rel)
        out.append((rel, f"{experiment}: {figure.replace('_', ' ')}"))
    return out


def _figures_dir(source: Path, experiment: str) -> Path | None:
    """The experiment's ``figures/`` under ``source`` (a reference, or its latest run)."""
    direct = source / experiment / results.FIGURES_DIR
    if direct.is_dir():
        return direct
    latest = results.latest_run(source, experiment)
    if latest is not None and (latest / results.FIGURES_DIR).is_dir():
        return latest / results.FIGURES_DIR
    return None


def counts_sentence(totals: ClaimTotals) -> str:
    """HTML: ``the paper's claims: R reproduced, …, of M``, each count coloured."""
    parts = [  # a zero count is shown grey, whatever its status
        f'<span class="verdict {STATUS_CSS[s] if totals.by_status[s] else "none"}">'
        f"{totals.by_status[s]} {escape(s)}</span>"
        for s in STATUSES
    ]
    return f"The paper's claims: {' '.join(parts)} of <b>{totals.total}</b>"


def paper_card(key: str, title: str, href: str, claims: PaperClaims | None, pictures, rows) -> str:  # noqa: ANN001
    """One paper on the index: its pictures, its claims counted, its own rows apart, and
    what the counts include. ``rows``: the paper's rows and map claims by verdict (a Tally)."""
    images = "".join(
        f'<figure><a href="{escape(h)}"><img src="{escape(h)}" alt="{escape(c)}"></a>'
        f"<figcaption>{escape(c)}</figcaption></figure>"
        for h, c in pictures
    )
    if claims is not None and claims.totals.total:
        own = claims.totals.own
        counted = (
            f"<p>{counts_sentence(claims.totals)}.</p>"
            f'<p class="muted">walkrepro\'s own rows (generalisation, sensitivity, ablation, '
            f"sanity), apart: {own.reproduced} reproduced, {own.calibrated} calibrated, "
            f"{own.known} known deviations, {own.failed} failed. {escape(claims.scope)}</p>"
        )
    else:
        counted = (
            f"<p>No claim register yet (<code>experiments/claims/{escape(key)}.yaml</code>): "
            f"its rows and map claims count {rows.reproduced} reproduced, {rows.calibrated} "
            f"calibrated, {rows.known} known deviations, {rows.failed} failed.</p>"
        )
    return (
        f'<section class="card"><h2><a href="{escape(href)}">{escape(title)}</a></h2>'
        f'<div class="pictures">{images}</div>{counted}</section>'
    )


def user_runs(root: Path) -> list[UserRun]:
    """Every run directory under ``root`` (``<experiment>/<run>/``), newest first."""
    found = []
    if not root.is_dir():
        return found
    for folder in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
        for run in results.runs(root, folder.name):
            record = _json(run / results.RUN_FILE)
            check = _json(run / results.CHECK_FILE)
            if record is None and check is None:
                continue  # not a run directory
            record = record or {}
            found.append(
                UserRun(
                    experiment=str(record.get("experiment", folder.name)),
                    directory=run,
                    outcome=str(record.get("outcome") or (check or {}).get("outcome", "?")),
                    counts=(check or {}).get("counts"),
                    currency=currency(record.get("commit"), f"experiments/{folder.name}.yaml"),
                    overrides=tuple(record.get("overrides", [])),
                )
            )
    return sorted(found, key=lambda r: r.directory.name, reverse=True)


def _json(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _link(site: Path, target: Path, text: str) -> str:
    """A relative link from the site's index to ``target`` (outside the site)."""
    rel = Path(os.path.relpath(target, site)).as_posix()
    return f'<a href="{escape(rel)}">{escape(text)}</a>'


def user_runs_section(site: Path, root: Path, runs: Sequence[UserRun]) -> str:
    """ "Your runs": each run with its verdict counts, commit and currency."""
    head = (
        f'<h2 id="your-runs">Your runs</h2>\n<p class="muted">Every run under '
        f"{escape(str(root))} (<code>walkrepro run</code> writes there), newest first: its "
        "outcome, its rows by verdict (as <code>walkrepro run</code> printed them) and the "
        "commit it ran at.</p>\n"
    )
    if not runs:
        return head + "<p>No runs yet: <code>walkrepro run forward_walk</code> makes one.</p>"
    rows = []
    for r in runs:
        c = r.counts or {}
        verdict = (
            f"{c.get('reproduced', 0)} reproduced, {c.get('calibrated', 0)} calibrated, "
            f"{c.get('known', 0)} known, {c.get('failed', 0)} failed"
            if r.counts
            else "not evaluated"
        )
        ended = {"complete": "pass", "fell": "known"}.get(r.outcome, "fail")
        row_class = ' class="fail"' if c.get("failed") else ""
        check = r.directory / results.CHECK_FILE
        run_file = r.directory / results.RUN_FILE
        target = check if check.is_file() else run_file
        overrides = ", ".join(r.overrides)
        rows.append(
            f"<tr><td>{escape(r.experiment)}</td>"
            f"<td>{_link(site, target, r.directory.name)}</td>"
            f'<td><span class="verdict {ended}">{escape(r.outcome)}</span></td>'
            f"<td{row_class}>{escape(verdict)}</td>"
            f"<td>{escape(r.currency.text)}</td>"
            f"<td><code>{escape(overrides)}</code></td></tr>"
        )
    return (
        head + "<table><tr><th>experiment</th><th>run</th><th>outcome</th><th>rows</th>"
        "<th>commit</th><th>--set</th></tr>\n" + "\n".join(rows) + "\n</table>"
    )


COUNTS_EXPLAINED = """\
<h2 id="counts">What the counts include</h2>
<ul class="muted">
<li><b>The paper's claims</b> are the entries of its claim register
(<code>experiments/claims/&lt;paper&gt;.yaml</code>): every result the paper reports that a
reproduction could check. A claim's status comes from the rows that test it
(<code>claim: &lt;id&gt;</code>): failed if one fails, else deviating if one is a known
deviation, else calibrated if one served a calibration, else reproduced; not covered when no
row tests it yet, uncheckable when the register says why none can. This is what
<code>walkrepro claims</code> and the README count.</li>
<li><b>walkrepro's own rows</b> (<code>own: generalisation | sensitivity | ablation |
sanity</code>) test walkrepro's own questions, not the paper's, and are counted apart.</li>
<li><b>Rows and map claims by verdict</b> (the table below and each paper's page) count every
row of every experiment's reference <em>and</em> every claim of its maps, evaluated on the
committed map cells. <code>walkrepro run &lt;experiment&gt;</code> prints the experiment's own
rows only: its maps are swept by <code>walkrepro sweep --map</code>. So an experiment with maps
counts more here than its run prints; each paper's page shows the two apart.</li>
<li>Each reference was made at a commit; it is <em>the current code</em> when the tree of
<code>walkrepro/</code>, <code>robots/</code> and the experiment's spec at that commit equals
the checkout's HEAD.</li>
</ul>
"""


def paper_claims(source: Path, found: Sequence) -> dict[str, PaperClaims]:  # ExperimentResult
    """Each paper's register claims counted on ``source``: the committed references
    (:func:`walkrepro.publish.claim_register.paper_totals`, what the README and
    ``walkrepro claims`` show), or the results found in a ``check --out`` directory, whose
    counts say how many of the register's claims they test."""
    from walkrepro.locations import REFERENCES_DIR
    from walkrepro.publish.claim_register import evaluate_register, paper_totals, totals
    from walkrepro.specs.claims import find_register, register_papers
    from walkrepro.specs.files import shipped_experiment_names

    out: dict[str, PaperClaims] = {}
    if source.resolve() == REFERENCES_DIR.resolve():
        for key, (t, claims) in paper_totals(source).items():
            scope = (
                "Counted on the committed references: every shipped experiment's rows and its "
                "maps' claims."
            )
            out[key] = PaperClaims(t, tuple(claims), scope)
        return out
    rows = _found_rows(found)
    names = {r.name for r in found}
    shipped = set(shipped_experiment_names())
    for key in register_papers():
        register = find_register(key).model
        paper_rows = rows.get(key, [])
        t = totals(register, paper_rows)
        mine = {r.name for r in found if r.spec.paper.key == key}
        missing = {
            n
            for n in shipped
            if n not in names and _paper_of(n) == key  # shipped experiments not in source
        }
        tested = t.total - t.by_status[NOT_COVERED] - t.by_status[UNCHECKABLE]
        scope = f"Counted on the {len(mine)} experiments of this report"
        if missing:
            scope += (
                f", not on {len(missing)} more of the paper's: {tested} of the register's "
                f"{t.total} claims are tested here, and a claim only those test counts not "
                "covered."
            )
        else:
            scope += ": every shipped experiment of the paper, with its maps' claims."
        out[key] = PaperClaims(t, tuple(evaluate_register(register, paper_rows)), scope)
    return out


def _paper_of(name: str) -> str | None:
    from walkrepro.errors import WalkreproError
    from walkrepro.specs.files import load_spec

    try:
        return load_spec(name).spec.paper.key
    except WalkreproError:
        return None


def _found_rows(found: Sequence) -> dict[str, list]:  # ExperimentResult -> RowVerdict
    """The tagged rows of the results found, by paper: each experiment's ``check.json``
    rows tagged by its spec's expectations (rows that no longer match the spec count
    failed, as a stale reference does), and its maps' claims on the committed cells."""
    from walkrepro.evaluation.checks import FAIL
    from walkrepro.publish.claim_register import RowVerdict, verdict_rows
    from walkrepro.studies.sweep.command import map_verdicts

    out: dict[str, list] = {}
    for r in found:
        rows = out.setdefault(r.spec.paper.key, [])
        committed = r.check.get("rows", [])
        expect = r.spec.expect
        same = len(committed) == len(expect) and all(
            c.get("metric") == e.metric for c, e in zip(committed, expect, strict=False)
        )
        for i, e in enumerate(expect):
            row = committed[i] if same else None
            status = row["status"] if row else FAIL
            rows.append(
                RowVerdict(r.name, e.metric, status, row and row.get("measured"), e.claim, e.own)
            )
        if r.spec.sweeps and _paper_of(r.name) is not None:
            for verdict in map_verdicts([r.name], False, r.directory, 1):
                rows += verdict_rows(verdict)
    return out
