"""`twolink train --init AGENT`: a run starts from a saved agent's policy (read as data),
names itself so, and refuses an agent of another algorithm, arm or base in one line,
exit 2, nothing written."""
from __future__ import annotations

import pytest

pytest.importorskip("stable_baselines3")

import torch  # noqa: E402

from twolink.cli import main  # noqa: E402
from twolink.control.learned import learned_agent_path  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import build, run_name, train  # noqa: E402

SMOKE = dict(algo="ppo", links=2, steps=256, envs=4, n_steps=32, eval_every=256)


def test_a_run_starts_from_the_agents_policy(tmp_path):
    first = train(TrainConfig(**SMOKE, seed=3), tmp_path / "first")
    agent = str(tmp_path / "first" / first["agent"])
    model, env = build(TrainConfig(**SMOKE, init=agent))
    plain, plain_env = build(TrainConfig(**SMOKE))
    try:
        from twolink.control.sb3_agent import SB3Agent

        want = SB3Agent(agent).policy.state_dict()
        got = model.policy.state_dict()
        assert all(torch.equal(got[k], want[k]) for k in want)
        other = plain.policy.state_dict()
        assert not all(torch.equal(other[k], want[k]) for k in want)
    finally:
        env.close()
        plain_env.close()
    assert run_name(TrainConfig(**SMOKE, init=agent)) == "ppo_2links_init_seed0"
    record = train(TrainConfig(**SMOKE, init=agent), tmp_path / "second")
    assert record["config"]["init"] == agent


@pytest.mark.parametrize("argv, message", [
    (["--links", "6", "--init", "AGENT6"], "its base is pd, this run's none"),
    (["--links", "6", "--base", "pd", "--algo", "sac", "--init", "AGENT6"],
     "its algorithm is ppo, this run's sac"),
    (["--init", "AGENT6"], "its links is 6, this run's 2"),
    (["--init", "missing.zip"], "does not exist"),
    (["--init", "agent.npz"], "init must be the path of a saved agent .zip"),
    (["--algo", "ippo", "--init", "AGENT6"], "--init does not apply to --algo ippo|mappo"),
])
def test_bad_init_is_one_line_exit_2_nothing_written(tmp_path, capsys, argv, message):
    six = str(learned_agent_path("ppo_pd_6link_tapered"))
    argv = [six if a == "AGENT6" else str(tmp_path / a) if a.endswith((".zip", ".npz"))
            else a for a in argv]
    out = tmp_path / "run"
    assert main(["train", *argv, "--steps", "128", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()
