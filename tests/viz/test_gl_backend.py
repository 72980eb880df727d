"""The GL backend is chosen when a renderer is made: without libEGL, or with a MUJOCO_GL
mujoco doesn't know, every command but rendering works, and rendering fails in one line.

libEGL is hidden from a child Python by a ``sitecustomize`` that makes ``ctypes.CDLL``
(through which PyOpenGL, mujoco and :func:`twolink.viz.render.diagnose` all load it) refuse
any ``libEGL*`` name, as the dynamic loader does on a machine without libegl1.
"""
import os
import subprocess
import sys
import textwrap

import pytest

_HIDE_EGL = textwrap.dedent('''
    import ctypes
    _init = ctypes.CDLL.__init__
    def _no_egl(self, name, *args, **kwargs):
        if name and str(name).rsplit("/", 1)[-1].startswith("libEGL"):
            raise OSError(f"{name}: cannot open shared object file: No such file or directory")
        _init(self, name, *args, **kwargs)
    ctypes.CDLL.__init__ = _no_egl
''')


def _env(tmp_path, *, hide_egl=False, **variables):
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "PYTHONPATH")}
    if hide_egl:
        site = tmp_path / "site"
        site.mkdir(exist_ok=True)
        (site / "sitecustomize.py").write_text(_HIDE_EGL)
        env["PYTHONPATH"] = str(site)
    env.update(variables)
    return env


def _python(tmp_path, code, **env):
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=_env(tmp_path, **env), cwd=tmp_path)


def _twolink(tmp_path, *argv, **env):
    return subprocess.run([sys.executable, "-m", "twolink.cli", *argv], capture_output=True,
                          text=True, env=_env(tmp_path, **env), cwd=tmp_path)


NO_EGL = {"hide_egl": True}
BOGUS = {"MUJOCO_GL": "bogus"}
BROKEN = pytest.mark.parametrize("broken", [NO_EGL, BOGUS, dict(NO_EGL, MUJOCO_GL="egl")],
                                 ids=["no-libEGL", "MUJOCO_GL=bogus", "MUJOCO_GL=egl,no-libEGL"])


def test_the_hidden_libegl_is_really_missing(tmp_path):
    res = _python(tmp_path, "import ctypes; ctypes.CDLL('libEGL.so.1')", **NO_EGL)
    assert res.returncode != 0 and "libEGL.so.1: cannot open shared object" in res.stderr
    res = _python(tmp_path, "import ctypes; ctypes.CDLL('libEGL.so.1')")
    assert res.returncode == 0, res.stderr


@BROKEN
@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["synthesize", "--help"]])
def test_commands_load_without_a_gl_backend(tmp_path, broken, argv):
    res = _twolink(tmp_path, *argv, **broken)
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""
    assert ("twolink 0.1.0" if argv == ["--version"] else "usage: twolink") in res.stdout


@BROKEN
def test_non_rendering_commands_run_without_a_gl_backend(tmp_path, broken):
    res = _twolink(tmp_path, "mjcf", "-o", "arm.xml", **broken)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "arm.xml").read_text().lstrip().startswith("<mujoco")
    res = _twolink(tmp_path, "rollout", "--policy", "centralized", "--no-save", **broken)
    assert res.returncode == 0, res.stderr


@pytest.mark.parametrize("broken, named", [
    (NO_EGL, "libEGL.so.1 is missing"),
    (BOGUS, "MUJOCO_GL='bogus' is not a rendering backend"),
])
def test_rendering_fails_in_one_line_naming_the_cause(tmp_path, broken, named):
    res = _twolink(tmp_path, "render", "--duration", "0.1", "--size", "64x48", "-o", "v.mp4",
                   **broken)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1, res.stderr
    assert res.stderr.startswith("twolink render: error: headless rendering is unavailable: ")
    assert named in res.stderr
    assert not (tmp_path / "v.mp4").exists()


def test_importing_loads_no_gl_library_and_keeps_mujoco_gl(tmp_path):
    code = ("import os, sys, twolink.cli, twolink.viz.render\n"
            "print(os.environ.get('MUJOCO_GL'), any(m.startswith('OpenGL') for m in sys.modules))")
    assert _python(tmp_path, code).stdout.split() == ["None", "False"]
    assert _python(tmp_path, code, MUJOCO_GL="osmesa").stdout.split() == ["osmesa", "False"]


def test_a_renderer_binds_egl_when_it_is_made(tmp_path):
    code = ("import twolink.viz.render as r, mujoco\n"
            "before = mujoco.GLContext.__module__\n"
            "with r.Renderer(width=64, height=48) as ren: frame = ren.frame([0, 0, 0, 0])\n"
            "print(before, r.gl_backend(), mujoco.GLContext.__module__, frame.shape)")
    res = _python(tmp_path, code)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["twolink.gl", "egl", "mujoco.egl", "(48,", "64,", "3)"]


def test_the_environment_loads_without_libegl_and_fails_to_render_in_one_line(tmp_path):
    pytest.importorskip("dm_control")
    code = ("import twolink.envs.dm, twolink.viz.render as r\n"
            "env = twolink.envs.dm.load('centralized'); env.reset(); env.step([0.0, 0.0])\n"
            "try:\n"
            "    env.physics.render(height=48, width=64, camera_id='top')\n"
            "except r.RenderError as exc:\n"
            "    print(exc)\n")
    res = _python(tmp_path, code, **NO_EGL)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == [
        "headless rendering is unavailable: libEGL.so.1 is missing (run "
        "scripts/install-system-deps.sh as root, or apt-get install libegl1)"]


def test_mujoco_renderer_made_directly_after_import_twolink_binds_egl(tmp_path):
    code = ("import twolink, mujoco\n"
            "model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\".1\"/>"
            "</worldbody></mujoco>')\n"
            "try:\n"
            "    with mujoco.Renderer(model, 48, 64) as r:\n"
            "        print(r.render().shape, mujoco.GLContext.__module__)\n"
            "except RuntimeError as exc:\n"
            "    print(type(exc).__name__, exc)\n")
    res = _python(tmp_path, code)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["(48,", "64,", "3)", "mujoco.egl"]
    res = _python(tmp_path, code, **NO_EGL)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("RenderError headless rendering is unavailable: "
                                 "libEGL.so.1 is missing")
