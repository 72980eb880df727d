"""`twolink train --action-rate C`: the penalty's numbers, the wrapper's rewards (and its
reset at an episode's end), a run with the penalty resuming bit for bit, and bad values
as one line with exit 2 and nothing written."""
from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import torch  # noqa: E402

from twolink.cli import main  # noqa: E402
from twolink.training import action_rate, checkpoint  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import CLOCKS, train  # noqa: E402

SMOKE = dict(algo="ppo", links=2, steps=512, envs=4, n_steps=32, eval_every=256,
             action_rate=1.0)
AGENT = "ppo_2links_ar1_seed0.zip"


def test_the_penalty_is_c_times_the_mean_squared_change():
    p = action_rate.penalty([[1.0, -1.0], [0.5, 3.0]], np.array([[0.0, 0.0], [0.5, 0.0]]), 2.0)
    assert p == pytest.approx([2.0, 1.0])      # 3.0 is clipped to 1: 2 * (0 + 1) / 2


def _env():
    from twolink.envs.sb3 import TwoLinkSB3VecEnv
    from twolink.training.config import ENV

    env = TwoLinkSB3VecEnv(2, **dict(ENV, links=2, nthread=1))
    env.seed(7)
    return env


def test_the_wrapper_subtracts_the_penalty_and_forgets_at_an_episode_end():
    plain, wrapped = _env(), action_rate.wrap(_env(), 0.5)
    assert type(wrapped).__name__ == "ActionRateVecEnv"
    assert np.array_equal(plain.reset(), wrapped.reset())
    last = np.zeros((2, 2))
    for a in ([[1.0, 0.0], [-1.0, 0.5]], [[-1.0, 0.0], [-1.0, 0.25]]):
        a = np.array(a, dtype=np.float32)
        _, r0, _, _ = plain.step(a)
        _, r1, _, _ = wrapped.step(a)
        assert r1 == pytest.approx(r0 - 0.5 * np.mean((a - last) ** 2, axis=1))
        last = a
    wrapped.step_async(np.ones((2, 2), dtype=np.float32))
    inner = wrapped.venv.step_wait
    wrapped.venv.step_wait = lambda: (lambda o, r, d, i: (o, r, np.array([True, False]), i))(
        *inner())
    wrapped.step_wait()
    assert np.array_equal(wrapped.last, [[0.0, 0.0], [1.0, 1.0]])


class Stop(Exception):
    pass


def _weights(path):
    with zipfile.ZipFile(path) as z:
        return torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True)


def test_a_run_with_the_penalty_resumes_bit_for_bit(tmp_path):
    whole = train(TrainConfig(**SMOKE), tmp_path / "whole")
    seen = []

    def stop(line):
        seen.append(line)
        if len(seen) == 2:
            raise Stop

    with pytest.raises(Stop):
        train(TrainConfig(**SMOKE), tmp_path / "cut", progress=stop)
    resumed = train(None, tmp_path / "cut", resume=True)
    plain = [[{k: v for k, v in p.items() if k not in CLOCKS} for p in r["curve"]]
             for r in (whole, resumed)]
    assert plain[0] == plain[1] and resumed["config"]["action_rate"] == 1.0
    a, b = _weights(tmp_path / "whole" / AGENT), _weights(tmp_path / "cut" / AGENT)
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    _, ta = checkpoint.load(tmp_path / "whole" / "checkpoint.pt")
    _, tb = checkpoint.load(tmp_path / "cut" / "checkpoint.pt")
    assert torch.equal(ta["episodes"]["action_rate"]["last"],
                       tb["episodes"]["action_rate"]["last"])
    assert torch.count_nonzero(ta["episodes"]["action_rate"]["last"]) > 0


@pytest.mark.parametrize("argv, message", [
    (["--action-rate", "-1"], "--action-rate must be a number from 0 to 100, got '-1'"),
    (["--action-rate", "nan"], "--action-rate must be a number from 0 to 100"),
    (["--action-rate", "lots"], "--action-rate must be a number from 0 to 100"),
    (["--algo", "ippo", "--action-rate", "101"], "--action-rate must be a number from 0 to 100"),
])
def test_bad_values_are_one_line_exit_2_nothing_written(tmp_path, capsys, argv, message):
    out = tmp_path / "run"
    assert main(["train", *argv, "--steps", "128", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()
