"""Whether a reference was made by the current code: its commit against ``HEAD``.

A committed reference records the commit it was made at (``results/<experiment>/run.json``;
a map: ``results/maps/<map>/sweep.yaml``, ``provenance.commit``). Its rows are the current
code's if nothing that decides them changed since: the tree of ``walkrepro/``, ``robots/``
and the experiment's own spec ``experiments/<experiment>.yaml`` at that commit equals
``HEAD``'s (``git diff --quiet <commit> HEAD -- …``). Any edit there counts, even one that
moves no number (re-making the reference is what shows it does not).

Outside a clone of walkrepro's repository (an installed copy) or for a commit git does not
know, currency is unknown.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from functools import cache

from walkrepro.locations import IS_CHECKOUT, PROJECT_ROOT

#: The folders whose tree decides every experiment's rows.
CODE_PATHS = ("walkrepro", "robots")


@dataclass(frozen=True)
class Currency:
    """A reference's commit and whether the code that decides it is unchanged since.

    Attributes:
        commit: the full commit the reference was made at (``""``: not recorded).
        current: True (unchanged), False (changed) or None (unknown).
        changed: the paths (of :data:`CODE_PATHS` and the spec) that changed, when known.
    """

    commit: str
    current: bool | None
    changed: tuple[str, ...] = ()

    @property
    def short(self) -> str:
        """The commit's first 10 characters, or ``unrecorded``."""
        return self.commit[:10] if self.commit else "unrecorded"

    @property
    def text(self) -> str:
        """``made at <commit>, the current code`` or ``…, code changed since: …``."""
        if not self.commit:
            return "commit not recorded"
        if self.current is None:
            return f"made at {self.short} (currency unknown)"
        if self.current:
            return f"made at {self.short}, the current code"
        return f"made at {self.short}; changed since: {', '.join(self.changed)}"


def _git(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["git", "-C", str(PROJECT_ROOT), *args], capture_output=True, text=True, check=False
    )


@cache
def _head() -> str | None:
    if not IS_CHECKOUT:
        return None
    try:
        result = _git("rev-parse", "HEAD")
    except OSError:  # no git
        return None
    return result.stdout.strip() if result.returncode == 0 else None


@cache
def _changed(commit: str, paths: tuple[str, ...]) -> tuple[str, ...] | None:
    """The paths among ``paths`` whose tree differs between ``commit`` and HEAD (a folder
    named by itself, with the count of its changed files), or None if unknown."""
    result = _git("diff", "--name-only", commit, "HEAD", "--", *paths)
    if result.returncode != 0:  # an unknown commit
        return None
    files = [f for f in result.stdout.splitlines() if f]
    out = []
    for path in paths:
        inside = [f for f in files if f == path or f.startswith(path + "/")]
        if inside:
            out.append(
                path if len(inside) == 1 and inside[0] == path else f"{path}/ ({len(inside)} files)"
            )
    return tuple(out)


def currency(commit: str | None, spec_path: str | None) -> Currency:
    """The currency of a reference made at ``commit`` (``+dirty`` is stripped: the commit's
    tree is what can be compared) for the spec at ``spec_path`` (relative to the repository,
    e.g. ``experiments/forward_walk.yaml``; None: the code only)."""
    commit = (commit or "").removesuffix("+dirty").strip()
    if not commit:
        return Currency("", None)
    if _head() is None:
        return Currency(commit, None)
    paths = (*CODE_PATHS, spec_path) if spec_path else CODE_PATHS
    changed = _changed(commit, paths)
    if changed is None:
        return Currency(commit, None)
    return Currency(commit, not changed, changed)
