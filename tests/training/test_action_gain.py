"""``twolink train --action-gain G``: the arms get clip(G a, -1, 1) tau_max, the wrappers
above the gain see the agent's own action, the agent file records G and its loader
applies it, the run is named and checkpointed with it, and bad gains are one line."""
from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from twolink.control.action_gain import check_action_gain, gained
from twolink.sim.controller import ControllerError


def test_gained_clips_the_action_then_the_gained_action():
    a = np.array([[0.5, -0.9], [2.0, -0.2]])
    np.testing.assert_array_equal(gained(a, 1.0), [[0.5, -0.9], [1.0, -0.2]])
    np.testing.assert_allclose(gained(a, 1.3), [[0.65, -1.0], [1.0, -0.26]])
    assert gained(a, 1.3).dtype == np.float64


@pytest.mark.parametrize("bad", [0.5, 0.0, 10.5, float("nan"), float("inf"), "1.3", True,
                                 None])
def test_a_gain_is_a_number_from_1_to_10(bad):
    with pytest.raises(ValueError, match="action_gain must be a number in \\[1, 10\\]"):
        check_action_gain(bad)
    assert check_action_gain(1) == 1.0 and check_action_gain(10) == 10.0


sb3 = pytest.importorskip("stable_baselines3")

from twolink.cli import main  # noqa: E402
from twolink.control.agent_meta import AGENT_MEMBER  # noqa: E402
from twolink.control.sb3_agent import SB3Agent  # noqa: E402
from twolink.envs.action_gain import ActionGainVecEnv  # noqa: E402
from twolink.envs.sb3 import TwoLinkSB3VecEnv  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import build, run_name, train  # noqa: E402


def _err(capsys, argv) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    return err


def _arms(**options):
    return TwoLinkSB3VecEnv(2, actions="normalized", observation="cos_sin", reward="shaped",
                            x0="random", **options)


def test_the_arms_get_the_gained_action():
    plain, wrapped = _arms(), ActionGainVecEnv(_arms(), 1.3)
    plain.seed(7)
    wrapped.seed(7)
    np.testing.assert_array_equal(plain.reset(), wrapped.reset())
    a = np.array([[0.5, -0.9], [0.1, 0.8]], np.float32)
    o_plain, r_plain, _, _ = plain.step(gained(a, 1.3))
    o_wrapped, r_wrapped, _, _ = wrapped.step(a)
    np.testing.assert_array_equal(o_plain, o_wrapped)
    np.testing.assert_array_equal(r_plain, r_wrapped)
    moved = _arms()
    moved.seed(7)
    moved.reset()
    assert not np.array_equal(moved.step(a)[0], o_wrapped)     # the gain changed the step
    for env in (plain, wrapped, moved):
        env.close()


def test_the_gain_needs_normalized_actions():
    env = TwoLinkSB3VecEnv(2, actions="box")
    with pytest.raises(ValueError, match="an action gain needs the arms' normalized actions"):
        ActionGainVecEnv(env, 1.3)
    env.close()


def test_history_and_action_rate_see_the_agent_s_own_action():
    config = TrainConfig(algo="sac", steps=64, envs=2, history=2, action_rate=1.0,
                         action_gain=2.0)
    model, env = build(config)
    env.reset()
    a = np.array([[0.3, -0.6], [0.9, 0.0]], np.float32)
    obs, _, _, _ = env.step(a)
    # The history's newest action is the agent's a, not the gained 2a.
    np.testing.assert_allclose(obs[:, -2:], a, rtol=1e-6)
    rate = env.venv                                     # the action-rate wrapper
    np.testing.assert_allclose(rate.last, a, rtol=1e-6)
    assert isinstance(rate.venv, ActionGainVecEnv)
    env.close()


@pytest.fixture(scope="module")
def gained_run(tmp_path_factory):
    """(folder, record) of a short SAC run with the gain 1.5."""
    run = tmp_path_factory.mktemp("gain") / "run"
    config = TrainConfig(algo="sac", steps=64, envs=2, eval_every=64, action_gain=1.5)
    assert run_name(config) == "sac_2links_ag1.5_seed0"
    return run, train(config, run)


def test_the_agent_records_and_applies_its_gain(gained_run, tmp_path, capsys):
    assert run_name(TrainConfig(algo="sac")) == "sac_2links_seed0"
    run, record = gained_run
    assert record["config"]["action_gain"] == 1.5
    path = run / record["agent"]
    with zipfile.ZipFile(path) as z:
        assert json.loads(z.read(AGENT_MEMBER))["action_gain"] == 1.5
    agent = SB3Agent(path)
    assert agent.meta["action_gain"] == 1.5
    x = np.array([[0.3, -1.0, 0.5, 0.0], [-2.0, 1.0, 0.0, -1.0], [1.0, 2.0, 0.1, 0.2]])
    from twolink.arm.observations import features

    raw, _ = agent.policy.predict(features(x, "cos_sin"), deterministic=True)
    np.testing.assert_allclose(agent(x), gained(raw, 1.5) * agent.tau_max)
    # A resume with another gain is refused.
    copy = tmp_path / "copy"
    copy.mkdir()
    (copy / "checkpoint.pt").write_bytes((run / "checkpoint.pt").read_bytes())
    assert "checkpoint of a run with action_gain 1.5, not 1.0" in _err(
        capsys, ["train", "--resume", "--action-gain", "1", "--steps", "128",
                 "--out", str(copy)])


@pytest.mark.parametrize("value", ["0.5", '"x"', "null", "20"])
def test_a_bad_recorded_gain_is_one_line(gained_run, tmp_path, value):
    run, record = gained_run
    src = run / record["agent"]
    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == AGENT_MEMBER:
                data = data.replace(b'"action_gain": 1.5', b'"action_gain": ' + value.encode())
            zout.writestr(item, data)
    with pytest.raises(ControllerError, match="its twolink.json says action_gain .*; a gain "
                                              "is a number from 1 to 10"):
        SB3Agent(bad)


def test_bad_gains_are_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    for value in ("0.5", "11", "nan", "x"):
        assert "--action-gain must be a number from 1 to 10" in _err(
            capsys, ["train", "--action-gain", value, "--out", str(out)])
    assert "--action-gain does not apply to --algo ippo|mappo" in _err(
        capsys, ["train", "--algo", "mappo", "--action-gain", "1.3", "--out", str(out)])
    assert not out.exists()


def test_a_warm_start_keeps_the_gain(gained_run, tmp_path, capsys):
    run, record = gained_run
    agent = str(run / record["agent"])
    assert f"--init {agent}: its action gain is 1.5, this run's 1.0" in _err(
        capsys, ["train", "--algo", "sac", "--init", agent, "--steps", "64",
                 "--out", str(tmp_path / "warm")])
    assert not (tmp_path / "warm").exists()
    config = TrainConfig(algo="sac", steps=64, envs=2, init=agent, action_gain=1.5)
    model, env = build(config)                  # the same gain: warm-started
    env.close()


def test_a_residual_gets_the_gained_action():
    from twolink.control.residual import base_controller, residual_torques
    from twolink.training.run import arm_of

    config = TrainConfig(algo="ppo", links=3, steps=64, envs=2, n_steps=32, base="pd",
                         action_gain=2.0)
    model, env = build(config)
    env.reset()
    arms = env
    while hasattr(arms, "venv"):
        arms = arms.venv
    live = arms._live()
    sent = []
    torques = live.torques
    live.torques = lambda action, **kw: sent.append(torques(action, **kw)) or sent[-1]
    x = arms.states
    a = np.array([[0.3, -0.2, 0.05], [-0.45, 0.1, 0.2]], np.float32)
    want = residual_torques(base_controller("pd", arm_of(config)), x, gained(a, 2.0),
                            live.params.tau_max)
    env.step(a)
    np.testing.assert_allclose(sent[0], want, rtol=1e-12)
    plain = residual_torques(base_controller("pd", arm_of(config)), x, a, live.params.tau_max)
    assert not np.allclose(sent[0], plain)                 # the gain made a difference
    env.close()
