"""Robust synthesis: Q(m, u) = min_k (or mean_k) [rho_k + gamma T_k V] over K parameter draws,
held against a plain loop over the K models written here (its own draws, its own numpy
transitions, memberships from (13) as printed, equal to round-off); its provenance; the
CLI's checks. That the shipped robust files re-synthesise bit for bit is
tests/test_policy.py's test over the whole registry, and --ship's below."""
import json
import math

import numpy as np
import pytest
from reference_fqi import dense_memberships

from twolink.arm import parameter_file
from twolink.arm.dynamics import full_acceleration
from twolink.arm.integrate import sample_step
from twolink.arm.parameters import TABLE_I
from twolink.arm.task import agent_reward
from twolink.cli import main
from twolink.commands import synthesize as synthesize_command
from twolink.synthesis.problems import (
    MAX_ROBUST_BYTES,
    agent1_problem,
    agent2_problem,
    parameter_draws,
    robust_bytes,
    solve_robust,
)
from twolink.synthesis.synthesize import synthesize
from twolink.fqi import fuzzy
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.registry import SHIPPED

NAMES = ("l1", "l2", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2")   # the physical ones


def reference_draws(p, k, spread, seed):
    """The centre, then K - 1 draws: every physical parameter times 1 + U(-spread, spread),
    in the order of NAMES, from one generator."""
    rng = np.random.default_rng(seed)
    out = [p]
    for _ in range(k - 1):
        out.append(p.scaled(**{n: 1.0 + float(rng.uniform(-spread, spread)) for n in NAMES}))
    return out


def reference_robust(grid, points_k, rewards_k, mode, gamma=0.98, delta=0.01):
    """Synchronous sweeps of Alg. 1 over K models, one (m, u) at a time, as written:
    Q'(m, u) = min over k (or the sum over k in order, divided by K) of
    rho_k(m, u) + gamma sum_m~ mu_m~(f_k(c_m, u)) max_u~ Q(m~, u~). Returns (Q, sweeps)."""
    n_x, n_u = rewards_k[0].shape
    mu = [[[[(t, w) for t, w in enumerate(dense_memberships(grid, pts[m, j])) if w]
            for j in range(n_u)] for m in range(n_x)] for pts in points_k]
    q = np.zeros((n_x, n_u))
    sweeps = 0
    while True:
        v = [max(row) for row in q.tolist()]
        new = np.empty_like(q)
        for m in range(n_x):
            for j in range(n_u):
                values = []
                for k in range(len(points_k)):
                    total = 0.0
                    for t, w in mu[k][m][j]:
                        total += w * v[t]
                    values.append(float(rewards_k[k][m, j]) + gamma * total)
                if mode == "worst":
                    new[m, j] = min(values)
                else:
                    acc = 0.0
                    for x in values:
                        acc += x
                    new[m, j] = acc / len(values)
        sweeps += 1
        change = float(np.abs(new - q).max())
        q = new
        if change <= delta:
            return q, sweeps


def _agent2_reference(p, grid):
    """Agent 2's transitions on the full model (6), link 1 at rest, by the numpy RK4."""
    c = grid.centers()
    x = np.stack([np.zeros(len(c)), c[:, 0], np.zeros(len(c)), c[:, 1]], -1)
    tau = np.stack([np.zeros(3), [-p.tau2_max, 0.0, p.tau2_max]], -1)
    nxt = sample_step(full_acceleration, p, x[:, None, :], tau[None, :, :])
    return nxt[..., [1, 3]], agent_reward(nxt, 2)


def test_draws_are_the_centre_then_joint_uniform_changes():
    draws = parameter_draws(TABLE_I, 5, 0.2, 11)
    assert draws == reference_draws(TABLE_I, 5, 0.2, 11)
    assert draws[0] is TABLE_I and len(set(draws)) == 5
    for d in draws[1:]:
        ratios = np.array([getattr(d, n) / getattr(TABLE_I, n) for n in NAMES])
        assert np.all(np.abs(ratios - 1) <= 0.2) and np.all(ratios != 1)
        assert (d.tau1_max, d.tau2_max) == (TABLE_I.tau1_max, TABLE_I.tau2_max)
    assert parameter_draws(TABLE_I, 3, 0.2, 12) != draws[:3]
    assert parameter_draws(TABLE_I, 3, 0.0, 11) == [TABLE_I] * 3


@pytest.mark.parametrize("mode", ["worst", "mean"])
def test_agent2_robust_equals_the_plain_loop(mode):
    models = parameter_draws(TABLE_I, 3, 0.3, 5)
    agent = solve_robust([agent2_problem(m, "full", compiled=True) for m in models], mode=mode)
    grid = agent.grid
    refs = [_agent2_reference(m, grid) for m in models]
    q, sweeps = reference_robust(grid, [r[0] for r in refs], [r[1] for r in refs], mode)
    # memberships of (13) as printed round differently from the fast path's 1 - w
    np.testing.assert_allclose(agent.q, q, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.argmax(agent.q, 1), np.argmax(q, 1))
    assert agent.info["iterations"] == sweeps
    assert agent.info["robust"] == mode and agent.info["draws"] == 3


def test_agent1_robust_on_a_coarse_grid_equals_the_plain_loop():
    """Frozen context on a coarse grid: link 1 moves under (6) with link 2 held, theta2
    and tau2 carried over."""
    axes = (fuzzy.Axis("theta1", np.deg2rad([-180.0, -90.0, 0.0, 90.0]), True),
            fuzzy.Axis("dtheta1", np.array([-2 * math.pi, 0.0, 2 * math.pi]), False),
            fuzzy.Axis("theta2", np.deg2rad([-180.0, 0.0]), True))
    models = parameter_draws(TABLE_I, 4, 0.2, 8)
    agent = solve_robust([agent1_problem(None, m, "full", axes=axes, compiled=True)
                          for m in models], mode="worst")
    grid = agent.grid
    c = grid.centers()
    points, rewards = [], []
    for p in models:
        x = np.stack([c[:, 0], c[:, 2], c[:, 1], np.zeros(len(c))], -1)
        tau = np.zeros((len(c), 3, 2))
        tau[:, :, 0] = [-p.tau1_max, 0.0, p.tau1_max]
        tau[:, :, 1] = c[:, 3:4]

        def held(pp, s, t):
            a = full_acceleration(pp, s, t)
            return np.stack([a[..., 0], 0.0 * a[..., 1]], -1)
        nxt = sample_step(held, p, x[:, None, :], tau)
        points.append(np.stack([nxt[..., 0], nxt[..., 2], nxt[..., 1],
                                np.broadcast_to(c[:, None, 3], nxt.shape[:-1])], -1))
        rewards.append(agent_reward(nxt, 1))
    q, sweeps = reference_robust(grid, points, rewards, "worst")
    np.testing.assert_allclose(agent.q, q, rtol=0, atol=1e-12)
    assert agent.info["iterations"] == sweeps


def test_one_draw_is_the_nominal_synthesis_and_worst_is_below_mean():
    nominal = Policy.load(SHIPPED["decentralized_full"].file)
    one = synthesize("decentralized", model="full", robust="worst", draws=1)
    for a, b in zip(one.agents, nominal.agents):    # one theta1 slice shifted: round-off
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(a.greedy_actions, b.greedy_actions)
        assert a.info["iterations"] == b.info["iterations"]
    worst = synthesize("decentralized", model="full", robust="worst", draws=4, spread=0.2,
                       seed=3)
    mean = synthesize("decentralized", model="full", robust="mean", draws=4, spread=0.2,
                      seed=3)
    a2w, a2m = worst.agents[0], mean.agents[0]
    # the min of the K backups is at most their mean, sweep by sweep (rho <= 0, Q_0 = 0,
    # so Q only decreases and the worst case, sweeping longer, ends lower still)
    assert a2w.info["iterations"] >= a2m.info["iterations"]
    assert np.all(a2w.q <= a2m.q) and np.any(a2w.q < a2m.q - 0.1)


def test_provenance_records_the_draws_and_keeps_the_centre():
    pol = synthesize("decentralized", model="full", robust="mean", draws=3, spread=0.15,
                     seed=21, context="propagated")
    meta = pol.meta
    assert meta["model"] == "full" and meta["context"] == "propagated"
    assert meta["parameters"] == TABLE_I.as_dict()
    r = meta["robust"]
    assert (r["mode"], r["draws"], r["spread"], r["seed"], r["draw_0"]) == \
        ("mean", 3, 0.15, 21, "centre")
    assert r["perturbed"] == list(NAMES)
    assert r["models"] == [p.as_dict() for p in reference_draws(TABLE_I, 3, 0.15, 21)]
    json.dumps(meta)                                    # the header is JSON


@pytest.mark.parametrize("name", ["centralized_robust", "decentralized_robust"])
def test_shipped_robust_files_record_their_registry_entry(name):
    entry = SHIPPED[name]
    meta = Policy.load(entry.file).meta
    assert (meta["robust"]["mode"], meta["robust"]["draws"], meta["robust"]["spread"],
            meta["robust"]["seed"]) == (entry.robust, entry.draws, entry.spread, entry.seed)
    assert (entry.robust, entry.draws, entry.spread, entry.model) == ("worst", 8, 0.2, "full")
    assert meta["parameters"] == TABLE_I.as_dict() and meta["model"] == "full"


def test_ship_rebuilds_a_robust_policy_bit_for_bit(tmp_path, monkeypatch, capsys):
    import twolink.resources
    original = Policy.load(SHIPPED["centralized_robust"].file)
    monkeypatch.setattr(twolink.resources, "shipped_policy_dir", lambda: tmp_path)
    monkeypatch.setattr(synthesize_command, "source_checkout", lambda: tmp_path)
    assert main(["synthesize", "--ship", "centralized_robust", "--json"]) == 0
    written = Policy.load(tmp_path / "centralized_full_worst8-0.2-seed2006.npz")
    np.testing.assert_array_equal(written.agents[0].q, original.agents[0].q)
    assert written.agents[0].info["iterations"] == original.agents[0].info["iterations"]
    assert written.meta["robust"] == original.meta["robust"]
    assert json.loads(capsys.readouterr().out)[0]["agents"]["centralized"]["draws"] == 8


def test_identified_model_takes_the_file_and_records_it(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    fitted = TABLE_I.scaled(m2=1.1, b1=0.9)
    parameter_file.save(tmp_path / "arm.json", fitted, provenance={"source": "test"})
    assert main(["synthesize", "decentralized", "--model", "identified", "--params",
                 "arm.json", "--robust", "worst", "--draws", "2", "--seed", "4",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["path"] == "decentralized_identified_robust.npz"
    pol = Policy.load(tmp_path / out["path"])
    assert pol.meta["model"] == "identified" and pol.meta["dynamics"] == "full"
    assert pol.meta["parameters"] == fitted.as_dict()
    src = pol.meta["parameters_source"]
    assert src["provenance"] == {"source": "test"}
    assert src["sha256"] == json.loads((tmp_path / "arm.json").read_text())["sha256"]
    assert pol.meta["robust"]["models"][0] == fitted.as_dict()
    # the same as the full model (6) with those parameters
    again = synthesize("decentralized", fitted, model="full", robust="worst", draws=2,
                       spread=0.2, seed=4)                  # the CLI's default spread
    for a, b in zip(pol.agents, again.agents):
        np.testing.assert_array_equal(a.q, b.q)


def test_robust_memory_is_estimated_before_any_work():
    import tracemalloc
    synthesize("centralized", model="full", robust="worst", draws=1)     # warm the kernels
    tracemalloc.start()
    try:
        synthesize("centralized", model="full", robust="worst", draws=3, spread=0.2)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert 0.9 * robust_bytes("centralized", 1, 3) < peak <= robust_bytes("centralized", 1, 3)
    assert robust_bytes("centralized", 1, 8) < MAX_ROBUST_BYTES
    per_model = robust_bytes("centralized", 1, 2) - robust_bytes("centralized", 1, 1)
    assert robust_bytes("centralized", 1, 16) - robust_bytes("centralized", 1, 8) == 8 * per_model
    assert robust_bytes("centralized", 1, 1000) > MAX_ROBUST_BYTES
    with pytest.raises(ValueError, match="spread must lie in"):
        synthesize("centralized", robust="worst", draws=2, spread=0.9)
    with pytest.raises(ValueError, match="robust synthesis only"):
        synthesize("centralized", draws=3)
    with pytest.raises(ValueError, match="at least one problem"):
        solve_robust([])
    with pytest.raises(ValueError, match="one grid and one action set"):
        solve_robust([agent2_problem(), agent2_problem(TABLE_I.scaled(tau2_max=2.0))])


@pytest.mark.parametrize("argv, message", [
    (["centralized", "--draws", "4"], "--draws applies to a robust synthesis only"),
    (["centralized", "--spread", "0.1", "--seed", "3"],
     "--spread, --seed apply to a robust synthesis only"),
    (["centralized", "--robust", "worst", "--spread", "0.9"], "--spread must lie in [0, 0.9)"),
    (["centralized", "--robust", "worst", "--spread", "-0.1"], "--spread must lie in"),
    (["centralized", "--robust", "worst", "--spread", "nan"], "--spread must be a number"),
    (["centralized", "--robust", "worst", "--draws", "0"], "--draws must be a positive whole number, got 0"),
    (["centralized", "--robust", "worst", "--draws", "2.5"], "--draws must be a whole number"),
    (["centralized", "--robust", "mean", "--draws", "1000"],
     "--draws 1000: the transitions of 1000 centralized models take about"),
    (["centralized", "--robust", "worst", "--seed", "-1"], "--seed must be a non-negative"),
    (["centralized", "--robust", "worst", "--sweeps", "serial"], "synchronous sweeps only"),
    (["centralized", "--model", "identified"], "--model identified needs --params FILE"),
    (["centralized", "--params", "missing.json"], "missing.json: no such file"),
    (["--ship", "centralized_robust", "--draws", "3"], "--ship takes everything"),
])
def test_bad_robust_input_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys, argv,
                                                         message):
    monkeypatch.chdir(tmp_path)
    assert main(["synthesize", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("twolink synthesize: error:") and message in err, err
    assert len(err.splitlines()) == 1 and list(tmp_path.iterdir()) == []


def test_a_corrupted_parameter_file_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    parameter_file.save(tmp_path / "arm.json", TABLE_I, provenance={})
    text = (tmp_path / "arm.json").read_text().replace('"m1": 1.25', '"m1": 1.5')
    (tmp_path / "arm.json").write_text(text)
    assert main(["synthesize", "centralized", "--model", "identified", "--params",
                 "arm.json"]) == 2
    err = capsys.readouterr().err.strip()
    assert "arm.json" in err and "sha256" in err and len(err.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.json"]


@pytest.mark.parametrize("model", ["simplified", "full"])
def test_one_theta1_slice_shifted_gives_every_transition(model):
    """The robust path integrates one theta1 slice of the grid and shifts it (the arm is
    horizontal: nothing depends on theta1): the numpy RK4 of every pair, to round-off."""
    def close(a, b):
        d = a.next_points - b.next_points
        d[..., 0] = np.mod(d[..., 0] + np.pi, 2 * np.pi) - np.pi
        assert np.abs(d).max() < 1e-13
        np.testing.assert_array_equal(a.rewards, b.rewards)
    from twolink.synthesis.problems import centralized_problem
    close(centralized_problem(TABLE_I, model), centralized_problem(TABLE_I, model, compiled=True))
    p = TABLE_I.scaled(m2=1.2, I1=0.8)
    a2 = solve_robust([agent2_problem(p, model)])
    for context in ("frozen", "propagated"):
        close(agent1_problem(a2, p, model, context),
              agent1_problem(a2, p, model, context, compiled=True))
