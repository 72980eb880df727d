"""The line that says why headless rendering is impossible names the chosen backend's
missing piece: OSMesa's library, GLFW's display, or a MUJOCO_GL MuJoCo does not know."""
import ctypes
import subprocess
import sys
from pathlib import Path

import pytest

from twolink.gl import diagnose


def _has(lib: str) -> bool:
    try:
        ctypes.CDLL(lib)
        return True
    except OSError:
        return False


def test_an_unknown_backend_is_named_with_the_known_ones(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "glx")
    line = diagnose()
    assert "MUJOCO_GL='glx' is not a rendering backend" in line
    assert "egl" in line and "osmesa" in line and "glfw" in line


@pytest.mark.skipif(_has("libOSMesa.so.8") or _has("libOSMesa.so"),
                    reason="libOSMesa is installed here")
def test_osmesa_without_its_library_says_so(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    line = diagnose()
    assert "needs libOSMesa, which is not installed" in line and "libosmesa6" in line
    assert "needs MUJOCO_GL=egl" not in line


def test_glfw_without_a_display_says_so(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert "MUJOCO_GL=glfw needs a display (DISPLAY is not set)" in diagnose()


def test_render_with_glfw_and_no_display_is_one_line(tmp_path):
    """The command says so in one line, before GLFW prints its own X11 warnings."""
    env = {"MUJOCO_GL": "glfw", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    res = subprocess.run([str(Path(sys.executable).parent / "twolink"), "render", "--duration", "0.2",
                          "--size", "64x48", "-o", str(tmp_path / "a.mp4")],
                         capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        "twolink render: error: headless rendering is unavailable: MUJOCO_GL=glfw needs a "
        "display (DISPLAY is not set); unset MUJOCO_GL to render headless with EGL"]
    assert list(tmp_path.iterdir()) == []
