"""Choosing an OpenGL backend for headless rendering, only when something renders.

Importing walkrepro never selects a GL backend: physics, logs, metrics, checks and figures
need none, so they work on any machine. Rendering (``walkrepro render``, the snapshot strips
of ``check --update-reference``) asks :func:`gl_context_class` for a backend:

1. the user's ``MUJOCO_GL``, if set (``egl``, ``osmesa``, or ``glfw``/``glx`` with a display);
2. else EGL (Mesa's ``libegl-mesa0``, or a GPU driver's EGL);
3. else OSMesa (``libosmesa6``, software).

Each candidate is first tried in a short child process, because PyOpenGL binds its platform
once per process, at its first import: a failed attempt here would leave this process unable
to use the next candidate. If none works, :class:`RenderingUnavailable` says what to install.
"""

from __future__ import annotations

import functools
import importlib
import os
import subprocess
import sys

from walkrepro.errors import WalkreproError

#: Headless backends tried in order when ``MUJOCO_GL`` is unset (MuJoCo's names).
HEADLESS_BACKENDS = ("egl", "osmesa")
#: How long a child process may take to create a 1 x 1 context [s].
PROBE_TIMEOUT = 60.0

INSTALL_HINT = (
    "Rendering needs an OpenGL backend, and none works on this machine ({tried}). On a "
    "headless Debian/Ubuntu machine install Mesa's EGL (apt-get install libegl1 libegl-mesa0 "
    "libgl1-mesa-dri) or OSMesa (apt-get install libosmesa6), or run with a display; "
    "MUJOCO_GL=egl|osmesa|glfw forces one. Everything else in walkrepro works without it."
)


class RenderingUnavailable(WalkreproError):
    """No OpenGL backend can create a context here (exit code 2, one paragraph)."""


_PROBE = """
import os, sys
name = sys.argv[1]
if name in ("egl", "osmesa"):
    os.environ["PYOPENGL_PLATFORM"] = name
module = name if name in ("egl", "osmesa", "cgl") else "glfw"
os.environ["MUJOCO_GL"] = "disable"
import importlib
context = importlib.import_module("mujoco." + module).GLContext(1, 1)
context.make_current()
context.free()
"""


def probe(backend: str) -> tuple[bool, str]:
    """Whether ``backend`` can create a GL context, tried in a child process.

    Returns:
        ``(works, the child's last error line or "")``.
    """
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE, backend],
            env=env,
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, str(exc)
    lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
    return done.returncode == 0, lines[-1] if lines else ""


@functools.cache
def gl_context_class() -> type:
    """The ``GLContext`` class of the first working backend (see the module docstring).

    Raises:
        RenderingUnavailable: if no candidate backend works.
    """
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    candidates = (requested,) if requested else HEADLESS_BACKENDS
    tried = []
    for name in candidates:
        works, error = probe(name)
        if works:
            return _context_class(name)
        tried.append(f"{name}: {error or 'failed'}")
    raise RenderingUnavailable(INSTALL_HINT.format(tried="; ".join(tried)))


def available() -> bool:
    """Whether some backend renders here (for skipping rendering tests)."""
    try:
        gl_context_class()
    except RenderingUnavailable:
        return False
    return True


def import_mujoco() -> None:
    """Import MuJoCo with no OpenGL backend bound, whatever ``MUJOCO_GL`` says.

    MuJoCo binds a backend on its first import and fails to import at all if that backend's
    library is missing (``MUJOCO_GL=osmesa`` without libosmesa6), though physics needs no
    GL. So it is first imported with GL disabled, and the user's setting is put back for
    :func:`gl_context_class` to honour; the environment is as it was. Called by the
    command's set-up and by :func:`walkrepro.load`; a no-op once MuJoCo is imported.
    """
    if "mujoco" in sys.modules:
        return
    user = os.environ.get("MUJOCO_GL")
    os.environ["MUJOCO_GL"] = "disable"
    try:
        import mujoco  # noqa: F401
    finally:
        if user is None:
            del os.environ["MUJOCO_GL"]
        else:
            os.environ["MUJOCO_GL"] = user


def _context_class(name: str) -> type:
    """Import a backend's ``GLContext`` in this process (after its probe succeeded).

    MuJoCo's own names: ``egl`` and ``osmesa`` are headless; ``cgl`` is macOS; anything else
    (``glfw``, ``glx``, ``1``...) is GLFW with a display, as MuJoCo itself maps them.
    """
    if name in HEADLESS_BACKENDS:
        os.environ.setdefault("PYOPENGL_PLATFORM", name)
    module = name if name in (*HEADLESS_BACKENDS, "cgl") else "glfw"
    return importlib.import_module(f"mujoco.{module}").GLContext
