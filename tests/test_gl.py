"""Rendering is optional: importing walkrepro picks no GL backend, and rendering picks one or explains."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from walkrepro.cli import app
from walkrepro.runtime import gl


def test_import_chooses_no_backend() -> None:
    """Importing walkrepro (and its CLI) sets no MUJOCO_GL and imports no OpenGL."""
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    code = (
        "import os, sys, walkrepro.cli, walkrepro.evaluation.metrics, walkrepro.runs.runner\n"
        "assert 'MUJOCO_GL' not in os.environ, os.environ['MUJOCO_GL']\n"
        "assert not any(m == 'OpenGL' or m.startswith('OpenGL.') for m in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_a_broken_user_backend_does_not_stop_walkrepro() -> None:
    """With MUJOCO_GL naming a backend whose library is missing, walkrepro still starts."""
    env = {**os.environ, "MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": ""}
    env.pop("PYOPENGL_PLATFORM")
    done = subprocess.run(
        [sys.executable, "-m", "walkrepro", "--version"], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0 and "walkrepro" in done.stdout, done.stderr


def test_no_backend_gives_one_paragraph_and_exit_2(
    monkeypatch: pytest.MonkeyPatch, tmp_path: object
) -> None:
    """When no backend works, render fails with what to install and exit code 2, no traceback."""
    from typer.testing import CliRunner

    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "probe", lambda backend: (False, f"no {backend} here"))
    gl.gl_context_class.cache_clear()
    try:
        with pytest.raises(gl.RenderingUnavailable, match="libosmesa6"):
            gl.gl_context_class()
        assert not gl.available()
        log = _tiny_log(tmp_path)
        result = CliRunner().invoke(app, ["render", str(log), "--at", "0"])
    finally:
        gl.gl_context_class.cache_clear()
    assert result.exit_code == 2, result.output
    assert "egl: no egl here; osmesa: no osmesa here" in result.output
    assert "Traceback" not in result.output


def test_user_choice_is_the_only_candidate(monkeypatch: pytest.MonkeyPatch) -> None:
    """MUJOCO_GL, when set, is the one backend tried (no silent fallback to another)."""
    tried: list[str] = []
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.setattr(gl, "probe", lambda backend: (tried.append(backend), (False, "x"))[1])
    gl.gl_context_class.cache_clear()
    try:
        assert not gl.available()
    finally:
        gl.gl_context_class.cache_clear()
    assert tried == ["osmesa"]


@pytest.mark.skipif(not gl.available(), reason=gl.INSTALL_HINT.format(tried="probed at collection"))
def test_render_writes_a_strip_on_this_machine(tmp_path: object) -> None:
    """Where a backend exists, render writes a PNG strip of the logged states."""
    from typer.testing import CliRunner

    log = _tiny_log(tmp_path)
    png = log.parent / "strip.png"
    result = CliRunner().invoke(app, ["render", str(log), "--at", "0,0.1", "--out", str(png)])
    assert result.exit_code == 0, result.output
    assert png.stat().st_size > 1000


def _tiny_log(tmp_path: object):  # noqa: ANN202 - Path
    from pathlib import Path

    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.runs.runner import run
    from walkrepro.specs.files import load_spec

    spec = resolve_spec(load_spec("stand_dyros_red", ["sim.duration=0.1"])).spec
    path = Path(str(tmp_path)) / "log.mcap"
    run(spec, path)
    return path
