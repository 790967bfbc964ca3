"""Documentation: a short README, generated documents kept current, reasons written once."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from walkrepro import PROJECT_ROOT
from walkrepro.cli import app
from walkrepro.publish import docsgen

README = PROJECT_ROOT / "README.md"
#: The commands a newcomer types: CI runs the second verbatim (.ci/run).
MAIN_COMMAND = "pip install -e . && walkrepro run forward_walk"
TEST_COMMAND = 'pip install -e ".[test]" && pytest'


@pytest.fixture(scope="module")
def generated() -> dict[Path, str]:
    """The generated documents as the code and the committed results make them now."""
    return docsgen.generated_files()


def test_readme_is_short_and_holds_the_two_commands() -> None:
    """The README fits in 250 lines and gives the main command and the test command verbatim."""
    text = README.read_text()
    assert len(text.splitlines()) <= 250
    assert f"```bash\n{MAIN_COMMAND}\n```" in text
    assert f"```bash\n{TEST_COMMAND}\n```" in text
    assert TEST_COMMAND in (PROJECT_ROOT / ".ci" / "run").read_text()


def test_generated_documents_are_current(generated: dict[Path, str]) -> None:
    """docs/ and the README's status table are what `walkrepro docs` makes from the specs and results."""
    stale = docsgen.stale_files(generated)
    assert not stale, f"stale (run `walkrepro docs`): {[str(p) for p in stale]}"


def test_a_stale_status_table_is_detected(generated: dict[Path, str], tmp_path: Path) -> None:
    """A README whose status table differs by one count is reported stale."""
    readme = generated[README]
    table = readme[readme.index(docsgen.STATUS_BEGIN) : readme.index(docsgen.STATUS_END)]
    assert re.search(r"\| \d+ \|", table), table
    copy = tmp_path / "README.md"
    copy.write_text(readme.replace(table, re.sub(r"\| (\d+) \|", r"| 999 |", table, count=1)))
    assert docsgen.stale_files({copy: readme}) == [copy]
    copy.write_text(readme)
    assert docsgen.stale_files({copy: readme}) == []


def test_status_table_needs_its_markers() -> None:
    """A README without the status markers is an error, not a silently appended table."""
    with pytest.raises(ValueError, match="status"):
        docsgen.replace_status("# walkrepro\n", "| table |")
    text = f"a\n{docsgen.STATUS_BEGIN}\nold\n{docsgen.STATUS_END}\nb\n"
    assert docsgen.replace_status(text, "new") == "a\nnew\nb\n"


def test_generated_documents_carry_the_header(generated: dict[Path, str]) -> None:
    """Every generated document but the README starts with the do-not-edit header; no hand-written one does."""
    for path, text in generated.items():
        if path != README:
            assert text.startswith(docsgen.GENERATED_HEADER + "\n"), path
    for path in docsgen.hand_written():
        assert not path.read_text().startswith(docsgen.GENERATED_HEADER), path
    assert (PROJECT_ROOT / "docs" / "analysis" / "lee2021.md") in docsgen.hand_written()


def test_no_known_deviation_reason_is_written_twice() -> None:
    """No spec's known-deviation reason (nor a sentence of it) appears verbatim in a hand-written document."""
    reasons = list(docsgen.known_reasons())
    assert len(reasons) > 20  # expectations and map claims both
    assert any(" · map " in where for where, _ in reasons)
    copies = [
        (str(path.relative_to(PROJECT_ROOT)), where, sentence)
        for path in docsgen.hand_written()
        for where, reason in reasons
        for sentence in docsgen.copied_sentences(path.read_text(), reason)
    ]
    assert not copies, copies


def test_a_copied_reason_is_found_across_line_breaks_and_markup() -> None:
    """A reason, or one long sentence of it, copied into markdown (wrapped, with `code`) is found; a short phrase is not."""
    reason = (
        "0.078 m/s against the paper's 0.11 m/s. The E-FSM's timing is the LIPM's: SSA "
        "accelerates the CoM from where SSD stopped it until the capture point reaches x_s − r."
    )
    doc = (
        "Intro.\n\nThe E-FSM's timing is the LIPM's: SSA accelerates the `CoM` from where\n"
        "SSD stopped it until the capture point reaches x_s − r. More.\n"
    )
    assert docsgen.copied_sentences(doc, reason) == [
        "SSA accelerates the CoM from where SSD stopped it until the capture point reaches x_s − r."
    ]
    assert docsgen.copied_sentences(f"- **Why:** {reason}", reason)[0] == reason
    assert docsgen.copied_sentences("walks at 0.078 m/s against the paper's", reason) == []


def test_every_known_deviation_is_in_its_papers_page(generated: dict[Path, str]) -> None:
    """Each known deviation's reason appears on the generated page of its paper."""
    from walkrepro.specs.files import load_spec

    pages = {p.stem: t for p, t in generated.items() if p.parent.name == "deviations"}
    assert set(pages) == {"lee2021", "faraji", "jo_oh"}
    for where, reason in docsgen.known_reasons():
        paper = load_spec(where.split(" · ")[0]).spec.paper.key
        assert " ".join(reason.split()).replace("|", "\\|") in pages[paper], where


def test_spec_reference_lists_every_field(generated: dict[Path, str]) -> None:
    """The spec reference has a row for every field of every spec model and controller params model."""
    from walkrepro.controllers import controller_class, controller_names
    from walkrepro.specs.models import ExperimentSpec

    text = generated[PROJECT_ROOT / "docs" / "spec-reference.md"]
    schema = ExperimentSpec.model_json_schema()
    models = [schema, *schema["$defs"].values()]
    models += [controller_class(c).Params.model_json_schema() for c in controller_names()]
    for model in models:
        for field in model.get("properties", {}):
            assert f"| `{field}` |" in text, (model.get("title"), field)
    assert "| `duration` | float | required |" in text


def test_documents_cite_no_internal_issue_numbers(generated: dict[Path, str]) -> None:
    """Neither generated nor hand-written documents cite the project's issue numbers (a reader cannot look them up)."""
    for path in [*generated, *docsgen.hand_written()]:
        text = generated.get(path) or path.read_text()
        assert not re.search(r"\bissues? #?\d+", text, re.IGNORECASE), path


def test_relative_links_resolve() -> None:
    """Every relative link in README.md and docs/ points to a file or folder that exists."""
    broken = []
    for path in [README, *sorted((PROJECT_ROOT / "docs").rglob("*.md"))]:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", path.read_text()):
            if "://" in target:
                continue
            if not (path.parent / target).exists():
                broken.append((str(path.relative_to(PROJECT_ROOT)), target))
    assert not broken, broken


def test_docs_command_checks_then_writes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`walkrepro docs --check` exits 1 on a stale document and writes nothing; `walkrepro docs` then brings it up to date."""
    target = tmp_path / "docs" / "page.md"
    monkeypatch.setattr(docsgen, "generated_files", lambda: {target: "new\n"})
    result = CliRunner().invoke(app, ["docs", "--check"])
    assert result.exit_code == 1 and "stale" in result.output and not target.exists()
    result = CliRunner().invoke(app, ["docs"])
    assert result.exit_code == 0 and target.read_text() == "new\n", result.output
    result = CliRunner().invoke(app, ["docs", "--check"])
    assert result.exit_code == 0 and "up to date" in result.output, result.output


def test_updated_references_update_the_docs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """After `check --update-reference` the generated documents are rewritten from the new references."""
    from walkrepro.cli import registers

    target = tmp_path / "README.md"
    target.write_text("old\n")
    monkeypatch.setattr(docsgen, "generated_files", lambda: {target: "new\n"})
    registers.update_docs()
    assert target.read_text() == "new\n" and "docs updated" in capsys.readouterr().out
    registers.update_docs()  # nothing stale: nothing rewritten, nothing said
    assert "docs updated" not in capsys.readouterr().out
