"""Training under a mix of challenge levels (``twolink train --challenge none+medium+hard``):
the name's grammar, arm i under level i mod L (its plants, delays, noise and faults), the
curve scoring every level of the mix, a resume bit for bit, and bad input in one line."""
from __future__ import annotations

import io
import json
import re
import zipfile

import numpy as np
import pytest

from twolink.sim.challenges import LEVELS, Mix, is_mix, levels_of, mix

MIX = "none+medium+hard"


def test_a_mix_names_distinct_levels_in_the_table_order():
    m = mix(MIX)
    assert isinstance(m, Mix) and m.name == MIX
    assert m.levels == (LEVELS["none"], LEVELS["medium"], LEVELS["hard"])
    assert [m.level(i).name for i in range(7)] == ["none", "medium", "hard"] * 2 + ["none"]
    assert levels_of("medium") == (LEVELS["medium"],) and levels_of(MIX) == m.levels
    assert is_mix(MIX) and is_mix(m) and not is_mix("hard") and not is_mix(None)
    with pytest.raises(ValueError, match="a mix holds two or more Challenge levels"):
        Mix((LEVELS["hard"],))
    with pytest.raises(ValueError, match="a mix holds two or more Challenge levels"):
        Mix(("none", "hard"))
    for bad in ("hard+none", "medium+medium", "none+", "medium+extreme", "+"):
        with pytest.raises(ValueError, match=re.escape(f"unknown challenge {bad!r}: a level")):
            mix(bad)


def test_each_arm_runs_under_its_own_level():
    from twolink.envs.gym import TwoLinkVectorEnv

    env = TwoLinkVectorEnv(6, challenge=MIX, observation="cos_sin", actions="normalized",
                           x0="random", nthread=1)
    env.reset(seed=3)
    arms = env._arms
    assert arms._delay.samples.tolist() == [0, 1, 1] * 2          # medium and hard: 1 late
    assert arms.sensors.delay.samples.tolist() == [0, 0, 1] * 2    # hard: readings 1 late
    angle = np.degrees(arms.sensors.noise.std[:, 0])
    assert np.allclose(angle, [0.0, 1.0, 2.0] * 2)
    assert arms.sensors.faults.dropout.tolist() == [0.0, 0.0, 0.05] * 2
    plants = arms.plant.params
    nominal = LEVELS["none"].plant(np.random.default_rng(0))
    assert plants[0] == nominal and plants[3] == nominal           # none: Table I itself
    assert plants[1] != nominal and plants[4] != plants[1]         # drawn per arm
    hard_tau = np.asarray(plants[2].tau_max) / np.asarray(nominal.tau_max)
    assert np.all(hard_tau <= 0.8 + 1e-12)                         # hard: 20 % less torque
    # Noise-free arms read the true state; noisy ones do not.
    obs = env.step(np.zeros((6, 2), np.float32))[0]
    truth = env._arms.x
    q = truth[:, :2]
    exact = np.stack([np.cos(q[:, 0]), np.sin(q[:, 0]), np.cos(q[:, 1]), np.sin(q[:, 1])], 1)
    assert np.allclose(obs[[0, 3], :4], exact[[0, 3]])
    assert not np.allclose(obs[[1, 2, 4, 5], :4], exact[[1, 2, 4, 5]])
    env.close()
    with pytest.raises(ValueError, match=re.escape(f"a mix of 3 levels ({MIX}) needs at least "
                                                   f"as many arms, got 2")):
        TwoLinkVectorEnv(2, challenge=MIX, nthread=1)


@pytest.fixture(scope="module")
def whole_run(tmp_path_factory):
    pytest.importorskip("stable_baselines3")
    from twolink.training.config import TrainConfig
    from twolink.training.run import train

    out = tmp_path_factory.mktemp("whole_mix")
    config = TrainConfig(algo="ppo", steps=384, envs=3, n_steps=32, eval_every=192,
                         challenge=MIX, history=2)
    return train(config, out), out, config


def test_the_curve_scores_every_level_of_the_mix(whole_run):
    record, out, _ = whole_run
    curve = json.loads((out / "curve.json").read_text())
    assert curve["config"]["challenge"] == MIX
    assert curve["evaluation"]["challenge"] == MIX and "mix" in curve["evaluation"]
    # none once on the nominal arm (65), medium and hard on 8 plants each (2 x 520).
    assert [p["n"] for p in curve["curve"]] == [65 + 2 * 8 * 65] * 3
    with zipfile.ZipFile(out / "ppo_2links_none+medium+hard_h2_seed0.zip") as z:
        assert json.loads(z.read("twolink.json"))["challenge"] == MIX


def test_the_curve_point_is_the_levels_evaluated_one_by_one(whole_run):
    from twolink.control.sb3_agent import sb3_agent
    from twolink.sim.evaluation import evaluate
    from twolink.training.config import EVAL_PLANTS, EVAL_SEED

    record, out, _ = whole_run
    agent = sb3_agent(str(out / record["agent"]))
    runs = [evaluate(agent, nthread=1, challenge="none"),
            *(evaluate(agent, nthread=1, challenge=lv, seed=EVAL_SEED, count=EVAL_PLANTS)
              for lv in ("medium", "hard"))]
    last = record["curve"][-1]
    assert last["successes"] == sum(r.score.successes for r in runs)
    assert last["n"] == sum(r.score.n for r in runs)


class _Stop(Exception):
    pass


def _interrupted_then_resumed(train, config, out):
    """``train(config, out)`` stopped at its second progress line (after the first curve
    point), then resumed to the end: the resumed run's record."""
    seen = []

    def stop(line):
        seen.append(line)
        if len(seen) == 2:
            raise _Stop

    with pytest.raises(_Stop):
        train(config, out, progress=stop)
    return train(None, out, resume=True)


def test_a_resumed_mix_run_is_bit_for_bit_the_uninterrupted_one(whole_run, tmp_path):
    import torch

    from twolink.training.run import CLOCKS, train

    record, whole, config = whole_run
    resumed = _interrupted_then_resumed(train, config, tmp_path)

    def plain(curve):
        return [{k: v for k, v in p.items() if k not in CLOCKS} for p in curve]

    def weights(path):
        with zipfile.ZipFile(path) as z:
            return torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True)

    assert plain(resumed["curve"]) == plain(record["curve"])
    a, b = weights(tmp_path / record["agent"]), weights(whole / record["agent"])
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_bad_mixes_are_one_line_and_write_nothing(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from twolink.cli import main

    out = tmp_path / "run"
    cases = [(["--challenge", "hard+none"], "unknown challenge 'hard+none': a level"),
             (["--challenge", "none+none"], "unknown challenge 'none+none'"),
             (["--challenge", MIX, "--envs", "4"],
              "a mix of 3 levels (none+medium+hard) needs a multiple of 3 arms (--envs)"),
             (["--challenge", MIX, "--envs", "6", "--seed", "2026"],
              "seed 2026 is an evaluation seed")]
    for argv, message in cases:
        capsys.readouterr()
        assert main(["train", *argv, "--steps", "128", "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
        assert not out.exists()


def test_a_multi_agent_run_takes_a_mix_and_resumes_bit_for_bit(tmp_path):
    pytest.importorskip("skrl")
    from twolink.envs.pettingzoo_batched import batched_parallel_env
    from twolink.training.marl import MarlConfig, train

    arms = batched_parallel_env(3, challenge=MIX, observe="local", reward="shaped",
                                actions="normalized", observation="cos_sin")
    # The spaces are the noisiest level's: unbounded readings.
    assert np.isinf(arms.observation_spaces["link1"].high).any()
    arms.close()
    config = MarlConfig(algo="ippo", observe="local", steps=192, envs=3, n_steps=32,
                        eval_every=96, challenge=MIX, history=2, seed=3)
    whole = train(config, tmp_path / "whole")
    assert [p["n"] for p in whole["curve"]] == [65 + 2 * 8 * 65] * 3
    resumed = _interrupted_then_resumed(train, config, tmp_path / "cut")
    keep = ("steps", "successes", "n", "median_settle")
    assert [{k: p[k] for k in keep} for p in resumed["curve"]] == \
        [{k: p[k] for k in keep} for p in whole["curve"]]
    import torch

    a, b = (torch.load(tmp_path / run / whole["agent"], weights_only=True)["policies"]
            for run in ("whole", "cut"))
    assert all(torch.equal(a[k][n], b[k][n]) for k in a for n in a[k])
