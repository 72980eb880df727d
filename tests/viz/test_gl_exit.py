"""A process that rendered and then goes on (torch, SB3) or simply exits: exit status 0
and no EGLError at exit, whether the environment was closed or not.

mujoco's ``Renderer.render`` leaves its EGL context current on the thread, and mujoco's
EGL module terminates the display in an ``atexit`` handler; a renderer freed after that
(at interpreter finalization) printed an ``EGLError`` and could crash. The renderer now
releases its context after every frame and closes itself at exit, before the display is
terminated (:func:`twolink.gl.release_current`, :func:`twolink.gl.close_at_exit`).
Each case runs in a fresh interpreter with ``MUJOCO_GL`` unset (EGL); skipped where EGL
cannot render.
"""
import importlib.util
import os
import subprocess
import sys
import textwrap

import pytest

_RENDER = textwrap.dedent('''
    import sys, threading
    import twolink
    from twolink.envs.gym import TwoLinkEnv

    args = sys.argv[1:]
    try:                          # at module level, as the report had it
        env = TwoLinkEnv(render_mode="rgb_array")
        env.reset(seed=0)
        if "thread" in args:
            t = threading.Thread(target=env.render); t.start(); t.join()
        else:
            frame = env.render()
    except Exception as exc:      # twolink.viz.render is not imported before the frame
        if type(exc).__name__ != "RenderError":
            raise
        print("NO-EGL", exc); sys.exit(0)
    if "current" in args:
        from mujoco.egl import egl_ext
        print("current after frame:", bool(egl_ext.eglGetCurrentContext()))
    if "torch" in args:
        import torch
        net = torch.nn.Sequential(torch.nn.Linear(4, 64), torch.nn.Tanh(), torch.nn.Linear(64, 2))
        opt = torch.optim.Adam(net.parameters(), lr=1e-3)
        for _ in range(5):
            loss = net(torch.randn(32, 4)).pow(2).sum()
            opt.zero_grad(); loss.backward(); opt.step()
        print("torch ok")
    if "close" in args:
        env.close()
    if "del" in args:
        del env
    print("done")
''')

CASES = [("plain",), ("close",), ("del",), ("thread",), ("torch",), ("torch", "close"),
         ("current",)]


def _run(tmp_path, *args):
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    script = tmp_path / "render_then_exit.py"
    script.write_text(_RENDER)
    return subprocess.run([sys.executable, str(script), *args], capture_output=True,
                          text=True, env=env, cwd=tmp_path, timeout=300)


@pytest.mark.parametrize("args", CASES, ids=["-".join(c) for c in CASES])
def test_rendering_then_exit_is_clean(tmp_path, args):
    if "torch" in args and importlib.util.find_spec("torch") is None:
        pytest.skip("torch is not installed (pip install 'twolink[rl]')")
    res = _run(tmp_path, *args)
    if res.stdout.startswith("NO-EGL"):
        pytest.skip(res.stdout.strip())
    assert res.returncode == 0, (res.returncode, res.stderr[-3000:])
    assert "EGLError" not in res.stderr and "Traceback" not in res.stderr, res.stderr[-3000:]
    lines = res.stdout.splitlines()
    assert lines[-1] == "done"
    if "current" in args:                 # no context left current on the thread
        assert lines[0] == "current after frame: False"
