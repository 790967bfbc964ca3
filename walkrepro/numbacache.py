"""numba's on-disk cache, keyed on every source file a kernel can depend on.

numba's ``cache=True`` stamps a cached kernel with its own file's modification time and
size only. A kernel compiles its callees (``@njit`` helpers) and the globals it reads
(constants, arrays) into itself, so editing a helper or a constant in *another* module, e.g.
``walkrepro/robot.py``'s ``frame_jacobian`` used by ``controllers/efsm/kernels.py``, would
leave the kernel's stale machine code in use.

:class:`SourceTreeLocator` is numba's in-tree locator (cache files in the module's
``__pycache__``) with a different stamp: a hash of the kernel's module and of every module
of the same package it imports, transitively, found by reading their ``import`` statements
(not by importing them). Any edit to one of those files changes the stamp, and numba then
recompiles the kernel and overwrites its cache. It is installed for :data:`PACKAGES` when
walkrepro is imported, before any kernel is defined.
"""

from __future__ import annotations

import ast
import hashlib
import sys
from functools import cache
from pathlib import Path

from numba.core import caching

#: Top-level packages whose kernels are cached by :class:`SourceTreeLocator`.
PACKAGES: set[str] = {"walkrepro"}


def watch(package: str) -> None:
    """Key the caches of ``package``'s kernels (those defined from now on) on its sources."""
    PACKAGES.add(package)


def _package_root(module: str) -> Path | None:
    """The directory that holds ``module``'s top-level package, if it is a watched one."""
    top = module.partition(".")[0]
    if top not in PACKAGES:
        return None
    package = sys.modules.get(top)
    file = getattr(package, "__file__", None)
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


@cache
def _file_hash(file: Path, mtime_ns: int, size: int) -> bytes:
    return hashlib.sha256(file.read_bytes()).digest()


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


def source_stamp(module: str) -> str:
    """Hash of :func:`dependency_files` (their paths and contents)."""
    digest = hashlib.sha256()
    for file in dependency_files(module):
        stat = file.stat()
        digest.update(str(file).encode() + _file_hash(file, stat.st_mtime_ns, stat.st_size))
    return digest.hexdigest()


class SourceTreeLocator(caching.InTreeCacheLocator):
    """numba's in-tree cache locator, stamped with :func:`source_stamp` of the kernel's
    module instead of its own file's modification time."""

    def __init__(self, py_func, py_file) -> None:  # noqa: ANN001 - numba's signature
        super().__init__(py_func, py_file)
        self._module = py_func.__module__

    @classmethod
    def from_function(cls, py_func, py_file):  # noqa: ANN001, ANN206 - numba's signature
        if _package_root(getattr(py_func, "__module__", "") or "") is None:
            return None  # not ours: numba's own locators decide
        return super().from_function(py_func, py_file)

    def get_source_stamp(self) -> str:
        return source_stamp(self._module)


def install() -> None:
    """Puts :class:`SourceTreeLocator` first among numba's cache locators (idempotent)."""
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # numba < 0.61
    if SourceTreeLocator not in impl._locator_classes:
        impl._locator_classes = [SourceTreeLocator, *impl._locator_classes]
