"""numba's on-disk cache, in a directory keyed on every source file a kernel can depend on.

numba's ``cache=True`` stamps a cached kernel with its own file's modification time and
size only. A kernel compiles its callees (``@njit`` helpers) and the globals it reads
(constants, arrays) into itself, so editing a helper or a constant in *another* module, e.g.
``walkrepro/sim/robot.py``'s ``frame_jacobian`` used by ``papers/lee2021/kernels.py``, would
leave the kernel's stale machine code in use.

So walkrepro gives numba a cache directory of its own through numba's documented setting
``NUMBA_CACHE_DIR`` (``numba.config.CACHE_DIR``): ``<cache home>/walkrepro/numba/<key>``,
where the key is a hash of the kernel sources of the watched packages (:data:`PACKAGES`):
every module that imports numba, and every module of the same package it imports,
transitively, found by reading their ``import`` statements (not by importing them). An edit
to one of those files gives a new key and so a new, empty directory, where numba compiles
afresh; an edit elsewhere (the CLI, a figure) keeps the compiled kernels. The cache home is
``$XDG_CACHE_HOME`` or ``~/.cache``, or, when the user set ``NUMBA_CACHE_DIR``, that
directory. Keys unused for :data:`KEEP_DAYS` days are removed.

:func:`install` runs before the first kernel compiles: in the ``walkrepro`` command's
set-up (:func:`walkrepro.cli.command_setup`, through the environment, which its worker
processes inherit) and in :func:`walkrepro.load` (through ``numba.config``, leaving a
library user's environment alone). Importing walkrepro does neither.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import shutil
import sys
import time
from functools import cache
from pathlib import Path

#: Top-level packages whose kernels' sources key the cache directory.
PACKAGES: set[str] = {"walkrepro"}
#: A cache directory (one key) not used for this many days is removed.
KEEP_DAYS = 14
#: numba's setting (an environment variable read when numba is imported).
CACHE_DIR_ENV = "NUMBA_CACHE_DIR"


def watch(package: str) -> None:
    """Key the cache directory on ``package``'s kernel sources too (a package outside
    walkrepro with kernels of its own); call it before the package's kernels compile."""
    PACKAGES.add(package)
    install()


def _package_root(module: str) -> Path | None:
    """The directory that holds ``module``'s top-level package, if it is a watched one."""
    top = module.partition(".")[0]
    if top not in PACKAGES:
        return None
    package = sys.modules.get(top)
    file = getattr(package, "__file__", None)
    if file is None:  # not imported yet: found on the path without importing it
        from importlib.util import find_spec

        spec = find_spec(top)
        file = spec.origin if spec is not None else None
    return Path(file).resolve().parent.parent if file else None


def _module_file(root: Path, module: str) -> Path | None:
    base = root.joinpath(*module.split("."))
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _imports(file: Path, module: str) -> set[str]:
    stat = file.stat()
    return _imports_of(file, module, stat.st_mtime_ns, stat.st_size)


@cache
def _imports_of(file: Path, module: str, mtime_ns: int, size: int) -> frozenset[str]:
    """Modules of the same top-level package that ``file`` (module ``module``) imports (for
    ``from m import n``: ``m``, and ``m.n`` if that is a module). The packages on the way run
    their ``__init__`` too, but a kernel can only compile in the names it imports."""
    top = module.partition(".")[0]
    is_package = file.name == "__init__.py"
    found: set[str] = set()
    for node in _runtime_nodes(ast.parse(file.read_bytes(), str(file))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from the module's package, up node.level - 1 more
                parts = module.split(".")[: len(module.split(".")) - node.level + is_package]
                base = ".".join([*parts, *([node.module] if node.module else [])])
            else:
                base = node.module or ""
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return frozenset(name for name in found if name.partition(".")[0] == top)


def _runtime_nodes(tree: ast.AST):  # noqa: ANN202 - a generator of nodes
    """``ast.walk`` without the ``if TYPE_CHECKING:`` blocks (never run, so never compiled)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            test = getattr(child, "test", None) if isinstance(child, ast.If) else None
            name = getattr(test, "id", None) or getattr(test, "attr", None)
            if name == "TYPE_CHECKING":
                todo.extend(child.orelse)
            else:
                todo.append(child)


def dependency_files(module: str) -> list[Path]:
    """``module``'s source file and those of every module of its package that it imports,
    directly or through others (sorted); empty if ``module`` is not in a watched package."""
    root = _package_root(module)
    if root is None:
        return []
    seen: dict[str, Path] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        file = _module_file(root, name)
        if file is None:  # a name imported from a module, not a module itself
            continue
        seen[name] = file
        todo.extend(_imports(file, name) - seen.keys())
    return sorted(seen.values())


def kernel_modules(package: str) -> list[str]:
    """The modules of ``package`` that import numba (where a kernel can be defined)."""
    root = _package_root(package)
    if root is None:
        return []
    found = []
    for file in sorted((root / package).rglob("*.py")):
        if b"numba" in file.read_bytes():  # cheap filter, then the imports themselves
            module = ".".join(file.relative_to(root).with_suffix("").parts)
            module = module.removesuffix(".__init__")
            tree = ast.parse(file.read_bytes(), str(file))
            imported = {
                alias.name.partition(".")[0]
                for node in _runtime_nodes(tree)
                if isinstance(node, ast.Import)
                for alias in node.names
            } | {
                (node.module or "").partition(".")[0]
                for node in _runtime_nodes(tree)
                if isinstance(node, ast.ImportFrom) and not node.level
            }
            if "numba" in imported:
                found.append(module)
    return found


def _stat_signature() -> str:
    """Hash of the path, modification time and size of every source file of the watched
    packages: cheap (no file is read), and it changes whenever a source file may have."""
    digest = hashlib.sha256()
    for package in sorted(PACKAGES):
        root = _package_root(package)
        if root is None:
            continue
        for file in sorted((root / package).rglob("*.py")):
            stat = file.stat()
            digest.update(f"{file}\0{stat.st_mtime_ns}\0{stat.st_size}\n".encode())
    return digest.hexdigest()


def cache_key() -> str:
    """:func:`source_key`, remembered in the cache home for the sources' current
    :func:`_stat_signature` (reading and parsing them takes a third of a second)."""
    memo = cache_home() / "keys.json"
    signature = _stat_signature()
    try:
        known = json.loads(memo.read_text())
    except (OSError, ValueError):
        known = {}
    if not isinstance(known, dict):
        known = {}
    if isinstance(known.get(signature), str):
        return known[signature]
    key = source_key()
    known = dict(list(known.items())[-31:]) | {signature: key}
    try:
        memo.parent.mkdir(parents=True, exist_ok=True)
        partial = memo.with_name(f".keys.{os.getpid()}.json")
        partial.write_text(json.dumps(known))
        os.replace(partial, memo)  # atomic: a concurrent reader sees the old or the new
    except OSError:
        pass
    return key


def source_key() -> str:
    """Hash of the kernel sources of every watched package: their paths (relative to the
    package's parent) and contents."""
    digest = hashlib.sha256()
    for package in sorted(PACKAGES):
        root = _package_root(package)
        if root is None:
            continue
        files = sorted({f for m in kernel_modules(package) for f in dependency_files(m)})
        for file in files:
            digest.update(str(file.relative_to(root)).encode() + b"\0" + file.read_bytes())
    return digest.hexdigest()[:16]


def cache_home() -> Path:
    """The user's ``NUMBA_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/walkrepro/numba`` (or
    ``~/.cache/walkrepro/numba``). A ``NUMBA_CACHE_DIR`` that is already one of ours (a
    worker process inherits its parent's) names its home by its parent."""
    user = os.environ.get(CACHE_DIR_ENV)
    if user:
        path = Path(user)
        return path.parent if path.name.startswith("walkrepro-") else path
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "walkrepro" / "numba"


def _prune(home: Path, keep: Path) -> None:
    """Remove the key directories beside ``keep`` unused for :data:`KEEP_DAYS` days."""
    cutoff = time.time() - KEEP_DAYS * 86400
    for old in home.glob("walkrepro-*"):
        if old != keep and old.is_dir() and old.stat().st_mtime < cutoff:
            shutil.rmtree(old, ignore_errors=True)


def install(environ: bool = True) -> Path | None:
    """Point numba's cache at the directory of the current :func:`cache_key` (idempotent).

    Args:
        environ: also set ``NUMBA_CACHE_DIR`` in the environment, so that child processes
            (``--jobs`` workers, a local Ray) inherit it: the command's set-up does. The
            library (:func:`walkrepro.load`) leaves the environment alone and sets numba's
            own setting, ``numba.config.CACHE_DIR``, which numba reads at each
            ``cache=True`` decoration and keeps while no ``NUMBA_*`` variable changes.

    Returns the directory, or None if it cannot be created (numba's own default applies).
    """
    home = cache_home()
    directory = home / f"walkrepro-{cache_key()}"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        os.utime(directory)  # marks it used, for _prune
    except OSError:
        return None
    _prune(home, directory)
    if environ:
        os.environ[CACHE_DIR_ENV] = str(directory)  # read when numba is imported
        config = sys.modules.get("numba.core.config")
        if config is not None:  # numba already imported: its setting, read at each compile
            config.CACHE_DIR = str(directory)
    else:
        from numba.core import config

        config.CACHE_DIR = str(directory)
    return directory
