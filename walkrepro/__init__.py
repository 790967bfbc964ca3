"""walkrepro: reproduce published biped-walking controllers in MuJoCo and check the result."""

import os

# A stop signal (Ctrl-C, SIGTERM) during the second of start-up below (MuJoCo, numba) is
# held, when this process is the walkrepro command, and handed to the run or the sweep, so
# even a stop that early leaves an interrupted run directory (interrupt.py; stdlib only).
from walkrepro.interrupt import hold_stop_signals_if_command

hold_stop_signals_if_command()

# No OpenGL backend is chosen at import: only rendering needs one, and walkrepro.gl picks it
# when something renders (the user's MUJOCO_GL if set, else EGL, else OSMesa). MuJoCo binds
# a backend on its first import and fails to import at all if that backend's library is
# missing (MUJOCO_GL=osmesa without libosmesa6), so it is first imported with GL disabled
# and the user's setting is put back for walkrepro.gl to honour.
_user_gl = os.environ.get("MUJOCO_GL")
os.environ["MUJOCO_GL"] = "disable"
try:
    import mujoco  # noqa: E402, F401
finally:
    if _user_gl is None:
        del os.environ["MUJOCO_GL"]
    else:
        os.environ["MUJOCO_GL"] = _user_gl

# A run is one simulation loop on one core, and its matrices are small (at most 60 x 60):
# there OpenBLAS's worker threads only add hand-offs (≈ 2.5 µs on Paper I's 12 x 12 eigh at
# 2 kHz), and `walkrepro check --jobs N` would oversubscribe the cores. It reads this when
# numpy loads it, so it is set before anything imports numpy; users may override it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

# numba's cache=True notices edits to a kernel's own file only; this points numba's cache at
# a directory keyed on every source the kernels import too (see numbacache.py). Before
# anything imports numba, which reads NUMBA_CACHE_DIR when it loads.
from walkrepro import numbacache  # noqa: E402

numbacache.install()

# Where the robots, experiments and references are, and where runs go: a checkout's own
# folders, or the installed package's shipped copies and ./results (see locations.py).
from walkrepro.locations import (  # noqa: E402, F401
    EXPERIMENTS_DIR,
    IS_CHECKOUT,
    PROJECT_ROOT,
    REFERENCES_DIR,
    RESULTS_DIR,
    ROBOTS_DIR,
)
