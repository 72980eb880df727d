"""`twolink train --base pd` (twolink.control.residual, twolink.envs.residual): the
residual agent of zero action is the tuned per-joint PD (its torques, and the arms the
env drives); the base round-trips through the agent file, so `twolink evaluate --links 6`
scores what the curve scored; an unknown base, or a base where it does not apply, is one
line. Skipped where Stable-Baselines3 is not installed."""
from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
import torch  # noqa: E402

from twolink.arm.parameters import TS, links_parameters  # noqa: E402
from twolink.cli import main  # noqa: E402
from twolink.control.links_pd import tuned  # noqa: E402
from twolink.control.residual import base_controller  # noqa: E402
from twolink.control.sb3_agent import SB3Agent  # noqa: E402
from twolink.envs.residual import ResidualVecEnv  # noqa: E402
from twolink.envs.sb3 import TwoLinkSB3VecEnv  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.metrics import random_poses  # noqa: E402
from twolink.sim.plants import MujocoPlant  # noqa: E402
from twolink.sim.rollout import rollout  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import PolicyController, build, save_agent  # noqa: E402

ARM = links_parameters(6, "tapered")
STATES = np.concatenate([random_poses(6, 16, 3)[:, :6],
                         np.random.default_rng(4).normal(0, 2, (16, 6))], 1)


def _zero_agent(path, base="pd", history=1):
    """A 6-link PPO agent whose deterministic action is exactly 0, saved at ``path``."""
    config = TrainConfig(links=6, base=base, envs=2, n_steps=8, steps=16, history=history)
    model, env = build(config)
    with torch.no_grad():
        model.policy.action_net.weight.zero_()
        model.policy.action_net.bias.zero_()
    save_agent(model, path, config)
    env.close()
    return model, config


@pytest.mark.parametrize("history", [1, 3])
def test_zero_action_is_the_tuned_pd(tmp_path, history):
    model, _ = _zero_agent(tmp_path / "a.zip", history=history)
    pd = tuned(ARM)
    want = pd(STATES)
    assert np.abs(want).max() > 0.1 and np.any(np.abs(want) < pd.tau_max)  # saturated or not
    agent = SB3Agent(tmp_path / "a.zip")
    assert agent.meta["base"] == "pd"
    assert np.array_equal(agent(STATES), want)
    assert agent.history == history
    mine = PolicyController(model.policy, ARM, history=history,
                            base=base_controller("pd", ARM))
    assert np.array_equal(mine(STATES), want)
    # without the base the same zero policy is zero torque
    assert np.array_equal(PolicyController(model.policy, ARM, history=history)(STATES),
                          np.zeros((16, 6)))


def test_the_env_drives_the_arms_with_the_pd_at_zero_action():
    x0 = random_poses(6, 4, 11)
    env = ResidualVecEnv(TwoLinkSB3VecEnv(4, links=6, rule="tapered", actions="normalized",
                                          observation="cos_sin", nthread=1),
                         base_controller("pd", ARM))
    env.venv.set_options([{"x0": row} for row in x0])
    env.reset()
    for _ in range(20):
        env.step(np.zeros((4, 6), dtype=np.float32))
    with MujocoPlant(ARM, nthread=1) as plant:
        traj = rollout(tuned(ARM), plant, x0, duration=20 * TS)
    got = env.venv.states
    env.close()
    assert np.abs(traj.x[:, -1] - x0).max() > 0.01           # the arms moved
    assert np.allclose(got, traj.x[:, -1], atol=1e-9)


def test_the_base_round_trips_through_the_agent_file(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--links", "6", "--base", "pd", "--steps", "32", "--envs", "2",
                 "--n-steps", "16", "--eval-every", "32", "--out", str(out), "--json"]) == 0
    got = capsys.readouterr()
    record = json.loads(got.out)
    assert record["config"]["base"] == "pd"
    assert "over base pd" in got.err
    path = out / "ppo_6links_pd_seed0.zip"
    with zipfile.ZipFile(path) as z:
        meta = json.loads(z.read("twolink.json"))
    assert meta["base"] == "pd" and meta["base_gains"] == {"sat_deg": 40, "zeta": 1.4}
    assert main(["evaluate", str(path), "--links", "6", "--poses", "64", "--seed",
                 "20061122", "--json"]) == 0
    scored = json.loads(capsys.readouterr().out)
    last = record["curve"][-1]
    assert (last["n"], last["successes"]) == (64, _successes(scored))


def _successes(result) -> int:
    """The successes of ``twolink evaluate --links --json``'s result (its one horizon)."""
    found = []

    def walk(v):
        if isinstance(v, dict):
            if "successes" in v and "n" in v:
                found.append(v["successes"])
            for w in v.values():
                walk(w)
        elif isinstance(v, list):
            for w in v:
                walk(w)

    walk(result)
    assert len(set(found)) == 1, result
    return found[0]


def _rewrite(path, out, **changes):
    with zipfile.ZipFile(path) as z, zipfile.ZipFile(out, "w") as w:
        for item in z.infolist():
            data = z.read(item)
            if item.filename == "twolink.json":
                meta = json.loads(data)
                meta.update(changes)
                data = json.dumps(meta).encode()
            w.writestr(item, data)


def test_unknown_base_and_misplaced_base_are_one_line(tmp_path, capsys):
    _zero_agent(tmp_path / "a.zip")
    _rewrite(tmp_path / "a.zip", tmp_path / "mpc.zip", base="mpc")
    with pytest.raises(ControllerError, match="names the base controller 'mpc', which "
                                              "this version does not know"):
        SB3Agent(tmp_path / "mpc.zip")
    _rewrite(tmp_path / "a.zip", tmp_path / "gains.zip", base_gains={"sat_deg": -1})
    with pytest.raises(ControllerError, match="base pd without gains"):
        SB3Agent(tmp_path / "gains.zip")
    for argv, text in (
            (["evaluate", str(tmp_path / "mpc.zip"), "--links", "6"], "base controller 'mpc'"),
            (["train", "--base", "mpc"], "--base must be one of"),
            (["train", "--base", "pd"], "base pd is the tuned per-joint PD of 3 to 6 links")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and text in err[0], err
    assert "base" in TrainConfig.IDENTITY and TrainConfig().base == "none"
    # an agent saved without a base loads as before: its torques are the action alone
    _zero_agent(tmp_path / "plain.zip", base="none")
    with zipfile.ZipFile(tmp_path / "plain.zip") as z:
        assert "base" not in json.loads(z.read("twolink.json"))
    assert np.array_equal(SB3Agent(tmp_path / "plain.zip")(STATES), np.zeros((16, 6)))


def test_a_residual_run_resumes_bit_for_bit_and_only_as_itself(tmp_path, capsys):
    import io

    from twolink.training.run import train

    common = dict(links=6, base="pd", envs=2, n_steps=16, eval_every=32)
    whole = train(TrainConfig(steps=96, **common), tmp_path / "whole")
    seen = []

    def stop(line):                                  # interrupted after its 2nd point
        seen.append(line)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(TrainConfig(steps=96, **common), tmp_path / "part", progress=stop)
    assert main(["train", "--resume", "--base", "none", "--out", str(tmp_path / "part")]) == 2
    assert "with base 'pd', not 'none'" in capsys.readouterr().err
    resumed = train({"steps": 96}, tmp_path / "part", resume=True)
    strip = lambda c: [(p["steps"], p["successes"]) for p in c]  # noqa: E731
    assert strip(resumed["curve"]) == strip(whole["curve"])

    def weights(folder):
        with zipfile.ZipFile(folder / "ppo_6links_pd_seed0.zip") as z:
            return torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True)

    a, b = weights(tmp_path / "whole"), weights(tmp_path / "part")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
