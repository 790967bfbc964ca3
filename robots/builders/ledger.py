"""The provenance ledgers ``robots/<robot>/parameters.yaml``: reading and validating them,
the numbers as the MJCF and the READMEs write them, and each README's generated table."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from walkrepro.specs.yamlload import load as load_yaml

ROBOTS_DIR = Path(__file__).resolve().parents[1]


def fmt(x: float, digits: int = 6) -> str:
    """Compact decimal text of ``x`` with ``digits`` significant digits, never ``-0``.

    Values below 1e-12 in magnitude are round-off of zero (e.g. symmetric sums) and are
    written as 0 so the file reads cleanly and regenerates identically.
    """
    if abs(x) < 1e-12:
        return "0"
    s = f"{x:.{digits}g}"
    return "0" if s in ("-0", "0") else s


def fvec(v: object, digits: int = 6) -> str:
    return " ".join(fmt(float(x), digits) for x in np.asarray(v, dtype=float).ravel())


#: The four provenance classes (shared/GUIDE.md, "Models around the controller").
LEDGER_CLASSES = ("paper", "source", "assumed", "calibrated")
#: Fields every ledger entry must have, and the optional ones.
LEDGER_REQUIRED = ("value", "unit", "class", "source")
LEDGER_OPTIONAL = ("description", "source_value")
#: The block of a robot README that ``--readme`` rewrites from the ledger.
README_BEGIN = "<!-- parameters: generated from parameters.yaml; do not edit -->"
README_END = "<!-- end of parameters -->"

LedgerValue = float | list[float] | dict[str, float] | str
#: Ledger entries named ``option_<attribute>`` set the robot's MJCF ``<option>`` attribute
#: (the scene's solver and friction cone, which the robot's lab's simulator decided); their
#: value may be the attribute's MuJoCo keyword (``elliptic``), not only a number.
OPTION_PREFIX = "option_"


class LedgerError(ValueError):
    """A ledger file is malformed; the message names the file and the entry."""


def _is_number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _check_value(where: str, value: object) -> None:
    """A number, a list of numbers, or a mapping name -> number (per-joint tables)."""
    if _is_number(value):
        return
    if isinstance(value, list) and value and all(_is_number(v) for v in value):
        return
    if (
        isinstance(value, dict)
        and value
        and all(isinstance(k, str) and _is_number(v) for k, v in value.items())
    ):
        return
    raise LedgerError(
        f"{where}: value must be a number, a list of numbers or a mapping name -> number, "
        f"not {value!r}"
    )


def validate_entry(path: Path, name: object, entry: object) -> None:
    """Raise :class:`LedgerError` naming ``path`` and ``name`` unless the entry is well formed."""
    where = f"{path}: parameters.{name}"
    if not isinstance(name, str) or not name:
        raise LedgerError(f"{path}: parameter name {name!r} must be a non-empty string")
    if not isinstance(entry, dict):
        raise LedgerError(f"{where}: must be a mapping with {', '.join(LEDGER_REQUIRED)}")
    missing = [k for k in LEDGER_REQUIRED if k not in entry]
    if missing:
        raise LedgerError(f"{where}: missing {', '.join(missing)}")
    unknown = sorted(set(entry) - set(LEDGER_REQUIRED) - set(LEDGER_OPTIONAL))
    if unknown:
        raise LedgerError(f"{where}: unknown field(s) {', '.join(map(str, unknown))}")
    if entry["class"] not in LEDGER_CLASSES:
        raise LedgerError(
            f"{where}: class {entry['class']!r} is not one of {', '.join(LEDGER_CLASSES)}"
        )
    for key in ("unit", "source"):
        if not isinstance(entry[key], str):
            raise LedgerError(f"{where}: {key} must be a string")
    if not entry["source"].strip():
        raise LedgerError(f"{where}: source is empty")
    if not (name.startswith(OPTION_PREFIX) and isinstance(entry["value"], str)):
        _check_value(where, entry["value"])
    if "source_value" in entry:
        sv = entry["source_value"]
        if not (isinstance(sv, dict) and set(sv) == {"value", "source"}):
            raise LedgerError(f"{where}: source_value must be a mapping with value and source")
        _check_value(f"{where}.source_value", sv["value"])
        if not isinstance(sv["source"], str) or not sv["source"].strip():
            raise LedgerError(f"{where}: source_value.source is empty")


def read_ledger_file(path: Path) -> dict:
    """One ledger file, validated (its ``inherits`` is not followed here)."""
    if not path.exists():
        raise LedgerError(f"{path}: no such ledger")
    data = load_yaml(path.read_text())
    if not isinstance(data, dict) or set(data) != {"robot", "inherits", "parameters"}:
        raise LedgerError(f"{path}: the top level must have exactly robot, inherits, parameters")
    if data["robot"] != path.parent.name:
        raise LedgerError(f"{path}: robot {data['robot']!r} is not its directory's name")
    if data["inherits"] is not None and not isinstance(data["inherits"], str):
        raise LedgerError(f"{path}: inherits must be null or a robot name")
    params = data["parameters"]
    if not isinstance(params, dict) or not params:
        raise LedgerError(f"{path}: parameters must be a non-empty mapping")
    for name, entry in params.items():
        validate_entry(path, name, entry)
    return data


class Ledger:
    """A robot's resolved ledger: its own entries over those it inherits.

    Reading a value (``ledger["thigh"]``, :meth:`num`, :meth:`vec`, :meth:`table`) records
    the entry as used, so a test can check that every entry sets some number.
    """

    def __init__(self, robot: str, entries: dict[str, dict], files: dict[str, Path]) -> None:
        self.robot = robot
        self.entries = entries  # name -> entry, inherited ones first
        self.files = files  # name -> the ledger file that gives it
        self.accessed: set[str] = set()

    def __getitem__(self, name: str) -> LedgerValue:
        if name not in self.entries:
            raise LedgerError(f"{self.robot}: no ledger entry {name!r}")
        self.accessed.add(name)
        return self.entries[name]["value"]

    def num(self, name: str) -> float:
        """The entry's value as one number."""
        value = self[name]
        if not _is_number(value):
            raise LedgerError(f"{self.files[name]}: parameters.{name}: expected one number")
        return float(value)

    def vec(self, name: str, n: int | None = None) -> tuple[float, ...]:
        """The entry's value as a tuple of numbers (of length ``n`` if given)."""
        value = self[name]
        if not isinstance(value, list) or (n is not None and len(value) != n):
            raise LedgerError(
                f"{self.files[name]}: parameters.{name}: expected a list of {n or 'some'} numbers"
            )
        return tuple(float(v) for v in value)

    def table(self, name: str) -> dict[str, float]:
        """The entry's value as a mapping name -> number."""
        value = self[name]
        if not isinstance(value, dict):
            raise LedgerError(f"{self.files[name]}: parameters.{name}: expected a mapping")
        return {k: float(v) for k, v in value.items()}

    def per_joint(self, name: str) -> PerJoint:
        """The entry's value: one number for every joint, or a mapping per joint kind."""
        value = self[name]
        return self.table(name) if isinstance(value, dict) else self.num(name)

    def unused(self) -> list[str]:
        """Entries no number has read (yet)."""
        return [name for name in self.entries if name not in self.accessed]


def ledger_path(robot: str, robots_dir: Path = ROBOTS_DIR) -> Path:
    return robots_dir / robot / "parameters.yaml"


def load_ledger(robot: str, robots_dir: Path = ROBOTS_DIR) -> Ledger:
    """The robot's ledger, following ``inherits`` (entries here add or replace)."""
    chain: list[tuple[Path, dict]] = []
    name: str | None = robot
    while name is not None:
        path = ledger_path(name, robots_dir)
        if any(p == path for p, _ in chain):
            raise LedgerError(f"{path}: inherits forms a cycle")
        data = read_ledger_file(path)
        chain.append((path, data))
        name = data["inherits"]
    entries: dict[str, dict] = {}
    files: dict[str, Path] = {}
    for path, data in reversed(chain):
        for key, entry in data["parameters"].items():
            entries[key] = entry
            files[key] = path
    return Ledger(robot, entries, files)


#: A drive value: one number for every joint, or one per joint kind (``hip_yaw`` … ``ankle_roll``).
PerJoint = float | dict[str, float]


def mjcf_options(p: Ledger) -> dict[str, str]:
    """The ``<option>`` attributes the ledger's ``option_*`` entries set (keyword or number)."""
    out = {}
    for name in p.entries:
        if name.startswith(OPTION_PREFIX):
            value = p[name]
            out[name[len(OPTION_PREFIX) :]] = value if isinstance(value, str) else fvec(value)
    return out


def format_ledger_value(value: LedgerValue) -> str:
    """A ledger value as table text: a number, ``[a, b]``, ``name value, …`` or a keyword."""
    if isinstance(value, str):
        return value
    if isinstance(value, dict):
        return ", ".join(f"{k} {fmt(float(v), 10)}" for k, v in value.items())
    if isinstance(value, list):
        return "[" + ", ".join(fmt(float(v), 10) for v in value) + "]"
    return fmt(float(value), 10)


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def class_counts(entries: dict[str, dict]) -> str:
    counts = {c: sum(e["class"] == c for e in entries.values()) for c in LEDGER_CLASSES}
    return ", ".join(f"{c} {n}" for c, n in counts.items())


def readme_block(robot: str, robots_dir: Path = ROBOTS_DIR) -> str:
    """The generated README block of ``robot``: its own ledger entries as a table, and the
    count per class (of its own entries and, for a variant, of the resolved ledger)."""
    data = read_ledger_file(ledger_path(robot, robots_dir))
    own = data["parameters"]
    lines = [
        README_BEGIN,
        "",
        "| name | value | unit | class | source |",
        "|---|---|---|---|---|",
    ]
    for name, e in own.items():
        source = e["source"]
        if "source_value" in e:
            sv = e["source_value"]
            source += (
                f" **Source value not in force:** {format_ledger_value(sv['value'])}"
                f" ({sv['source']})"
            )
        lines.append(
            f"| `{name}` | {format_ledger_value(e['value'])} | {_cell(e['unit'])} | "
            f"{e['class']} | {_cell(source)} |"
        )
    lines.append("")
    entries = "1 entry" if len(own) == 1 else f"{len(own)} entries"
    counts = f"{entries} in `robots/{robot}/parameters.yaml`: {class_counts(own)}."
    parent = data["inherits"]
    if parent is not None:
        resolved = load_ledger(robot, robots_dir).entries
        counts += (
            f" It extends `{parent}` (`robots/{parent}/README.md`): the entries above add to or "
            f"replace its ledger; the robot's {len(resolved)} entries: {class_counts(resolved)}."
        )
    lines += [counts, "", README_END]
    return "\n".join(lines)


def replace_readme_block(text: str, block: str, path: Path) -> str:
    """``text`` with its generated parameter block replaced by ``block``."""
    if text.count(README_BEGIN) != 1 or text.count(README_END) != 1:
        raise LedgerError(f"{path}: needs exactly one {README_BEGIN} ... {README_END} block")
    head, rest = text.split(README_BEGIN)
    _, tail = rest.split(README_END)
    return head + block + tail


def readme_text(robot: str, robots_dir: Path = ROBOTS_DIR) -> tuple[Path, str]:
    """The README's path and the text it must have."""
    path = robots_dir / robot / "README.md"
    return path, replace_readme_block(path.read_text(), readme_block(robot, robots_dir), path)
