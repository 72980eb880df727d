"""robustness.evaluate: the batched evaluation against a plain per-run loop, per-row
independence, the summary statistics, bad input, and the targets of the robust policies."""
import json
import math
import re

import numpy as np
import pytest

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, TABLE_I, TS
from twolink.arm.task import agent_reward, centralized_reward
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.challenges import LEVELS, Challenge, draw_plants
from twolink.sim.estimation import compensated
from twolink.sim.evaluation import FAULT_STREAM, NOISE_STREAM, Evaluation, evaluate
from twolink.sim.metrics import discounted_return, evaluation_set, settle_time, success
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import Trajectory

#: Every part of a challenge on, faults frequent enough to fire in a short run.
HARSH = Challenge("harsh", spread=0.3, torque_limit=-0.2, action_delay=1, observation_delay=2,
                  angle_noise_deg=1.0, speed_noise=0.05, dropout=0.2, stuck=0.05)
#: Milder, for the uncompensated policy (which never settles under HARSH): no actuation delay.
MIXED = Challenge("mixed", spread=0.2, torque_limit=-0.1, observation_delay=1,
                  angle_noise_deg=0.5, speed_noise=0.02, dropout=0.2, stuck=0.05)
X0 = np.array([[-1.0, -3.0, 0.0, 0.0], [0.3, -0.2, 0.0, 0.0], [0.1, 0.1, 0.0, 0.0]])


@pytest.fixture(scope="module")
def policy():
    return load_policy("centralized_full")


def _generator(entropy, p, s):
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy, spawn_key=(p, s))))


def _reference_run(policy, plant_params, x0, ch, seed, p, s, steps, compensate):
    """One run alone, one sample at a time: noise, faults, reading delay, controller,
    actuation delay, plant; written from the docstrings, not from the fast path."""
    noise = _generator([seed, NOISE_STREAM], p, s)
    faults = _generator([seed, FAULT_STREAM], p, s)
    std = np.array([ch.angle_std, ch.angle_std, ch.speed_noise, ch.speed_noise])
    design = {"angle_noise_deg": ch.angle_noise_deg, "speed_noise": ch.speed_noise}
    ctrl = compensated(policy, delay=ch.action_delay, observation_delay=ch.observation_delay,
                       noise=True, **design) if compensate else policy   # for its own noise
    xs, us, handed, readings, commands, stuck_for = [x0], [], [], [], [], 0
    with MujocoPlant(plant_params, nthread=1) as plant:
        x = x0
        for k in range(steps):
            y = x + std * noise.standard_normal(4)
            u_drop, u_stick = faults.random(), faults.random()
            if k == 0:
                pass
            elif stuck_for:
                stuck_for, y = stuck_for - 1, handed[-1]
            elif u_stick < ch.stuck:
                stuck_for, y = 3, handed[-1]                 # STUCK_SAMPLES = 4
            elif u_drop < ch.dropout:
                y = handed[-1]
            handed.append(y)
            readings.append(handed[max(0, k - ch.observation_delay)])
            commands.append(np.asarray(ctrl(readings[-1][None]))[0])
            u = commands[k - ch.action_delay] if k >= ch.action_delay else np.zeros(2)
            x = plant.step(x, u)
            xs.append(x)
            us.append(u)
    xs = np.array(xs)
    r_links = np.stack([agent_reward(xs[1:], 1), agent_reward(xs[1:], 2)], -1)
    return Trajectory(np.arange(steps + 1) * TS, xs, np.array(us), centralized_reward(xs[1:]),
                      r_links)


@pytest.mark.parametrize("compensate, ch", [(False, MIXED), (True, HARSH)],
                         ids=["plain", "compensated"])
def test_evaluate_equals_a_plain_loop_over_runs(policy, compensate, ch):
    plants = ch.plants(2, seed=5)
    x0s = X0[:2] if compensate else X0          # the compensator's own loop is slow
    ev = evaluate(policy, params=plants, x0=x0s, seed=5, horizon=3.0, challenge=ch,
                  compensate=compensate)
    assert ev.success.shape == ev.settle.shape == ev.returns.shape == (2, len(x0s))
    assert ev.compensated == compensate
    for p, params in enumerate(plants):
        for s, x0 in enumerate(x0s):
            ref = _reference_run(policy, params, x0, ch, 5, p, s, 60, compensate)
            assert ev.settle[p, s] == settle_time(ref), (p, s)
            assert ev.success[p, s] == success(ref), (p, s)
            assert ev.returns[p, s] == discounted_return(ref), (p, s)
    assert len(np.unique(ev.returns)) == ev.runs        # different runs compared
    assert np.isfinite(ev.settle).any() or not compensate   # compensated, some settle


def test_a_runs_numbers_do_not_depend_on_its_batch_mates(policy):
    ch = LEVELS["hard"]
    big = evaluate(policy, x0=X0, seed=3, horizon=2.0, challenge=ch, count=3, compensate=False)
    small = evaluate(policy, x0=X0[:2], seed=3, horizon=2.0, challenge=ch, count=2,
                     compensate=False)
    assert big.params[:2] == small.params
    np.testing.assert_array_equal(big.settle[:2, :2], small.settle)
    np.testing.assert_array_equal(big.returns[:2, :2], small.returns)
    again = evaluate(policy, x0=X0, seed=3, horizon=2.0, challenge=ch, count=3,
                     compensate=False)
    np.testing.assert_array_equal(again.returns, big.returns)
    other = evaluate(policy, x0=X0, seed=4, horizon=2.0, challenge=ch, count=3,
                     compensate=False)
    assert other.params != big.params and not np.array_equal(other.returns, big.returns)


def test_delay_and_noise_without_a_challenge(policy):
    ev = evaluate(policy, x0=X0, delay=1, angle_noise_deg=1.0, horizon=2.0, compensate=False)
    assert ev.params == (TABLE_I,)
    ch = ev.challenge
    assert (ch.action_delay, ch.angle_noise_deg, ch.spread) == (1, 1.0, 0.0)
    assert ch.speed_noise == pytest.approx(GOAL_SPEED / math.degrees(GOAL_ANGLE))
    plain = evaluate(policy, x0=X0, horizon=2.0, compensate=True)   # nothing to compensate
    assert not plain.compensated and plain.challenge.name == "custom"
    assert not np.array_equal(plain.returns, ev.returns)


def _synthetic(success_rows, settle_rows, returns_rows):
    return Evaluation(np.array(success_rows), np.array(settle_rows, dtype=float),
                      np.array(returns_rows, dtype=float), (TABLE_I,) * len(success_rows),
                      np.zeros((len(success_rows[0]), 4)), LEVELS["none"], 0, 5.0, False, "x")


def test_summary_statistics_and_json():
    ev = _synthetic([[True, True, False, True], [True, False, False, True]],
                    [[1.0, 2.0, np.inf, 0.5], [1.5, np.inf, np.inf, 3.0]],
                    [[-1, -2, -9, -0.5], [-1.5, -8, -10, -3]])
    assert (ev.count, ev.runs, ev.rate) == (5, 8, 5 / 8)
    assert ev.plant_counts.tolist() == [3, 2]
    assert (ev.worst_plant, ev.worst_plant_rate) == (1, 0.5)
    assert (ev.worst_return, ev.mean_return) == (-10.0, -35.0 / 8)
    assert ev.median_settle == 2.5                      # (2.0 + 3.0) / 2; inf counts high
    lo, hi = ev.interval
    assert lo == pytest.approx(0.3057, abs=1e-4) and hi == pytest.approx(0.8632, abs=1e-4)
    d = json.loads(json.dumps(ev.as_dict()))
    assert d["successes"] == 5 and d["plant_successes"] == [3, 2]
    assert d["settle"][0][2] is None and d["wilson_95"] == [lo, hi]
    assert _synthetic([[False] * 3], [[np.inf] * 3], [[-1] * 3]).as_dict()["median_settle"] is None


@pytest.mark.parametrize("kwargs, message", [
    (dict(delay=100), "a delay of 100 samples is not shorter than the horizon of 100 samples"),
    (dict(challenge=Challenge("slow", observation_delay=60, action_delay=40)),
     "a delay of 100 samples"),
    (dict(angle_noise_deg=-1.0), "angle_noise_deg must be non-negative, got -1.0"),
    (dict(delay=-1), "action_delay must be a whole number of samples"),
    (dict(angle_noise_deg=math.nan), "angle_noise_deg must be a finite number"),
    (dict(challenge="medium", delay=1), "either a challenge or delay/angle_noise_deg"),
    (dict(challenge="wild"), "unknown challenge 'wild'"),
    (dict(x0=np.zeros((2, 3))), "x0 must have 4 components"),
    (dict(x0=np.zeros((2, 2, 4))), "x0 must be states of shape (n, 4)"),
    (dict(params=[]), "params must be a non-empty list of ArmParameters"),
    (dict(params=["TABLE_I"]), "params must be a non-empty list of ArmParameters"),
    (dict(params=[TABLE_I], count=2), "count 2 disagrees with the 1 params given"),
    (dict(count=0), "count must be a whole number of plants from 1 to 10000"),
    (dict(challenge="medium", count=10**6), "count must be a whole number of plants"),
    (dict(horizon=math.inf), "horizon must be a finite number"),
    (dict(horizon=-1.0), "duration must be a positive number of seconds"),
    (dict(seed=-3), "seed must be a non-negative whole number"),
    (dict(challenge="none", count=5000, x0=np.zeros((100, 4))), "5000 plants x 100 states"),
])
def test_bad_input_refused(policy, kwargs, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        evaluate(policy, **kwargs)


def test_spread_outside_its_range_refused():
    with pytest.raises(ValueError, match=re.escape("spread must be a relative change in "
                                                   "[0, 0.9), got 0.95")):
        evaluate("centralized_full", challenge=Challenge("wide", spread=0.95))
    with pytest.raises(ValueError, match="spread"):
        draw_plants(-0.1, 4, 0)


# --------------------------------------------------------------------------- targets
#: Seed of these checks: not the report's (twolink.studies.mismatch.plan.ROBUST_SEED), not the
#: robust synthesis's (2006), not the compensation's development seed (1000).
TARGET_SEED = 77
#: Plants of the check: 8 of the report's 32, all 65 states (520 runs).
TARGET_PLANTS = 8


def _consistent(ev_count, runs, target):
    """The count does not refute a rate >= target at 95 %: the upper end of its Wilson
    interval reaches the target. The tolerance is the sample's: 8 plants, not the
    report's 32, so this is a quick check that fails on a clear miss; the verdict on a
    target is the report's full figure (runs on one plant are correlated, so 8 plants
    can miss a shortfall that only the other plants show)."""
    from twolink.sim.metrics import wilson_interval
    return wilson_interval(ev_count, runs)[1] >= target


@pytest.mark.slow
@pytest.mark.robustness
def test_centralized_robust_meets_its_targets():
    nominal = evaluate("centralized_robust")
    assert nominal.count == nominal.runs == len(evaluation_set())        # 100 % nominal
    ev = evaluate("centralized_robust", challenge="medium", count=TARGET_PLANTS,
                  seed=TARGET_SEED, compensate=True)
    assert ev.compensated and ev.runs == TARGET_PLANTS * len(evaluation_set())
    assert _consistent(ev.count, ev.runs, 0.98), ev.as_dict(rows=False)
    n = ev.success.shape[1]
    assert all(_consistent(int(k), n, 0.95) for k in ev.plant_counts), ev.plant_counts
    assert ev.median_settle <= 1.5, ev.median_settle


@pytest.mark.slow
@pytest.mark.robustness
def test_decentralized_robust_meets_its_targets():
    nominal = evaluate("decentralized_robust")
    assert nominal.rate >= 0.95, nominal.count                          # the full figure
    ev = evaluate("decentralized_robust", challenge="medium", count=TARGET_PLANTS,
                  seed=TARGET_SEED, compensate=True)
    assert ev.compensated
    assert _consistent(ev.count, ev.runs, 0.90), ev.as_dict(rows=False)
