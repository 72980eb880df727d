"""`twolink train --algo ippo|mappo --base pd`: each agent's action is a residual over its
own joint's PD. Agents of zero action are the tuned per-joint PD, in memory and from the
saved file; the learner drives the arms with it; the base round-trips through the save
and an unknown base in the header is one line. Skipped without skrl."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("skrl")

import torch  # noqa: E402

from twolink.arm.parameters import TS, links_parameters  # noqa: E402
from twolink.cli import main  # noqa: E402
from twolink.control.links_pd import tuned  # noqa: E402
from twolink.control.marl_agent import load_marl_agent, read_marl_file  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.training import marl_state  # noqa: E402
from twolink.training.marl import MarlConfig  # noqa: E402

ARM = links_parameters(6, "tapered")
STATES = np.concatenate([np.random.default_rng(5).uniform(-3, 3, (16, 6)),
                         np.random.default_rng(6).normal(0, 2, (16, 6))], 1)
SMALL = dict(links=6, envs=4, n_steps=8, eval_every=32, steps=32, observe="local")


def _zeroed(learner):
    """Make every agent's mean action exactly 0 (its last layer zeroed)."""
    with torch.no_grad():
        for a in learner.agents:
            last = [m for m in learner.models[a]["policy"].net if hasattr(m, "weight")][-1]
            last.weight.zero_()
            last.bias.zero_()


@pytest.mark.parametrize("algo", ["ippo", "mappo"])
def test_zero_actions_are_the_tuned_pd(tmp_path, algo):
    learner = marl_state.Learner(MarlConfig(algo=algo, base="pd", **SMALL), torch)
    _zeroed(learner)
    want = tuned(ARM)(STATES)
    assert np.abs(want).max() > 0.1
    assert np.array_equal(learner.controller()(STATES), want)
    learner.save_agent(tmp_path / "a.marl.pt")
    agent = load_marl_agent(tmp_path / "a.marl.pt")
    assert agent.meta["base"] == "pd" and np.array_equal(agent(STATES), want)
    header, _ = read_marl_file(tmp_path / "a.marl.pt")
    assert header["base_gains"] == {"sat_deg": 40, "zeta": 1.4}
    # the learner drives the arms with the PD: after 8 steps of zero action, the states
    # of a PD rollout from the same start
    learner.obs, _ = learner.env.reset(seed=3)
    x0 = learner.env.state().copy()
    learner.agent.act = lambda obs, states, **k: (
        {a: torch.zeros(4, 1) for a in learner.agents}, None)
    learner.agent.record_transition = learner.agent.post_interaction = lambda **k: None
    learner.learn(32, 32)
    from twolink.sim.plants import MujocoPlant
    from twolink.sim.rollout import rollout

    with MujocoPlant(ARM, nthread=1) as plant:
        traj = rollout(tuned(ARM), plant, x0, duration=8 * TS)
    assert np.abs(traj.x[:, -1] - x0).max() > 0.01
    assert np.allclose(learner.env.state(), traj.x[:, -1], atol=1e-9)
    learner.close()


def test_a_run_records_its_base_and_an_unknown_base_is_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--algo", "ippo", "--links", "6", "--base", "pd", "--observe",
                 "local", "--envs", "4", "--n-steps", "8", "--steps", "32",
                 "--eval-every", "32", "--out", str(out), "--json"]) == 0
    got = capsys.readouterr()
    assert json.loads(got.out)["config"]["base"] == "pd" and "over base pd" in got.err
    path = out / "ippo_6links_local_pd_seed0.marl.pt"
    assert load_marl_agent(path).meta["base"] == "pd"
    saved = torch.load(path, weights_only=True)
    header = json.loads(saved["header"])
    torch.save({"header": json.dumps(dict(header, base="lqr")),
                "policies": saved["policies"]}, tmp_path / "bad.marl.pt")
    with pytest.raises(ControllerError, match="header names the base controller 'lqr'"):
        load_marl_agent(tmp_path / "bad.marl.pt")
    assert main(["evaluate", str(tmp_path / "bad.marl.pt"), "--links", "6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'lqr'" in err[0]
    assert main(["train", "--algo", "mappo", "--base", "pd"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "base pd is the tuned per-joint PD of 3 to 6 links" in err[0]
