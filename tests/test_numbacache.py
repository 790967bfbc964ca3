"""numba's cache directory keyed on every source a kernel imports (walkrepro/runtime/numbacache.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from walkrepro.runtime import numbacache

HELPER = "import numba\n\n@numba.njit(cache=True)\ndef bump(x):\n    return x + {step}\n"
KERNEL = (
    "import numba\nfrom cachepair.helpers import bump\n\n"
    "@numba.njit(cache=True)\ndef kernel(x):\n    return 2.0 * bump(x)\n"
)
# Prints the kernel's value and whether it came from the on-disk cache.
SCRIPT = (
    "import sys\n"
    "import walkrepro.runtime.numbacache as n\n"
    "if sys.argv[1] == 'watched':\n    n.watch('cachepair')\n"
    "from cachepair.kernel import kernel\n"
    "print(kernel(1.0), bool(kernel.stats.cache_hits))\n"
)


def _pair(root: Path) -> Path:
    package = root / "cachepair"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "helpers.py").write_text(HELPER.format(step=1.0))
    (package / "kernel.py").write_text(KERNEL)
    (package / "other.py").write_text("ANSWER = 42\n")
    return package


def _run(root: Path, mode: str) -> tuple[float, bool]:
    env = {k: v for k, v in os.environ.items() if k != numbacache.CACHE_DIR_ENV}
    env["PYTHONPATH"] = os.pathsep.join([str(root), *sys.path])
    env["XDG_CACHE_HOME"] = str(root / "cache")  # not the developer's cache
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, mode], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    return float(out[0]), out[1] == "True"


def _edit(file: Path, text: str, keep: Path) -> None:
    """Rewrites ``file``, leaving ``keep`` (the kernel's file, its modification time) alone."""
    stamp = keep.stat()
    file.write_text(text)
    os.utime(keep, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))


@pytest.mark.slow
def test_editing_a_shared_helper_changes_the_dependent_kernels_result(tmp_path: Path) -> None:
    """With the cache directory keyed on the sources, a kernel that inlines a helper from
    another module is recompiled when only the helper's module changes; its cache is used
    otherwise."""
    package = _pair(tmp_path)
    assert _run(tmp_path, "watched") == (4.0, False)  # compiled and cached
    assert _run(tmp_path, "watched") == (4.0, True)  # loaded from the cache
    _edit(package / "helpers.py", HELPER.format(step=2.0), package / "kernel.py")
    assert _run(tmp_path, "watched") == (6.0, False)  # the edit is seen: recompiled
    assert _run(tmp_path, "watched") == (6.0, True)


@pytest.mark.slow
def test_numbas_own_cache_keeps_the_stale_kernel(tmp_path: Path) -> None:
    """The control: unwatched, the same edit leaves the stale kernel in use (the bug the
    keyed directory exists for; if numba fixes it, this test says so)."""
    package = _pair(tmp_path)
    assert _run(tmp_path, "default") == (4.0, False)
    _edit(package / "helpers.py", HELPER.format(step=2.0), package / "kernel.py")
    assert _run(tmp_path, "default") == (4.0, True)  # stale: still x + 1


@pytest.fixture
def watched_pair(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The pair package, watched alone, with the cache home in ``tmp_path``."""
    package = _pair(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(numbacache, "PACKAGES", {"cachepair"})
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(numbacache.CACHE_DIR_ENV, raising=False)
    return package


def test_the_key_follows_the_kernels_sources_only(watched_pair: Path) -> None:
    """An edit of a module a kernel imports changes the key; an edit of a module no kernel
    imports does not."""
    assert numbacache.kernel_modules("cachepair") == ["cachepair.helpers", "cachepair.kernel"]
    key = numbacache.source_key()
    (watched_pair / "other.py").write_text("ANSWER = 43\n")
    assert numbacache.source_key() == key
    (watched_pair / "helpers.py").write_text(HELPER.format(step=3.0))
    assert numbacache.source_key() != key


def test_the_remembered_key_is_recomputed_when_a_source_changes(watched_pair: Path) -> None:
    key = numbacache.cache_key()
    assert numbacache.cache_key() == key == numbacache.source_key()
    (watched_pair / "helpers.py").write_text(HELPER.format(step=5.0))
    assert numbacache.cache_key() == numbacache.source_key() != key


def test_install_points_numba_at_the_keyed_directory(watched_pair: Path, tmp_path: Path) -> None:
    directory = numbacache.install()
    assert directory == tmp_path / "cache" / "walkrepro" / "numba" / (
        f"walkrepro-{numbacache.cache_key()}"
    )
    assert os.environ[numbacache.CACHE_DIR_ENV] == str(directory)
    # a worker process inherits the variable: its home stays the same, not nested
    assert numbacache.cache_home() == directory.parent


def test_walkrepro_kernels_depend_on_the_helpers_they_import() -> None:
    """The efsm and qpimpedance kernels' sources cover robot.py, whose helpers they inline."""
    for module in ("walkrepro.papers.lee2021.kernels", "walkrepro.papers.jo_oh.tasks"):
        names = {path.name for path in numbacache.dependency_files(module)}
        assert {"robot.py", f"{module.rsplit('.', 1)[1]}.py"} <= names
    kernels = numbacache.kernel_modules("walkrepro")
    assert "walkrepro.papers.lee2021.kernels" in kernels and "walkrepro.cli" not in kernels


def test_modules_outside_watched_packages_have_no_dependencies() -> None:
    assert numbacache.dependency_files("numpy.linalg") == []
