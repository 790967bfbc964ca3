"""The static HTML report (``walkrepro report``): its content, and a headless-Chromium check
that every page loads from ``file://`` with no console error and no broken image, link or
video."""

from __future__ import annotations

import json
import re
import shutil
from html import escape
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest
from typer.testing import CliRunner

from walkrepro import RESULTS_DIR
from walkrepro.cli import app
from walkrepro.errors import WalkreproError
from walkrepro.plugins import papers
from walkrepro.publish.report import build_report
from walkrepro.publish.report.claims import Tally, claim_from_row, tally
from walkrepro.publish.report.sources import VIDEO_FILE
from walkrepro.specs.files import load_spec

CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
PAPER_KEYS = ("lee2021", "faraji", "jo_oh")


def _row(status: str, note: str = "", measured: float | None = 1.0) -> dict:
    return {
        "metric": "walk_speed",
        "op": "between",
        "paper": [0.088, 0.132],
        "measured": measured,
        "status": status,
        "source": "§VI-A: approximately 0.11 m/s",
        "note": note,
        "observed": [0.07, 0.086] if status == "known deviation" else None,
        "band": "[0.088, 0.132]",
    }


def _fake_results(root: Path, rows: list[dict], outcome: str = "complete") -> Path:
    """A results tree with forward_walk's reference: check.json, one figure, a video and a
    Rerun recording."""
    exp = root / "forward_walk"
    (exp / "figures").mkdir(parents=True)
    (exp / "check.json").write_text(json.dumps({"outcome": outcome, "rows": rows}))
    shutil.copy(next((RESULTS_DIR / "forward_walk" / "figures").glob("*.png")), exp / "figures")
    (exp / "video.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42")
    (exp / "log.rrd").write_bytes(b"RRF2")
    (root / "maps").mkdir()  # no reference maps: each declared map is a failed claim
    return root


def test_a_known_deviation_row_splits_into_definition_and_reason() -> None:
    """The note's "Known deviation: ..." tail is the reason; the head is how it is measured."""
    claim = claim_from_row(_row("known deviation", "pelvis x speed. Known deviation: 0.078 m/s"))
    assert claim.definition == "pelvis x speed."
    assert claim.reason == "0.078 m/s"
    assert claim.observed == "[0.07, 0.086]"
    assert claim.label == "known deviation"
    failed = claim_from_row(_row("fail", "not measurable: fell", measured=None))
    assert (failed.reason, failed.measured) == ("not measurable: fell", "not measurable")


def test_tally_counts_each_verdict_and_unknown_statuses_as_failed() -> None:
    """Reproduced, calibrated, known and failed are counted apart; a status the report does
    not know is a failure, never silently dropped."""
    claims = [
        claim_from_row(_row(s))
        for s in ("pass", "pass", "calibrated", "known deviation", "fail", "??")
    ]
    t = tally(claims)
    assert (t.reproduced, t.calibrated, t.known, t.failed) == (2, 1, 1, 2)


def test_report_from_a_results_tree_links_only_relative_copied_files(tmp_path: Path) -> None:
    """A paper page shows the claim, the paper's value, the measured value, the verdict and
    the reason, with its figure, video and Rerun recording copied into the site and linked
    relatively."""
    source = _fake_results(
        tmp_path / "results", [_row("pass"), _row("known deviation", "x. Known deviation: slow")]
    )
    site = build_report(source, tmp_path / "site")
    n_maps = len(load_spec("forward_walk").spec.sweeps)
    assert n_maps > 0
    assert site.tallies["lee2021"] == Tally(reproduced=1, known=1, failed=n_maps)
    page = (tmp_path / "site" / "lee2021.html").read_text()
    for text in ("walk_speed", "§VI-A: approximately 0.11 m/s", "[0.088, 0.132]", "slow", "VI-A"):
        assert text in page
    assert 'src="assets/forward_walk/video.mp4"' in page
    assert 'href="assets/forward_walk/log.rrd"' in page
    links = re.findall(r'(?:href|src)="([^"]+)"', page)
    assert links and all(not urlparse(x).scheme and not x.startswith("/") for x in links)
    for link in links:
        assert (tmp_path / "site" / unquote(link.split("#")[0])).exists() or link.startswith("#")
    assert str(tmp_path) not in page  # nothing points back into the source tree


def test_report_from_a_check_output_directory_uses_each_experiments_latest_run(
    tmp_path: Path,
) -> None:
    """In a `walkrepro check --out DIR` tree the latest run of each experiment is shown, with
    the spec that run was made with (its spec.yaml), and its video."""
    spec = load_spec("forward_walk").spec
    for run, status in (("20260101T000000Z-aaaaaa", "fail"), ("20260102T000000Z-bbbbbb", "pass")):
        directory = tmp_path / "runs" / "forward_walk" / run
        directory.mkdir(parents=True)
        (directory / "check.json").write_text(
            json.dumps({"outcome": "complete", "rows": [_row(status)]})
        )
        (directory / "spec.yaml").write_text(
            spec.model_copy(update={"description": f"run {run}", "sweeps": []}).to_yaml()
        )
        (directory / "video.mp4").write_bytes(b"\x00")
    site = build_report(tmp_path / "runs", tmp_path / "site")
    assert site.tallies["lee2021"] == Tally(reproduced=1)
    page = (tmp_path / "site" / "lee2021.html").read_text()
    assert "run 20260102T000000Z-bbbbbb" in page and "20260101" not in page
    assert 'src="assets/forward_walk/video.mp4"' in page


def test_a_broken_run_counts_as_a_failed_claim(tmp_path: Path) -> None:
    """A reference whose run ended in an error shows a failed row, as `walkrepro check` counts it."""
    source = _fake_results(tmp_path / "results", [_row("pass")], outcome="error")
    site = build_report(source, tmp_path / "site")
    assert site.tallies["lee2021"].failed == 1 + len(load_spec("forward_walk").spec.sweeps)
    assert "run error" in (tmp_path / "site" / "lee2021.html").read_text()


def test_report_refuses_an_empty_source_and_overwriting_its_source(tmp_path: Path) -> None:
    """No results is a one-paragraph error (exit 2); so is an --out that holds the source."""
    (tmp_path / "empty").mkdir()
    with pytest.raises(WalkreproError, match="no experiment results"):
        build_report(tmp_path / "empty", tmp_path / "site")
    source = _fake_results(tmp_path / "results", [_row("pass")])
    with pytest.raises(WalkreproError, match="overwrite"):
        build_report(source, tmp_path)
    result = CliRunner().invoke(app, ["report", "--from", str(tmp_path / "empty")])
    assert result.exit_code == 2
    assert "Traceback" not in result.output


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The report built once from the committed references."""
    out = tmp_path_factory.mktemp("report") / "site"
    result = CliRunner().invoke(app, ["report", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out


def test_the_committed_references_give_one_row_per_paper_with_checks_counts(site: Path) -> None:
    """The index has a row per paper, and each paper's counts equal the sum of its
    experiments' check.json counts plus its maps' claims as `walkrepro check` evaluates them."""
    from walkrepro.studies.sweep.command import map_verdicts

    index = (site / "index.html").read_text()
    for key in PAPER_KEYS:
        assert f'href="{key}.html"' in index and escape(papers()[key].citation) in index
        reproduced = calibrated = known = failed = 0
        names = []
        for check in sorted(RESULTS_DIR.glob("*/check.json")):
            if load_spec(check.parent.name).spec.paper.key != key:
                continue
            counts = json.loads(check.read_text())["counts"]
            reproduced, calibrated, known, failed = (
                reproduced + counts["reproduced"],
                calibrated + counts.get("calibrated", 0),  # references from before calibration
                known + counts["known"],
                failed + counts["failed"],
            )
            names.append(check.parent.name)
        for v in map_verdicts(names, False, site, 1):
            reproduced += sum(r.status == "pass" for r in v.rows)
            known += sum(r.status == "known deviation" for r in v.rows)
            failed += sum(r.status == "fail" for r in v.rows)
        row = re.search(rf'href="{key}\.html".*?</tr>', index).group(0)
        cells = [int(x) for x in re.findall(r'<td class="num">(\d+)</td>', row)]
        assert cells[1:] == [reproduced, calibrated, known, failed]


def test_the_index_leads_with_each_papers_robot_headline_and_claim_counts(site: Path) -> None:
    """Before any table, the index shows each paper's robot frame and headline figure (files
    in the site) and its register's claims counted as `walkrepro claims` counts them."""
    from walkrepro.publish.claim_register import STATUSES, paper_totals

    index = (site / "index.html").read_text()
    first_table = index.index("<table")
    for key in PAPER_KEYS:
        for picture in (f"assets/index/{key}_robot.png", f"assets/index/{key}_headline.png"):
            assert f'src="{picture}"' in index and index.index(picture) < first_table
            assert (site / picture).stat().st_size > 1000
    for key, (totals, _) in paper_totals(RESULTS_DIR).items():
        if key not in PAPER_KEYS or not totals.total:
            continue
        card = index[index.index(f'href="{key}.html#claims"') :]
        card = card[: card.index("</section>")]
        for status in STATUSES:
            assert f"{totals.by_status[status]} {status}</span>" in card, (key, status)
        assert f"of <b>{totals.total}</b>" in card
        own = totals.own
        assert f"apart: {own.reproduced} reproduced" in card
    assert 'id="counts"' in index and "walkrepro run &lt;experiment&gt;" in index


def test_each_register_claim_shows_its_rows_reference_commit_and_currency(site: Path) -> None:
    """A paper's page lists its register's claims; each row that tests one names the commit
    its reference was made at and whether that is the current code."""
    from walkrepro.publish.report.currency import currency

    page = (site / "lee2021.html").read_text()
    assert 'id="claims"' in page and "<code>walk.no-fall</code>" in page
    run = json.loads((RESULTS_DIR / "forward_walk" / "run.json").read_text())
    made = currency(run["commit"], "experiments/forward_walk.yaml")
    word = "current code" if made.current else "code changed since"
    assert f"reference {made.short}, {word}" in page


def test_each_experiment_counts_its_rows_as_run_prints_them_and_its_maps_apart(
    site: Path,
) -> None:
    """The paper page's experiment table shows an experiment's own rows (its check.json
    counts, what `walkrepro run` prints) apart from its maps' claims."""
    counts = json.loads((RESULTS_DIR / "forward_walk" / "check.json").read_text())["counts"]
    page = (site / "lee2021.html").read_text()
    row = re.search(r'<tr><td><a href="#forward_walk">.*?</tr>', page).group(0)
    own = (
        f"{counts['reproduced']} · {counts.get('calibrated', 0)} · {counts['known']} · "
        f"{counts['failed']}"
    )
    assert f'<td class="num">{own}</td>' in row


def _fake_run(root: Path, run: str, outcome: str, counts: dict | None) -> Path:
    directory = root / "forward_walk" / run
    directory.mkdir(parents=True)
    record = {"experiment": "forward_walk", "outcome": outcome, "commit": "0" * 40}
    record["overrides"] = ["sim.duration=1"]
    (directory / "run.json").write_text(json.dumps(record))
    if counts is not None:
        (directory / "check.json").write_text(json.dumps({"outcome": outcome, "counts": counts}))
    return directory


def test_your_runs_lists_each_run_with_its_outcome_verdict_and_commit(tmp_path: Path) -> None:
    """The index's "your runs" lists every run under the runs root, newest first, with its
    outcome, its rows by verdict, its commit and overrides, linked relatively to its files."""
    source = _fake_results(tmp_path / "results", [_row("pass")])
    runs = tmp_path / "my_runs"
    counts = {"reproduced": 3, "calibrated": 1, "known": 0, "failed": 2}
    _fake_run(runs, "20260101T000000Z-aaaaaa", "complete", counts)
    _fake_run(runs, "20260102T000000Z-bbbbbb", "interrupted", None)
    (runs / "notes").mkdir()  # a folder that holds no run is not listed
    build_report(source, tmp_path / "site", runs_root=runs)
    index = (tmp_path / "site" / "index.html").read_text()
    section = index[index.index('id="your-runs"') :]
    newer, older = section.index("20260102T000000Z-bbbbbb"), section.index("20260101T000000Z")
    assert newer < older
    assert "3 reproduced, 1 calibrated, 0 known, 2 failed" in section
    assert "interrupted" in section and "not evaluated" in section
    assert "sim.duration=1" in section and "notes" not in section
    assert "made at 0000000000 (currency unknown)" in section
    for link in re.findall(r'href="([^"]+)"', section):
        assert (tmp_path / "site" / unquote(link)).resolve().is_file(), link


def test_no_runs_says_how_to_make_one(tmp_path: Path) -> None:
    """Without runs, "your runs" says which command makes one."""
    source = _fake_results(tmp_path / "results", [_row("pass")])
    build_report(source, tmp_path / "site", runs_root=tmp_path / "none")
    index = (tmp_path / "site" / "index.html").read_text()
    assert "No runs yet: <code>walkrepro run forward_walk</code>" in index


def test_a_partial_source_says_how_many_claims_it_tests(tmp_path: Path) -> None:
    """Counted on a source that lacks some of a paper's experiments, the claims line says
    how many of the register's claims those results test."""
    source = _fake_results(tmp_path / "results", [_row("pass")])
    build_report(source, tmp_path / "site", runs_root=tmp_path / "none")
    index = (tmp_path / "site" / "index.html").read_text()
    assert re.search(r"\d+ of the register&#x27;s \d+ claims are tested here", index)


def test_reference_currency_compares_the_commits_code_with_head() -> None:
    """HEAD's own commit is the current code; the repository's first commit is not (its
    walkrepro/ differs); a commit git does not know is unknown."""
    import subprocess

    from walkrepro.locations import PROJECT_ROOT
    from walkrepro.publish.report.currency import currency

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(PROJECT_ROOT), *args], capture_output=True, text=True, check=True
        ).stdout.split()[0]

    head = git("rev-parse", "HEAD")
    assert currency(head, "experiments/forward_walk.yaml").current is True
    assert currency(head + "+dirty", None).current is True
    first = git("rev-list", "--max-parents=0", "HEAD")
    old = currency(first, "experiments/forward_walk.yaml")
    assert old.current is False and any(p.startswith("walkrepro") for p in old.changed)
    assert currency("f" * 40, None).current is None
    assert currency(None, None).text == "commit not recorded"


def test_no_page_cites_an_internal_issue_number(site: Path) -> None:
    """Generated pages cite the papers; no page refers to the project's own issue numbers."""
    for page in site.rglob("*.html"):
        found = re.findall(r"\bissues? #?\d+", page.read_text(), flags=re.IGNORECASE)
        assert found == [], f"{page.name}: {found}"


# --------------------------------------------------------------------------------------
# Headless Chromium


def _chromium_missing() -> str:
    """Why the browser test cannot run here ('' if it can)."""
    if not CHROMIUM.is_file() or not CHROMEDRIVER.is_file():
        return "Chromium is absent (apt-get install chromium chromium-driver; .ci/run does)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is absent (pip install -e '.[test]')"
    return ""


class _Links(HTMLParser):
    """Every href and src of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.targets: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for name, value in attrs:
            if name in ("href", "src") and value:
                self.targets.append(value)
            if name == "id" and value:
                self.ids.add(value)


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - a selenium driver
    """Headless Chromium driven by chromedriver, with the closed network's flags."""
    why = _chromium_missing()
    if why:
        pytest.skip(why)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in (
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--allow-file-access-from-files",
        f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}",
        "--window-size=1400,1800",
    ):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=Service(str(CHROMEDRIVER)))
    driver.set_page_load_timeout(120)
    yield driver
    driver.quit()


_LOAD_EVERY_IMAGE = """
const done = arguments[arguments.length - 1];
const images = Array.from(document.images);
images.forEach(img => { img.loading = "eager"; });
Promise.all(images.map(img => img.complete ? Promise.resolve() :
    new Promise(ok => { img.onload = ok; img.onerror = ok; })))
  .then(() => done(images.filter(img => img.naturalWidth === 0).map(img => img.src)));
"""

_VIDEO_STATES = """
const done = arguments[arguments.length - 1];
const videos = Array.from(document.querySelectorAll("video"));
// preload=auto: wait for the first decoded frame (readyState 2), not only the container.
Promise.all(videos.map(v => new Promise(ok => {
    v.preload = "auto";
    v.addEventListener("loadeddata", ok);
    v.addEventListener("error", ok, true);
    v.querySelector("source")?.addEventListener("error", ok);
    v.load();
    setTimeout(ok, 20000); })))
  .then(() => done(videos.map(v => ({src: v.currentSrc || v.querySelector("source").src,
                                     ready: v.readyState, error: v.error ? v.error.code : 0,
                                     duration: v.duration, width: v.videoWidth}))));
"""


def test_every_page_loads_in_chromium_without_errors_or_broken_media(
    site: Path, browser, tmp_path: Path
) -> None:  # noqa: ANN001 - selenium driver
    """Each page opens from file:// with no console error; every image has pixels; every link
    resolves to a file (and an anchor to an element); every video loads its metadata, or, where
    this Chromium lacks an H.264 decoder, is an MP4 that the Python reader decodes. A screenshot
    of each paper's page is saved."""
    import imageio_ffmpeg

    browser.set_script_timeout(180)
    pages = sorted(site.rglob("*.html"))
    assert {f"{k}.html" for k in PAPER_KEYS} <= {p.name for p in pages}
    ids = {}
    for page in pages:
        parser = _Links()
        parser.feed(page.read_text())
        ids[page.resolve()] = parser.ids
    no_decoder, n_videos = [], 0
    for page in pages:
        browser.get(page.as_uri())
        broken = browser.execute_async_script(_LOAD_EVERY_IMAGE)
        assert broken == [], f"{page.name}: broken images {broken}"
        for v in browser.execute_async_script(_VIDEO_STATES):
            n_videos += 1
            path = Path(unquote(urlparse(v["src"]).path))
            assert path.is_file(), f"{page.name}: video {v['src']} missing"
            if v["error"] == 4:  # MEDIA_ERR_SRC_NOT_SUPPORTED: no H.264 decoder in this build
                n_frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(path))
                assert n_frames > 0 and seconds > 0, f"{path} is not a playable MP4"
                no_decoder.append(path.name)
            else:
                assert v["error"] == 0 and v["ready"] >= 2, f"{page.name}: video {v}"
                assert v["duration"] > 0 and v["width"] > 0
        errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        assert errors == [], f"{page.name}: console errors {errors}"
        parser = _Links()
        parser.feed(page.read_text())
        for target in parser.targets:
            url = urlparse(target)
            assert not url.scheme and not url.netloc, f"{page.name}: {target} is not relative"
            path = (page.parent / unquote(url.path)).resolve() if url.path else page.resolve()
            assert path.is_file(), f"{page.name}: broken link {target}"
            if url.fragment and path.suffix == ".html":
                assert url.fragment in ids[path], f"{page.name}: no #{url.fragment} in {path.name}"
        if page.stem in PAPER_KEYS:
            browser.save_screenshot(str(tmp_path / f"{page.stem}.png"))
            assert (tmp_path / f"{page.stem}.png").stat().st_size > 10_000
    assert n_videos == len(list(RESULTS_DIR.glob(f"*/{VIDEO_FILE}")))
    if no_decoder:
        print(f"this Chromium has no H.264 decoder; checked with imageio-ffmpeg: {no_decoder}")


def test_report_command_leads_with_the_papers_claims(tmp_path: Path) -> None:
    """`walkrepro report` prints each paper's register claims before its rows (issue: the
    papers' claims first, walkrepro's own apart)."""
    result = CliRunner().invoke(app, ["report", "--out", str(tmp_path / "site")])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    for key in ("lee2021", "faraji", "jo_oh"):
        claims = next(i for i, line in enumerate(lines) if line.startswith(f"{key}: the paper's"))
        rows = next(i for i, line in enumerate(lines) if line.startswith(f"{key}: all rows"))
        assert claims < rows
        assert re.search(r"\d+ reproduced, .* of \d+$", lines[claims])
