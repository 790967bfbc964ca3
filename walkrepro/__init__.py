"""walkrepro: reproduce published biped-walking controllers in MuJoCo and check the result."""

import os
from pathlib import Path

# MuJoCo picks its OpenGL backend when it is first imported. walkrepro renders headless,
# so without a display default to OSMesa (software); users may set MUJOCO_GL=egl.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "osmesa"

# A run is one simulation loop on one core, and its matrices are small (at most 60 x 60):
# there OpenBLAS's worker threads only add hand-offs (≈ 2.5 µs on Paper I's 12 x 12 eigh at
# 2 kHz), and `walkrepro check --jobs N` would oversubscribe the cores. It reads this when
# numpy loads it, so it is set before anything imports numpy; users may override it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

# numba's cache=True notices edits to a kernel's own file only; this keys every walkrepro
# kernel's cache on the sources it imports too (see numbacache.py). Before any kernel exists.
from walkrepro import numbacache  # noqa: E402

numbacache.install()

#: Repository root when run from a checkout (robots/, experiments/ live there).
PROJECT_ROOT = Path(__file__).resolve().parent.parent
ROBOTS_DIR = PROJECT_ROOT / "robots"
EXPERIMENTS_DIR = PROJECT_ROOT / "experiments"
RESULTS_DIR = PROJECT_ROOT / "results"
