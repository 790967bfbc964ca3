"""walkrepro: reproduce published biped-walking controllers in MuJoCo and check the result."""

import os
from pathlib import Path

# MuJoCo picks its OpenGL backend when it is first imported. walkrepro renders headless,
# so without a display default to OSMesa (software); users may set MUJOCO_GL=egl.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "osmesa"

__version__ = "0.1.0"

#: Repository root when run from a checkout (robots/, experiments/ live there).
PROJECT_ROOT = Path(__file__).resolve().parent.parent
ROBOTS_DIR = PROJECT_ROOT / "robots"
EXPERIMENTS_DIR = PROJECT_ROOT / "experiments"
RESULTS_DIR = PROJECT_ROOT / "results"
