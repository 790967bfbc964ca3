#!/usr/bin/env python3
"""Generate the MJCF reconstructions ``robots/<name>/robot.xml`` from published figures.

Usage::

    python robots/build_models.py            # (re)write every robot.xml and README block
    python robots/build_models.py --readme   # only the README parameter blocks
    python robots/build_models.py --check    # exit 1 if a committed file is stale

The committed XML files are exactly this script's output (``tests/test_robot.py`` checks
it). Every number that sets a mass, a length, a spring, a gain, a damping, a limit, a sensor
or a contact parameter is an entry of the robot's provenance ledger
``robots/<name>/parameters.yaml`` (value, unit, class ``paper``/``source``/``assumed``/
``calibrated``, source), read by :func:`load_ledger`; this script and its builders
(``robots/builders/``: ``ledger.py`` reads the ledgers, ``core.py`` holds the shapes, bodies,
joints, drives, leg and arm every robot shares, ``mjcf.py`` writes the MJCF and solves the home
keyframe, and one module per robot draws it) hold only the structure (axes, joint names,
mirroring, formatting, collision bit masks) and what is derived (inertias from shapes, masses
that take what a total leaves, the home keyframe). ``tests/test_robot_ledger.py`` checks that
every entry is read and that no physical literal is left in them. Each robot's README has the ledger as a generated table.

What the script does for each robot:

1. It builds the robot as a tree of :class:`Body` objects drawn with primitive shapes.
2. It derives each body's ``<inertial>`` (mass, centre of mass, full inertia tensor) from
   the shapes, each shape being a uniform solid of a stated mass. Body masses are therefore
   exact, and inertias agree with the drawn geometry.
3. It compiles the model in MuJoCo and solves the ``home`` keyframe: the given knee bend,
   torso upright, feet flat, sole bottoms exactly at z = 0, the whole-body centre of mass
   above the midpoint of the two sole centres (so home is statically balanced), and the
   sole-centre midpoint at the world origin. For the series-elastic COMAN it also solves
   the spring pre-load and the servo targets that hold this posture in static equilibrium.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# The builders are a package beside this script, which runs as a file (not an installed module).
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from builders.coman import build_coman  # noqa: E402
from builders.coman_lab import build_coman_lab  # noqa: E402
from builders.core import per_joint  # noqa: E402
from builders.dyros_red import (  # noqa: E402
    build_dyros_actuated,
    build_dyros_actuated_9_9,
    build_dyros_armature,
    build_dyros_red,
    shg20_shd20,
)
from builders.kist_humanoid import build_kist  # noqa: E402
from builders.ledger import (  # noqa: E402
    README_BEGIN,
    README_END,
    ROBOTS_DIR,
    LedgerError,
    load_ledger,
    read_ledger_file,
    readme_text,
)
from builders.mjcf import generate  # noqa: E402

#: What tests and tools read from this script, besides BUILDERS and main.
__all__ = [
    "README_BEGIN",
    "README_END",
    "ROBOTS_DIR",
    "BUILDERS",
    "LedgerError",
    "generate",
    "load_ledger",
    "main",
    "per_joint",
    "read_ledger_file",
    "readme_text",
    "shg20_shd20",
]


BUILDERS = {
    "dyros_red": build_dyros_red,
    "dyros_red_actuated": build_dyros_actuated,
    "dyros_red_actuated_9_9": build_dyros_actuated_9_9,
    "dyros_red_armature": build_dyros_armature,
    "coman": build_coman,
    "coman_lab": build_coman_lab,
    "kist_humanoid": build_kist,
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check",
        action="store_true",
        help="only compare with the committed robot.xml files and README parameter blocks",
    )
    parser.add_argument(
        "--readme",
        action="store_true",
        help="only rewrite the README parameter blocks from the ledgers (no robot.xml)",
    )
    args = parser.parse_args(argv)
    stale = []
    for name, build in BUILDERS.items():
        path, text = readme_text(name)
        if args.check:
            if path.read_text() != text:
                stale.append(f"{name}/README.md")
        elif path.read_text() != text:
            path.write_text(text)
            print(f"wrote {path.relative_to(ROBOTS_DIR.parent)}")
        if args.readme:
            continue
        text = generate(build())
        path = ROBOTS_DIR / name / "robot.xml"
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(f"{name}/robot.xml")
        else:
            path.parent.mkdir(exist_ok=True)
            path.write_text(text)
            print(f"wrote {path.relative_to(ROBOTS_DIR.parent)}")
    if stale:
        print(f"stale (run python robots/build_models.py): {', '.join(stale)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
