"""Output locations that walkrepro writes: its own, or empty, never a user's folder.

Every command that writes outputs goes through here, so that nothing a user types deletes
or litters their files:

- a **root** that runs and sweeps accumulate under (``run``, ``check`` and ``sweep``'s
  ``--out``; ``plot --out``): :func:`claim_root` accepts a directory that does not exist
  yet, an empty one, or one holding walkrepro's marker file :data:`MARKER` (and a runs root
  written before the marker existed, recognised by its layout); it refuses any other
  directory unless ``--force``, and then writes the marker;
- a **directory replaced as a whole** (``report --out``): :func:`replacing` builds the new
  output in a hidden temporary sibling and swaps it in only when it is complete; the old
  output is removed only then, and only if it is walkrepro's (or ``--force``). A failure
  leaves the old output as it was and no temporary directory behind;
- a **file** (``export --out``, ``render --out``): :func:`check_file` refuses an existing
  file that is not walkrepro's own output unless ``--force``, a directory, and a place that
  cannot be written; :func:`writing_file` writes under a temporary name and renames.

Every refusal is a :class:`~walkrepro.errors.WalkreproError` (one paragraph, exit code 2).
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from walkrepro.errors import WalkreproError

#: The marker file walkrepro writes into every directory it owns.
MARKER = ".walkrepro-output"
#: Kinds of owned directories (the marker's ``kind``).
RUNS, REPORT, FIGURES = "runs", "report", "figures"
#: A run or sweep directory's name (``<UTC stamp>-<hex id>``), or one being written.
_RUN_NAME = re.compile(r"^(\d{8}T\d{6}Z-[0-9a-f]{6}|\.\d{8}T\d{6}Z-[0-9a-f]{6}\.partial)$")
#: What a report directory holds (:mod:`walkrepro.publish.report.site`).
_REPORT_ENTRIES = re.compile(r"^(.+\.html|style\.css|robots|assets)$")
_FORCE = "pass --force to use it anyway"


def marker_kind(directory: Path) -> str | None:
    """The kind recorded in ``directory``'s marker (None without a readable marker)."""
    try:
        return str(json.loads((directory / MARKER).read_text())["kind"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def write_marker(directory: Path, kind: str) -> None:
    """Mark ``directory`` as walkrepro's output of ``kind``."""
    from walkrepro._version import __version__

    text = json.dumps({"kind": kind, "walkrepro": __version__}) + "\n"
    (directory / MARKER).write_text(text)


def _entries(directory: Path) -> list[Path]:
    return [p for p in directory.iterdir() if p.name != MARKER]


def _legacy_runs_root(directory: Path) -> bool:
    """A runs root written before the marker: only ``<experiment>/<run>`` directories and
    ``sweeps/<experiment>/<sweep>`` directories."""

    def experiments(parent: Path) -> bool:
        return all(
            e.is_dir() and all(_RUN_NAME.match(r.name) for r in e.iterdir())
            for e in _entries(parent)
        )

    entries = _entries(directory)
    sweeps = [e for e in entries if e.name == "sweeps" and e.is_dir()]
    others = [e for e in entries if e not in sweeps]
    return (
        all(e.is_dir() for e in others)
        and all(experiments(s) for s in sweeps)
        and all(all(_RUN_NAME.match(r.name) for r in e.iterdir()) for e in others)
    )


def _legacy_report(directory: Path) -> bool:
    """A report written before the marker: its ``index.html`` and nothing else than pages,
    ``style.css``, ``robots/`` and ``assets/``."""
    entries = _entries(directory)
    return (directory / "index.html").is_file() and all(
        _REPORT_ENTRIES.match(e.name) for e in entries
    )


_LEGACY = {RUNS: _legacy_runs_root, REPORT: _legacy_report}


def _owned(directory: Path, kind: str) -> bool:
    """Whether ``directory`` (existing) is walkrepro's output of ``kind``, or empty."""
    if not _entries(directory):
        return True
    found = marker_kind(directory)
    if found is not None:
        return found == kind
    legacy = _LEGACY.get(kind)
    return legacy is not None and legacy(directory)


def _describe(directory: Path, kind: str) -> str:
    """Why ``directory`` is not walkrepro's ``kind`` output: what it holds."""
    found = marker_kind(directory)
    if found is not None:
        return f"it is a walkrepro {found} directory, not a {kind} directory"
    names = sorted(p.name for p in _entries(directory))
    shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
    return f"it holds files walkrepro did not write ({shown})"


def _unwritable(option: str, path: Path, exc: OSError | None = None) -> WalkreproError:
    why = f": {exc.strerror or exc}" if exc is not None else ": it is read-only"
    return WalkreproError(
        f"{option} {path}: cannot write here{why}. Choose a writable location with {option} PATH."
    )


def _creatable(path: Path, option: str) -> None:
    """Raise unless ``path`` exists or could be created: its nearest existing ancestor is a
    directory that can be written."""
    ancestor = path
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if ancestor == path:
        return
    if not ancestor.is_dir():
        raise WalkreproError(
            f"{option} {path}: cannot write here: {ancestor} is a file, not a directory. "
            f"Choose a writable location with {option} PATH."
        )
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise _unwritable(option, path)


def claim_root(
    root: Path,
    kind: str = RUNS,
    force: bool = False,
    option: str = "--out",
    create: bool = True,
) -> Path:
    """Make ``root`` walkrepro's ``kind`` directory (created if missing) and return it.

    Args:
        root: the directory outputs accumulate under.
        kind: :data:`RUNS` or :data:`FIGURES`.
        force: accept a directory that holds other files (the marker is written into it).
        option: the command-line option that named it, for the messages.
        create: create ``root`` and write its marker; False only checks (a command checks
            its ``--out`` before validating the rest, and creates it once something is
            written there, so a refused command leaves no empty directory).

    Raises:
        WalkreproError: ``root`` is a file, cannot be written, or holds files walkrepro did
            not write (without ``force``).
    """
    if root.exists() and not root.is_dir():
        raise WalkreproError(
            f"{option} {root}: that is a file, not a directory; give a directory with {option} DIR."
        )
    if root.is_dir():
        if not os.access(root, os.W_OK | os.X_OK):
            raise _unwritable(option, root)
        if not force and not _owned(root, kind):
            raise WalkreproError(
                f"{option} {root}: {_describe(root, kind)}; walkrepro writes only into its "
                f"own output directories (with a {MARKER} file) or empty ones. Choose a new "
                f"or empty directory, or {_FORCE}."
            )
    if not create:
        _creatable(root, option)
        return root
    try:
        root.mkdir(parents=True, exist_ok=True)
        if marker_kind(root) != kind:
            write_marker(root, kind)
    except OSError as exc:
        raise _unwritable(option, root, exc) from None
    return root


@contextmanager
def replacing(
    out: Path, kind: str = REPORT, force: bool = False, option: str = "--out"
) -> Iterator[Path]:
    """Write a directory that replaces ``out`` as a whole, atomically.

    Yields a hidden temporary sibling of ``out`` to write into. When the block ends
    normally, the sibling gets the marker and takes ``out``'s name, and the old ``out`` (if
    any) is deleted; when it raises (Ctrl-C included), the sibling is deleted and ``out`` is
    left as it was.

    Raises:
        WalkreproError: ``out`` is a file or read-only, its parent cannot be written, or it
            holds files walkrepro did not write (without ``force``); all before the block.
    """
    if out.exists() and not out.is_dir():
        raise WalkreproError(
            f"{option} {out}: that is a file, not a directory; give a directory with {option} DIR."
        )
    if out.is_dir():
        if not os.access(out, os.W_OK | os.X_OK):
            raise _unwritable(option, out)
        if not force and not _owned(out, kind):
            raise WalkreproError(
                f"{option} {out}: {_describe(out, kind)}, and walkrepro replaces this "
                f"directory as a whole. Choose a new or empty directory, or {_FORCE} "
                "(its contents are then deleted)."
            )
    tag = f"{os.getpid()}-{secrets.token_hex(3)}"
    work = out.with_name(f".{out.name}.{tag}.partial")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        work.mkdir()
    except OSError as exc:
        raise _unwritable(option, out, exc) from None
    try:
        yield work
        write_marker(work, kind)
        old = out.with_name(f".{out.name}.{tag}.old")
        if out.exists():
            os.rename(out, old)
            try:
                os.rename(work, out)
            except BaseException:
                os.rename(old, out)  # put the old output back
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(work, out)
    except OSError as exc:
        raise _unwritable(option, out, exc) from None
    finally:
        if work.exists():
            shutil.rmtree(work, ignore_errors=True)


def check_file(out: Path, force: bool = False, ours: bool = False, option: str = "--out") -> Path:
    """Check that the file ``out`` may be written.

    Args:
        out: the file to write.
        force: replace an existing file.
        ours: ``out`` is walkrepro's own output place (a run directory's ``video.mp4``), so
            an existing file there is replaced without ``force``.
        option: the command-line option that named it.

    Raises:
        WalkreproError: ``out`` is a directory, exists (without ``force`` or ``ours``), or
            its directory cannot be made or written.
    """
    if out.is_dir():
        raise WalkreproError(
            f"{option} {out}: that is a directory; give a file name with {option} FILE."
        )
    if out.exists() and not (force or ours):
        raise WalkreproError(
            f"{option} {out}: the file exists and walkrepro does not overwrite it; "
            f"give another name, or pass --force to replace it."
        )
    parent = out.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _unwritable(option, out, exc) from None
    if not os.access(parent, os.W_OK | os.X_OK):
        raise _unwritable(option, parent)
    return out


def partial_name(out: Path) -> Path:
    """The temporary name ``out`` is written under (hidden, same directory, same suffix so
    that writers that choose a format by it still do)."""
    return out.with_name(f".{out.stem}.{os.getpid()}.partial{out.suffix}")


@contextmanager
def writing_file(out: Path, option: str = "--out") -> Iterator[Path]:
    """Yields the temporary path to write ``out`` under; renames it to ``out`` when the
    block ends normally, deletes it when the block raises (``out`` is then untouched)."""
    partial = partial_name(out)
    try:
        yield partial
        os.replace(partial, out)
    except OSError as exc:
        raise _unwritable(option, out, exc) from None
    finally:
        partial.unlink(missing_ok=True)
