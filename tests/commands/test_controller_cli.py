"""`--controller SPEC` on `twolink rollout` and `twolink render`: a user's file or module,
a baseline or a policy drives the same closed loop; refused specs end in one line, exit 2
and no file."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from twolink.cli import main
from twolink.control.controllers import resolve_controller
from twolink.sim.challenges import challenge
from twolink.sim.evaluation import challenged_rollouts
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.sim.trajectory_file import load_npz

X0 = [-1.0, -3.0, 0.0, 0.0]
USER = '''import numpy as np

K = np.array([[1.0, 0.0, 0.15, 0.0], [0.0, 2.0, 0.0, 0.05]])


def pd(x):
    return np.clip(-x @ K.T, [-1.5, -0.1], [1.5, 0.1])


def one_state(x):
    return np.zeros(2)


def nan(x):
    return np.full((len(x), 2), np.nan)


def boom(x):
    raise RuntimeError("sensor unplugged")


not_callable = 3
'''


@pytest.fixture
def user(tmp_path):
    path = tmp_path / "mine.py"
    path.write_text(USER)
    return path


def _cli(*argv, cwd=None, env=None):
    return subprocess.run([sys.executable, "-m", "twolink.cli", *map(str, argv)],
                          capture_output=True, text=True, cwd=cwd, timeout=120, check=False,
                          env=None if env is None else {**os.environ, **env})


@pytest.mark.slow
def test_rollout_runs_a_file_controller_and_a_baseline(user, tmp_path):
    """The file's pd and the lqr baseline run beside a shipped policy; the saved runs are
    the library rollout of the same controller from the same x0."""
    out = tmp_path / "runs"
    r = _cli("rollout", "--policy", "centralized", "--controller", f"{user}:pd",
             "--controller", "lqr", "--duration", 0.5, "--json", "-o", out)
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)
    assert [e["policy"] for e in rep["runs"]] == ["centralized", "pd", "lqr"]
    saved = load_npz(tmp_path / "runs.npz")
    for name, spec in (("pd", f"{user}:pd"), ("lqr", "lqr")):
        direct = rollout(resolve_controller(spec), make_plant("mujoco"), np.array([X0]),
                         duration=0.5)[0]
        np.testing.assert_array_equal(saved[(name, "mujoco")].x, direct.x)
        np.testing.assert_array_equal(saved[(name, "mujoco")].u, direct.u)
        (entry,) = [e for e in rep["runs"] if e["policy"] == name]
        assert entry["final_state"] == direct.x[-1].tolist()
    run = saved[("pd", "mujoco")]                      # the file's pd commanded every torque
    K = np.array([[1.0, 0.0, 0.15, 0.0], [0.0, 2.0, 0.0, 0.05]])
    np.testing.assert_allclose(run.u, np.clip(-run.x[:-1] @ K.T, [-1.5, -0.1], [1.5, 0.1]),
                               rtol=1e-12)


@pytest.mark.slow
def test_rollout_module_controller_under_a_challenge_compensated(user, tmp_path):
    """module:callable from PYTHONPATH; a baseline behind the compensator under medium is
    the closed loop of twolink.sim.evaluation, not the plain one."""
    r = _cli("rollout", "--controller", "mine:pd", "--controller", "lqr", "--challenge",
             "medium", "--compensate", "--seed", 3, "--duration", 0.5, "--json", "--no-save",
             cwd=tmp_path, env={"PYTHONPATH": str(tmp_path)})
    assert r.returncode == 2 and "pd names no model" in r.stderr     # pd has no meta model
    r = _cli("rollout", "--controller", "lqr", "--challenge", "medium", "--compensate",
             "--seed", 3, "--duration", 0.5, "--json", "--no-save")
    assert r.returncode == 0, r.stderr
    (entry,) = json.loads(r.stdout)["runs"]
    lqr = resolve_controller("lqr")
    want = challenged_rollouts({"lqr": lqr}, ["mujoco"], X0, challenge("medium"), seed=3,
                               compensate=True, duration=0.5)[("lqr", "mujoco")]
    plain = rollout(lqr, make_plant("mujoco"), np.array([X0]), duration=0.5)[0]
    assert entry["final_state"] == want.x[-1].tolist()
    assert entry["final_state"] != plain.x[-1].tolist()
    r = _cli("rollout", "--controller", "mine:pd", "--duration", 0.5, "--json", "--no-save",
             cwd=tmp_path, env={"PYTHONPATH": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    assert [e["policy"] for e in json.loads(r.stdout)["runs"]] == ["pd"]


@pytest.mark.parametrize("spec, message", [
    ("{user}:one_state", "returned torques of shape (2,) for states of shape (1, 4)"),
    ("{user}:nan", "controller nan returned NaN or infinite torques"),
    ("{user}:boom", "controller boom raised RuntimeError: sensor unplugged"),
    ("{user}:not_callable", "is not callable"),
    ("{user}:missing", "has no attribute 'missing'"),
    ("{tmp}/none.py:pd", "does not exist"),
    ("no_such_module_xyz:pd", "cannot import controller module 'no_such_module_xyz'"),
    ("nope", "unknown controller 'nope'"),
])
@pytest.mark.parametrize("command", ["rollout", "render"])
def test_refused_specs_one_line_exit_2_no_file(command, spec, message, user, tmp_path,
                                               capsys):
    spec = spec.replace("{user}", str(user)).replace("{tmp}", str(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    argv = [command, "--controller", spec, "--duration", "0.3",
            "-o" if command == "render" else "--prefix",
            str(out / ("v.gif" if command == "render" else "run"))]
    code = main(argv + (["--size", "64x48", "--no-progress"] if command == "render" else []))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err
    assert err.startswith(f"twolink {command}: error: ")
    assert list(out.iterdir()) == []


def test_refused_spec_from_the_shell(user, tmp_path):
    r = _cli("rollout", "--controller", f"{user}:one_state", "--duration", 0.3, "--prefix",
             tmp_path / "run")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "per_state" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.py"]


def test_render_a_file_controller_beside_a_baseline(user, tmp_path):
    from twolink.viz.video import read_video

    out = tmp_path / "pair.gif"
    r = _cli("render", "--controller", f"{user}:pd", "--controller", "lqr", "--duration",
             0.3, "--fps", 10, "--size", "64x48", "--no-ghost", "--no-progress", "--json",
             "-o", out)
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["policies"] == ["pd", "lqr"] and rep["width"] == 128
    video = read_video(out)
    assert video.shape == (4, 48, 128, 3)
    left, right = video[-1, :, :64].astype(int), video[-1, :, 64:].astype(int)
    assert np.abs(left - right).sum() > 0            # two controllers, two arms


@pytest.mark.parametrize("argv, message", [
    (["--policy", "centralized", "--controller", "lqr", "--controller", "pd"],
     "one or two --policy or --controller values"),
    (["--controller", "lqr", "--controller", "lqr"], "name the same policy 'lqr'"),
])
def test_render_takes_at_most_two(argv, message, tmp_path, capsys):
    code = main(["render", *argv, "--duration", "0.2", "-o", str(tmp_path / "v.mp4")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []
