"""YAML reading with JSON's numbers: ``5e-05`` is a float, as in YAML 1.2.

PyYAML resolves plain scalars by YAML 1.1, where a float needs a dot (``5.0e-05``), so a
number written the way JSON and Python's ``repr`` write it (``5e-05``, ``1e3``) would be
read as a string. walkrepro writes grid values as JSON (``cells.csv``, overrides) and users
type such numbers in specs and on the command line, so every YAML it reads goes through
:func:`load`, whose loader also takes the exponent-only forms as floats.
"""

from __future__ import annotations

import re
from typing import Any

import yaml


class Loader(yaml.SafeLoader):
    """``yaml.SafeLoader`` whose float resolver also accepts ``1e3``, ``5e-05``, ``-2E+4``."""


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
