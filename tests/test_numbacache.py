"""numba's cache keyed on every source a kernel imports (walkrepro/numbacache.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from walkrepro import numbacache

HELPER = "import numba\n\n@numba.njit(cache=True)\ndef bump(x):\n    return x + {step}\n"
KERNEL = (
    "import numba\nfrom cachepair.helpers import bump\n\n"
    "@numba.njit(cache=True)\ndef kernel(x):\n    return 2.0 * bump(x)\n"
)
# Prints the kernel's value and whether it came from the on-disk cache.
SCRIPT = (
    "import sys\n"
    "import walkrepro.numbacache as n\n"
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
    return package


def _run(root: Path, mode: str) -> tuple[float, bool]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), *sys.path])}
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, mode], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    return float(out[0]), out[1] == "True"


def _edit_helper(package: Path, step: float) -> None:
    """Rewrites the helper, leaving the kernel's file (and its modification time) alone."""
    kernel = package / "kernel.py"
    stamp = kernel.stat()
    (package / "helpers.py").write_text(HELPER.format(step=step))
    os.utime(kernel, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))


@pytest.mark.slow
def test_editing_a_shared_helper_changes_the_dependent_kernels_result(tmp_path: Path) -> None:
    """With walkrepro's locator, a kernel that inlines a helper from another module is
    recompiled when only the helper's module changes; its cache is used otherwise."""
    package = _pair(tmp_path)
    assert _run(tmp_path, "watched") == (4.0, False)  # compiled and cached
    assert _run(tmp_path, "watched") == (4.0, True)  # loaded from the cache
    _edit_helper(package, 2.0)
    assert _run(tmp_path, "watched") == (6.0, False)  # the edit is seen: recompiled
    assert _run(tmp_path, "watched") == (6.0, True)


@pytest.mark.slow
def test_numbas_own_cache_keeps_the_stale_kernel(tmp_path: Path) -> None:
    """The control: with numba's default locator the same edit leaves the stale kernel in
    use (the bug the locator exists for; if numba fixes it, this test says so)."""
    package = _pair(tmp_path)
    assert _run(tmp_path, "default") == (4.0, False)
    _edit_helper(package, 2.0)
    assert _run(tmp_path, "default") == (4.0, True)  # stale: still x + 1


def test_walkrepro_kernels_depend_on_the_helpers_they_import() -> None:
    """The efsm and qpimpedance kernels' stamps cover robot.py, whose helpers they inline."""
    for module in ("walkrepro.controllers.efsm.kernels", "walkrepro.controllers.qpimpedance.tasks"):
        names = {path.name for path in numbacache.dependency_files(module)}
        assert {"robot.py", f"{module.rsplit('.', 1)[1]}.py"} <= names


def test_kernels_outside_watched_packages_keep_numbas_locators() -> None:
    """numba's own locators handle other packages' kernels."""
    assert numbacache.dependency_files("numpy.linalg") == []
    assert numbacache.SourceTreeLocator.from_function(len, "x.py") is None
