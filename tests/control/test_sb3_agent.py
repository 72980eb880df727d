"""A saved Stable-Baselines3 agent as a controller: the torques of the cos/sin features'
deterministic action, one-line refusals of other zips and its leaderboard rows (plain
only); the safe loading itself is in test_sb3_safe_load.py. Skipped where SB3 is not
installed."""
from __future__ import annotations

import json
import sys
import zipfile

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3")

from twolink.arm.observations import features  # noqa: E402
from twolink.arm.parameters import TABLE_I  # noqa: E402
from twolink.cli import main  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.learned import default_learned_agents  # noqa: E402
from twolink.control.sb3_agent import sb3_algorithm  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """An untrained, seeded PPO on the training environment's options, saved; (model, path)."""
    import torch

    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    torch.set_num_threads(1)
    env = TwoLinkSB3VecEnv(2, observation="cos_sin", actions="normalized", reward="shaped",
                           x0="random")
    model = sb3.PPO("MlpPolicy", env, seed=7, device="cpu", n_steps=8, batch_size=16,
                    policy_kwargs={"net_arch": [16]})
    path = tmp_path_factory.mktemp("agents") / "tiny_ppo.zip"
    model.save(path)
    env.close()
    return model, path


def test_the_agent_gives_the_clipped_scaled_deterministic_action(tiny):
    model, path = tiny
    agent = resolve_controller(str(path))
    x = evaluation_set()[:20]
    u = agent(x)
    action, _ = model.predict(features(x, "cos_sin"), deterministic=True)
    assert u.shape == (20, 2)
    assert np.all(np.abs(u) <= TABLE_I.tau_max)
    np.testing.assert_allclose(u, np.clip(action, -1, 1) * TABLE_I.tau_max, rtol=0, atol=1e-12)
    assert np.ptp(u, axis=0).min() > 0           # the torques depend on the state
    assert agent.name == "tiny_ppo"
    meta = agent.meta
    assert (meta["algo"], meta["seed"], meta["steps"], meta["observation"]) == \
        ("ppo", 7, 0, "cos_sin")
    assert "model" not in meta                  # no model named: no compensated rows


def test_other_zips_are_refused_in_one_line(tmp_path, tiny):
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(other, "w") as z:
        z.writestr("readme.txt", "not an agent")
    with pytest.raises(ControllerError, match="is not a Stable-Baselines3 save") as e:
        resolve_controller(str(other))
    assert "\n" not in str(e.value)
    (tmp_path / "text.zip").write_text("hello")
    with pytest.raises(ControllerError, match="is not a zip file"):
        resolve_controller(str(tmp_path / "text.zip"))
    # An SB3 save of another algorithm: its data lacks PPO's and SAC's attributes.
    td3 = tmp_path / "td3.zip"
    with zipfile.ZipFile(tiny[1]) as src, zipfile.ZipFile(td3, "w") as z:
        data = json.loads(src.read("data"))
        for key in ("n_epochs", "clip_range", "gae_lambda"):
            data.pop(key)
        z.writestr("data", json.dumps(data))
        z.writestr("policy.pth", src.read("policy.pth"))
    with pytest.raises(ControllerError, match="of neither PPO nor SAC"):
        sb3_algorithm(td3)
    assert sb3_algorithm(tiny[1]) == "ppo"


def test_without_sb3_one_line_says_what_to_install(tiny, monkeypatch):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)     # import fails
    with pytest.raises(ControllerError) as e:
        resolve_controller(str(tiny[1]))
    assert str(e.value) == ("controller tiny_ppo.zip needs the rl extras: "
                            "pip install 'twolink[rl]'")
    assert default_learned_agents() == []          # the default list: silently none


def test_the_leaderboard_gives_the_agent_plain_rows_only(tiny, tmp_path, capsys):
    out = tmp_path / "lb"
    assert main(["leaderboard", "--quick", "--only", "--controller", str(tiny[1]), "--levels",
                 "none", "medium", "--plants", "2", "--out", str(out)]) == 0
    capsys.readouterr()
    rows = json.loads((out / "leaderboard.json").read_text())["rows"]
    assert [(r["controller"], r["level"], r["mode"]) for r in rows] == [
        ("tiny_ppo", "none", "plain"), ("tiny_ppo", "medium", "plain")]
    assert all(r["n"] > 0 and r["mean_abs_torque"] > 0 for r in rows)

