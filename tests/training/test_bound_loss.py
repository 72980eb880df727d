"""`twolink train --algo ippo|mappo --bound-loss C`: the update's gradient is that of the
PPO loss plus C * mean(max(|mu| - 1, 0)^2) of the policy's means; acting is untouched; the
coefficient names the run, is part of its identity, resumes bit for bit, and bad values
or another algorithm are one line with exit 2 and nothing written."""
from __future__ import annotations

import json

import pytest

from twolink.cli import main
from twolink.training.bound_loss import BOUND, bounded, penalty
from twolink.training.marl import MarlConfig, run_name

torch = pytest.importorskip("torch")


def test_the_gradient_is_that_of_the_loss_plus_the_penalty():
    mu = torch.tensor([[-2.5], [-0.3], [0.9], [1.0], [1.7], [4.0]], requires_grad=True)
    upstream = torch.tensor([[0.2], [-1.0], [0.5], [0.1], [-0.4], [0.3]])
    (bounded(mu, 3.0) * upstream).sum().backward()
    injected = mu.grad.clone()
    ref = mu.detach().clone().requires_grad_(True)
    ((ref * upstream).sum() + penalty(ref, 3.0)).backward()
    assert torch.allclose(injected, ref.grad)
    # inside the bound only the PPO loss's gradient arrives; beyond it the penalty's adds
    assert torch.equal(injected[1:4], upstream[1:4])
    assert injected[5, 0] == pytest.approx(0.3 + 2 * 3.0 * (4.0 - BOUND) / 6)
    assert injected[0, 0] == pytest.approx(0.2 - 2 * 3.0 * (2.5 - BOUND) / 6)


def test_forward_values_and_acting_are_untouched():
    mu = torch.tensor([[3.0], [-0.5]], requires_grad=True)
    assert torch.equal(bounded(mu, 2.0), mu)
    assert bounded(mu, 0.0) is mu                       # no bound loss: the tensor itself
    with torch.no_grad():
        assert bounded(mu, 2.0) is mu                   # acting records no gradient
    assert float(penalty(mu.detach(), 2.0)) == pytest.approx(2.0 * (3.0 - BOUND) ** 2 / 2)


def test_the_skrl_policy_carries_the_penalty_into_its_update():
    pytest.importorskip("skrl")
    from gymnasium import spaces

    from twolink.training.marl_state import _models

    box, act = spaces.Box(-1.0, 1.0, (3,)), spaces.Box(-1.0, 1.0, (1,))
    grads = {}
    for coef in (0.0, 5.0):
        torch.manual_seed(0)
        Policy, _ = _models(torch, [8], "Tanh", 0.0, -20.0, coef)
        policy = Policy(box, act, "cpu")
        with torch.no_grad():
            policy.net[-1].bias.fill_(3.0)              # every mean beyond the bound
        obs = torch.linspace(-1, 1, 12).reshape(4, 3)
        _, out = policy.act({"observations": obs, "taken_actions": torch.ones(4, 1)})
        (-out["log_prob"].mean()).backward()
        grads[coef] = policy.net[-1].bias.grad.clone()
    mean = 3.0 + 0.0                                    # the bias dominates the small layer
    assert grads[5.0] > grads[0.0]                      # the penalty pushes the mean down
    assert float(grads[5.0] - grads[0.0]) == pytest.approx(2 * 5.0 * (mean - BOUND),
                                                            rel=0.2)


def test_the_coefficient_names_the_run_and_is_its_identity():
    assert run_name(MarlConfig(algo="mappo", links=6, bound_loss=1.0, seed=1)) == \
        "mappo_6links_neighbours_bl1_seed1"
    assert run_name(MarlConfig(algo="mappo", links=6, seed=1)) == \
        "mappo_6links_neighbours_seed1"
    assert "bound_loss" in MarlConfig.IDENTITY
    assert MarlConfig(bound_loss=0.5).hyperparameters()["bound_loss"] == 0.5
    assert "bound_loss" not in MarlConfig().hyperparameters()
    old = MarlConfig().as_dict()
    del old["bound_loss"]                                  # a checkpoint from before it
    assert MarlConfig.from_dict(old).bound_loss == 0.0


@pytest.mark.parametrize("args, message", [
    (["--algo", "ppo", "--bound-loss", "1"], "--bound-loss is for --algo ippo|mappo"),
    (["--algo", "sac", "--bound-loss", "1"], "--bound-loss is for --algo ippo|mappo"),
    (["--algo", "mappo", "--bound-loss", "-1"], "--bound-loss must be a number from 0 to 100"),
    (["--algo", "ippo", "--bound-loss", "nan"], "--bound-loss must be a number from 0 to 100"),
    (["--algo", "ippo", "--bound-loss", "1e9"], "--bound-loss must be a number from 0 to 100"),
])
def test_bad_coefficients_are_one_line_exit_2_nothing_written(tmp_path, capsys, args,
                                                              message):
    out = tmp_path / "run"
    assert main(["train", *args, "--steps", "64", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not out.exists()


def test_a_run_with_it_resumes_bit_for_bit_and_refuses_another(tmp_path, capsys):
    pytest.importorskip("skrl")
    common = ["train", "--algo", "mappo", "--links", "3", "--envs", "4", "--n-steps", "16",
              "--eval-every", "64", "--seed", "3", "--bound-loss", "2"]
    assert main([*common, "--steps", "128", "-o", str(tmp_path / "whole"), "--json"]) == 0
    whole = json.loads(capsys.readouterr().out)
    assert whole["agent"] == "mappo_3links_neighbours_bl2_seed3.marl.pt"
    assert whole["hyperparameters"]["bound_loss"] == 2.0
    assert main([*common, "--steps", "64", "-o", str(tmp_path / "part")]) == 0
    (tmp_path / "part" / whole["agent"]).unlink()             # as if stopped at 64
    assert main(["train", "--resume", "-o", str(tmp_path / "part"), "--steps", "128"]) == 0
    a = torch.load(tmp_path / "whole" / whole["agent"], weights_only=True)["policies"]
    b = torch.load(tmp_path / "part" / whole["agent"], weights_only=True)["policies"]
    assert all(torch.equal(a[k][n], b[k][n]) for k in a for n in a[k])
    capsys.readouterr()
    (tmp_path / "part" / whole["agent"]).unlink()             # stopped again
    assert main(["train", "--resume", "-o", str(tmp_path / "part"), "--steps", "192",
                 "--bound-loss", "1"]) == 2
    assert "with bound_loss 2.0, not 1.0" in capsys.readouterr().err
