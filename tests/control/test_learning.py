"""Online fuzzy Q-learning (twolink.synthesis.learning): the update against a reference loop, the
fixed point of fuzzy Q-iteration, determinism, checkpoints and resume, bad input."""
from __future__ import annotations

import numpy as np
import pytest

from twolink.synthesis.learning import (
    Evaluation,
    Learner,
    stays_above,
    steps_to_reach,
    update_theta,
)
from twolink.synthesis.learning_setup import (
    LEARNERS,
    LEGACY,
    MAX_ARMS,
    MAX_EVALUATIONS,
    LearnConfig,
    make_agents,
)
from twolink.synthesis.problems import agent2_problem, solve
from twolink.policy.fuzzy_policy import Policy, load_policy
from twolink.sim.metrics import score
from twolink.sim.plants import ModelPlant


def reference_update(theta, idx, w, j, target, alpha, rule):
    """The batched update written as loops: per entry, gather every (arm, bin) that hit
    it, average their membership-weighted errors, and step min(1, alpha * weight)."""
    theta = theta.copy()
    old = theta.copy()
    n, k = idx.shape
    hits: dict = {}
    for a in range(n):
        q_xu = sum(w[a, b] * old[idx[a, b], j[a, b]] for b in range(k))
        for b in range(k):
            m, u = int(idx[a, b]), int(j[a, b])
            err = target[a] - (old[m, u] if rule in ("fuzzy", "rule") else q_xu)
            s, wsum = hits.get((m, u), (0.0, 0.0))
            hits[(m, u)] = (s + w[a, b] * err, wsum + w[a, b])
    for (m, u), (s, wsum) in hits.items():
        if wsum > 0:
            theta[m, u] = old[m, u] + min(1.0, alpha * wsum) * s / wsum
    return theta


@pytest.mark.parametrize("rule", ["fuzzy", "discrete", "rule", "fql"])
def test_update_matches_reference_loop(rule):
    rng = np.random.default_rng(3)
    agent = make_agents("decentralized")[1]                 # agent 1, 4-D grid, 16 bins
    theta = rng.uniform(-25, 0, agent.theta.shape)
    x = np.column_stack([rng.uniform(-3, 3, 40), rng.uniform(-6, 6, 40),
                         rng.uniform(-3, 3, 40), rng.uniform(-0.1, 0.1, 40)])
    x[:5] = x[0]                                             # shared bins across arms
    idx, w = agent.grid.memberships(x)
    if rule != "discrete":
        j = rng.integers(0, 3, idx.shape)
    else:
        j = np.broadcast_to(rng.integers(0, 3, len(x))[:, None], idx.shape)
    target = rng.uniform(-25, 0, len(x))
    for alpha in (0.05, 0.9):
        fast = update_theta(theta.copy(), idx, w, j, target, alpha, rule=rule)
        ref = reference_update(theta, idx, w, j, target, alpha, rule)
        np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-12)
        assert np.count_nonzero(fast != theta) > 20


def test_learner_converges_to_fuzzy_q_iteration_on_the_simplified_plant():
    """Given Alg. 1's transitions (every bin centre, every action, on the simplified
    plant), the learner's update reaches fuzzy Q-iteration's fixed point."""
    problem = agent2_problem()                         # 84 bins x 3 actions
    fqi = solve(problem, delta=1e-10).q
    agent = make_agents("decentralized")[0]
    assert agent.grid == problem.grid
    centres = problem.grid.centers()
    n, nu = len(centres), len(agent.actions)
    x = np.zeros((n * nu, 4))
    x[:, 1], x[:, 3] = np.repeat(centres[:, 0], nu), np.repeat(centres[:, 1], nu)
    tau = np.zeros((n * nu, 2))
    tau[:, 1] = np.tile(agent.actions[:, 0], n)
    with ModelPlant("simplified") as plant:
        nxt = plant.step(x, tau)
    idx, w = agent.grid.memberships(x[:, [1, 3]])
    assert np.allclose(w.max(axis=1), 1.0)            # each centre: one bin, weight 1
    j = np.broadcast_to(np.tile(np.arange(nu), n)[:, None], idx.shape)
    r = agent.reward(nxt)
    nidx, nw = agent.grid.memberships(nxt[:, [1, 3]])
    theta = np.zeros_like(fqi)
    for _ in range(2000):
        v = np.einsum("nk,nk->n", nw, theta.max(axis=1)[nidx])
        update_theta(theta, idx, w, j, r + 0.98 * v, 0.5, rule="fuzzy")
    assert np.abs(theta - fqi).max() < 1e-6
    assert fqi.min() < -5                              # not trivially zero


def _short(**kw) -> LearnConfig:
    """A short run of the plain learner: no theta average, no hysteresis, warm starts at
    the given Q (LEGACY), unless ``kw`` asks for them."""
    base = dict(learner="decentralized", steps=8 * 12, arms=8, seed=5, eval_every=8 * 4,
                episode=7, **LEGACY)
    base.update(kw)
    return LearnConfig(**base)


def _plain_run(config, **kw):
    with ModelPlant("full") as plant, Learner(config, plant=plant, **kw) as learner:
        learner.run()
        return [a.theta.copy() for a in learner.agents], learner.curve


@pytest.mark.slow
@pytest.mark.parametrize("learner", LEARNERS)
def test_same_seed_same_theta_bit_for_bit(learner):
    cfg = _short(learner=learner, update="discrete" if learner == "independent" else "fuzzy")
    a, curve = _plain_run(cfg)
    b, _ = _plain_run(cfg)
    c, _ = _plain_run(_short(learner=learner, seed=6))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))
    assert any(np.count_nonzero(x) > 0 for x in a)
    assert [e.steps for e in curve] == [0, 32, 64, 96]


def test_interrupted_then_resumed_equals_uninterrupted(tmp_path):
    cfg = _short()
    full, full_curve = _plain_run(cfg)
    ckpt = tmp_path / "ckpt.npz"

    def stop(e):
        if e.steps == 64:
            raise KeyboardInterrupt
    with ModelPlant("full") as plant, Learner(cfg, plant=plant) as learner:
        with pytest.raises(KeyboardInterrupt):
            learner.run(checkpoint=ckpt, on_eval=stop)
    saved = Policy.load(ckpt)
    assert saved.meta["learning"]["steps"] == 64
    with ModelPlant("full") as plant, Learner.resume(saved, plant=plant) as learner:
        learner.run(checkpoint=ckpt)
        resumed = [a.theta.copy() for a in learner.agents]
        curve = learner.curve
    assert all(np.array_equal(x, y) for x, y in zip(full, resumed))
    strip = [(e.steps, e.successes, e.median_settle, e.mean_return) for e in curve]
    assert strip == [(e.steps, e.successes, e.median_settle, e.mean_return) for e in full_curve]
    final = load_policy(str(ckpt))
    assert final.meta["learning"]["steps"] == 96
    assert np.array_equal(final.agents[1].q, resumed[1])


def test_warm_start_copies_theta_and_refuses_other_tasks_and_grids():
    init = load_policy("decentralized")
    with ModelPlant("simplified") as plant:
        with Learner(_short(), init=init, plant=plant) as learner:
            assert np.array_equal(learner.agents[1].theta, init.agents[1].q)
            assert learner.init_label == "decentralized"
        with pytest.raises(ValueError, match="is a decentralized policy; the centralized"):
            Learner(_short(learner="centralized"), init=init, plant=plant)
        with pytest.raises(ValueError, match="agent agent1 reads a grid over"):
            Learner(_short(learner="independent"), init=init, plant=plant)


@pytest.mark.parametrize("change, message", [
    ({"steps": 0}, "steps must be a whole number"),
    ({"steps": -5}, "steps must be a whole number"),
    ({"arms": 0}, "arms must be a whole number"),
    ({"arms": MAX_ARMS + 1}, "arms must be a whole number"),
    ({"steps": 4, "arms": 8}, "at least the number of arms"),
    ({"alpha": 0.0}, r"learning rate alpha must be a number in \(0, 1\]"),
    ({"alpha": 1.5}, "learning rate alpha"),
    ({"alpha": float("nan")}, "learning rate alpha"),
    ({"epsilon": -0.1}, "epsilon must be"),
    ({"learner": "joint"}, "unknown learner 'joint'"),
    ({"update": "sarsa"}, "unknown update 'sarsa'"),
    ({"steps": 10**6, "eval_every": 10}, "more than 200 evaluations"),
])
def test_bad_settings_are_refused(change, message):
    with pytest.raises(ValueError, match=message):
        _short(**change).check()


def test_resume_refuses_a_policy_without_resume_state():
    with pytest.raises(ValueError, match="not a learning checkpoint"):
        Learner.resume(load_policy("decentralized"))


def test_curve_summaries():
    from twolink.synthesis.learning import Evaluation
    curve = [Evaluation(s, score(np.arange(10) < k, np.ones(10)), -20.0, 0.0) for s, k in
             [(0, 0), (100, 9), (200, 8), (300, 10)]]
    assert steps_to_reach(curve) == 100
    assert not stays_above(curve)
    assert stays_above(curve[:2]) and steps_to_reach(curve[:1]) is None


def test_rule_update_is_the_per_rule_form_acting_as_policy_14():
    """``rule``, one arm, one step, written as the prototype's loop: each active bin its
    own epsilon-greedy action (its own coin), the arm applies sum mu_m u_{a_m} (agent 1
    reading the applied tau2), then theta[m, a_m] += alpha mu_m (r + gamma sum_m' mu_m'(x')
    max_u theta[m', u] - theta[m, a_m])."""
    rng = np.random.default_rng(11)
    cfg = LearnConfig(learner="decentralized", steps=40, arms=1, seed=2, update="rule",
                      epsilon=0.4, epsilon_final=0.4, alpha=0.3)
    with ModelPlant("full") as plant, Learner(cfg, plant=plant) as learner:
        for a in learner.agents:
            a.theta = rng.uniform(-25, 0, a.theta.shape)
        for _ in range(12):                       # several steps: coins both ways
            x = learner.x.copy()
            theta = [a.theta.copy() for a in learner.agents]
            draws = np.random.default_rng()
            draws.bit_generator.state = learner.rng.bit_generator.state
            sig = {"theta1": x[0, 0], "theta2": x[0, 1], "dtheta1": x[0, 2],
                   "dtheta2": x[0, 3]}
            picked = []
            for a, th in zip(learner.agents, theta):
                idx, w = a.grid.memberships(np.array([[sig[k] for k in a.grid.names]]))
                coins = draws.random(idx.shape)[0]
                random_u = draws.integers(0, len(a.actions), idx.shape)[0]
                out, bins = 0.0, []
                for b in range(idx.shape[1]):
                    m = int(idx[0, b])
                    u = int(random_u[b]) if coins[b] < 0.4 else int(np.argmax(th[m]))
                    out += w[0, b] * a.actions[u, 0]
                    bins.append((m, u, w[0, b]))
                sig[a.outputs[0]] = out
                picked.append(bins)
            nxt = plant.step(x, np.array([[sig["tau1"], sig["tau2"]]]))
            nsig = {"theta1": nxt[0, 0], "theta2": nxt[0, 1], "dtheta1": nxt[0, 2],
                    "dtheta2": nxt[0, 3]}
            expect = [t.copy() for t in theta]
            for a, th, ex, bins in zip(learner.agents, theta, expect, picked):
                idx, w = a.grid.memberships(np.array([[nsig[k] for k in a.grid.names]]))
                v = sum(w[0, b] * th[idx[0, b]].max() for b in range(idx.shape[1]))
                nsig[a.outputs[0]] = sum(w[0, b] * a.actions[int(np.argmax(th[idx[0, b]])), 0]
                                         for b in range(idx.shape[1]))
                target = float(a.reward(nxt)[0]) + 0.98 * v
                for m, u, mu in bins:
                    if mu > 0:
                        ex[m, u] += 0.3 * mu * (target - th[m, u])
            learner.step()
            for a, ex in zip(learner.agents, expect):
                np.testing.assert_allclose(a.theta, ex, rtol=0, atol=1e-9)


def test_average_is_an_exponential_average_of_the_same_theta():
    """``average``: learning is unchanged bit for bit; the policy reads theta_bar, the
    exponential average with beta = arms / average written as a loop here."""
    plain_cfg, avg_cfg = _short(update="discrete"), _short(update="discrete", average=20.0)
    beta = avg_cfg.arms / avg_cfg.average
    with ModelPlant("full") as plant, Learner(plain_cfg, plant=plant) as plain, \
            Learner(avg_cfg, plant=plant) as avg:
        bar = [a.theta.copy() for a in plain.agents]
        for _ in range(10):
            plain.step()
            avg.step()
            for b, a in zip(bar, plain.agents):
                b += beta * (a.theta - b)
        for p, a, b, q in zip(plain.agents, avg.agents, bar, avg.policy().agents):
            assert np.array_equal(p.theta, a.theta)
            np.testing.assert_allclose(q.q, b, rtol=0, atol=1e-12)
            assert np.abs(q.q - a.theta).max() > 1e-3       # not theta itself
        assert avg.policy().agents[0].info["averaged"] is True


def test_hysteresis_keeps_a_greedy_action_until_beaten_by_the_margin():
    """``hysteresis``: per bin, the kept action changes only when theta_bar's best beats it
    by more than the margin (a loop over bins here); the saved policy (14) acts on the
    kept actions, and its Q is theta_bar but in those rows; learning is unchanged."""
    margin = 0.01
    cfg = _short(update="discrete", average=20.0, hysteresis=margin)
    with ModelPlant("full") as plant, Learner(_short(update="discrete", average=20.0),
                                              plant=plant) as plain, \
            Learner(cfg, plant=plant) as hys:
        kept = [np.zeros(len(a.theta), dtype=int) for a in plain.agents]   # theta = 0: first
        changed = 0
        for _ in range(12):
            plain.step()
            hys.step()
            for k, bar in zip(kept, plain.theta_bar):
                for m in range(len(bar)):
                    best = int(np.argmax(bar[m]))
                    if bar[m, best] > bar[m, k[m]] + margin:
                        changed += k[m] != best
                        k[m] = best
        policy = hys.policy()
        for p, h, k, bar, agent in zip(plain.agents, hys.agents, kept, plain.theta_bar,
                                       policy.agents):
            assert np.array_equal(p.theta, h.theta)
            assert np.array_equal(agent.greedy_actions[:, 0], agent.actions[k, 0])
            differ = np.flatnonzero(np.any(agent.q != bar, axis=1))
            assert np.array_equal(differ, np.flatnonzero(k != np.argmax(bar, axis=1)))
            assert np.abs(agent.q - bar).max() <= margin + 1e-8
        assert changed > 0                          # kept actions did move
        assert any(np.any(k != np.argmax(b, axis=1)) for k, b in zip(kept, plain.theta_bar))


def test_averaged_run_resumes_bit_for_bit(tmp_path):
    cfg = _short(average=50.0, hysteresis=0.2)
    full, _ = _plain_run(cfg)
    ckpt = tmp_path / "ckpt.npz"

    def stop(e):
        if e.steps == 64:
            raise KeyboardInterrupt
    with ModelPlant("full") as plant, Learner(cfg, plant=plant) as learner:
        with pytest.raises(KeyboardInterrupt):
            learner.run(checkpoint=ckpt, on_eval=stop)
        bar64 = [b.copy() for b in learner.theta_bar]
        kept64 = [k.copy() for k in learner.kept]
        q64 = [a.q for a in learner.policy().agents]
    saved = Policy.load(ckpt)
    assert all(np.array_equal(a.q, q) for a, q in zip(saved.agents, q64))
    with ModelPlant("full") as plant, Learner.resume(saved, plant=plant) as learner:
        assert all(np.array_equal(a, b) for a, b in zip(learner.theta_bar, bar64))
        assert all(np.array_equal(a, b) for a, b in zip(learner.kept, kept64))
        learner.run()
        assert all(np.array_equal(a.theta, f) for a, f in zip(learner.agents, full))


def test_init_scale_keeps_the_greedy_policy_and_shrinks_the_values():
    init = load_policy("decentralized")
    with ModelPlant("simplified") as plant, \
            Learner(_short(init_scale=0.5), init=init, plant=plant) as learner:
        for a, b, c in zip(learner.agents, init.agents, learner.policy().agents):
            np.testing.assert_array_equal(a.theta, 0.5 * b.q)
            np.testing.assert_array_equal(c.greedy_actions, b.greedy_actions)
            assert b.q.min() < -5
    for bad, message in [({"init_scale": 0.0}, "warm-start scale must be"),
                         ({"init_scale": 1.5}, "warm-start scale must be"),
                         ({"average": -1.0}, r"theta average \(control steps\) must be"),
                         ({"hysteresis": -0.1}, "hysteresis margin must be"),
                         ({"learner": "centralized", "average": 10.0},
                          "not available to the centralized learner")]:
        with pytest.raises(ValueError, match=message):
            _short(**bad).check()


def test_the_largest_checkpoint_fits_a_policy_file(tmp_path):
    """MAX_ARMS arms, theta and its average, kept actions, MAX_EVALUATIONS evaluations:
    the checkpoint is written and read back (a policy header holds at most 1 MiB)."""
    cfg = LearnConfig(learner="decentralized", steps=MAX_ARMS * 2, arms=MAX_ARMS, seed=1,
                      update="discrete", average=1e5, hysteresis=0.1)
    with ModelPlant("full") as plant, Learner(cfg, plant=plant) as learner:
        learner.step()
        full = score(np.ones(65, bool), np.full(65, 12.345678901234567))
        learner.curve = [Evaluation(10**8, full, -21.123456789012345,
                                    123456.78901234567)] * MAX_EVALUATIONS
        learner.policy(resume=True).save(tmp_path / "big.npz")
        back = Learner.resume(Policy.load(tmp_path / "big.npz"), plant=plant)
        assert np.array_equal(back.x, learner.x) and len(back.curve) == MAX_EVALUATIONS
        assert all(np.array_equal(a.theta, b.theta) for a, b in zip(back.agents, learner.agents))


def test_the_api_defaults_are_the_recommended_learner():
    """LearnConfig() is what `twolink learn` runs: theta averaged over 200 k steps (none
    for the centralized learner), hysteresis 0.1, warm starts at half the given Q; a
    checkpoint without those settings resumes as it ran (LEGACY)."""
    from twolink.commands import learn as learn_command

    cfg = LearnConfig()
    assert (cfg.average, cfg.hysteresis, cfg.init_scale) == (200_000.0, 0.1, 0.5)
    assert LearnConfig(learner="centralized").average == 0.0
    assert (learn_command.AVERAGE, learn_command.HYSTERESIS, learn_command.INIT_SCALE) == \
        (cfg.average, cfg.hysteresis, cfg.init_scale)
    old = {k: v for k, v in cfg.as_dict().items() if k not in LEGACY}
    assert LearnConfig.from_dict(old).average == 0.0
    assert LearnConfig.from_dict(old).hysteresis == 0.0
