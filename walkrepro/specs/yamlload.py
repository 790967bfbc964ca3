"""YAML reading with JSON's numbers: ``5e-05`` is a float, as in YAML 1.2.

PyYAML resolves plain scalars by YAML 1.1, where a float needs a dot (``5.0e-05``), so a
number written the way JSON and Python's ``repr`` write it (``5e-05``, ``1e3``) would be
read as a string. walkrepro writes grid values as JSON (``cells.csv``, overrides) and users
type such numbers in specs and on the command line, so every YAML it reads goes through
:func:`load`, whose loader also takes the exponent-only forms as floats.

The loader also refuses a key given twice in one mapping (:class:`DuplicateKeyError`):
YAML would keep the last one silently, so ``robot: dyros_red`` followed later by
``robot: coman`` would run coman.
"""

from __future__ import annotations

import re
from typing import Any

import yaml


class DuplicateKeyError(yaml.constructor.ConstructorError):
    """A mapping gives the same key twice; ``problem_mark`` is the second one."""


#: libyaml's parser where PyYAML was built with it (ten times faster; same nodes and marks).
_SafeLoader: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class Loader(_SafeLoader):  # type: ignore[misc, valid-type]
    """``yaml.SafeLoader`` whose float resolver also accepts ``1e3``, ``5e-05``, ``-2E+4``,
    and which refuses duplicate keys."""

    def construct_mapping(self, node: yaml.Node, deep: bool = False) -> dict:
        """The mapping, after checking that no key is given twice (merge keys aside)."""
        if isinstance(node, yaml.MappingNode):
            first_line: dict[object, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge" or not isinstance(
                    key_node, yaml.ScalarNode
                ):
                    continue  # ``<<`` merges may be overridden; complex keys are rare
                key = self.construct_object(key_node)
                if key in first_line:
                    raise DuplicateKeyError(
                        "while reading a mapping",
                        node.start_mark,
                        f"duplicate key {key!r} (first given on line {first_line[key]}); "
                        "YAML would silently keep only the last one",
                        key_node.start_mark,
                    )
                first_line[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


_FLOAT_12 = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)
# Replace the SafeLoader's float resolver (a copy, so yaml.SafeLoader itself is unchanged).
Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:float"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def load(text: str) -> Any:
    """Parse YAML ``text`` (safe types only) with JSON-style exponent floats."""
    return yaml.load(text, Loader=Loader)  # noqa: S506 (a SafeLoader subclass)


def load_with_node(text: str) -> tuple[Any, yaml.Node | None]:
    """Parse ``text`` once: the data as :func:`load` gives it, and the composed node tree
    (whose marks give the line of every key and item); ``(None, None)`` for no document."""
    loader = Loader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    finally:
        loader.dispose()
    return data, node
