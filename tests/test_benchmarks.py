"""The benchmark suite: its problems equal the package's, peers agree with ours, every
row is present with a finite positive figure. No timing is asserted."""
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))   # benchmarks/ is no package dep

from benchmarks import (
    rollouts,
    run,
    synthesis,
    synthesis_common,
    synthesis_peers,
    synthesis_problem,
    synthesis_robust,
    synthesis_scaling,
)
from benchmarks.common import Row


def _by_name(rows):
    return {(r.section, r.name): r for r in rows}


def _positive_finite(rows, allow_zero=("agreement",)):
    for r in rows:
        assert math.isfinite(r.value), r
        if any(a in r.name for a in allow_zero):
            assert r.value >= 0, r
        else:
            assert r.value > 0, r


@pytest.mark.parametrize("name", ["centralized", "agent1"])
def test_peers_solve_the_same_mdp_and_agree(name):
    rows, summary = synthesis_problem.bench_problem(name, repeats=1)
    by = _by_name(rows)
    sec = f"synthesis: {name}"
    for peer in ("quantecon", "mdptoolbox"):
        rel, same = summary["agreement"][peer]
        assert rel <= 1e-10
        assert same == 1.0
        assert (sec, f"{peer} / ours per sweep") in by
    for key in ("model transitions f(c_m,u)", "transition matrix T", "sweeps (to convergence)",
                "ours: time per sweep", "peak memory (synthesis)", "total synthesis"):
        assert (sec, key) in by
    assert by[(sec, "Q-table size")].value == {"centralized": 63504, "agent1": 9072}[name]
    assert summary["layout"] == {"centralized": "factored", "agent1": "fixed"}[name]
    if name == "centralized":        # the package's factored sweeps against the references
        assert summary["max_dq"]["scipy"] <= 1e-12 and summary["max_dq"]["fixed"] <= 1e-12
        assert summary["greedy_bins_differ"] == {"scipy": 0, "fixed": 0}
        for key in ("factored, 1 thread: time per sweep", "fixed layout: time per sweep",
                    "quantecon / factored, 1 thread per sweep",
                    "quantecon / fixed layout per sweep", "fixed layout: bytes per sweep",
                    "equivalent bandwidth: fixed layout's bytes / ours time per sweep"):
            assert (sec, key) in by
        # "ours" runs on the package's threads (one below PARALLEL_MIN_WORK); explicit
        # one- and two-thread rows stay beside it.
        assert summary["threads"] == 1
        assert "1 thread" in by[(sec, "ours: time per sweep")].note
        if synthesis_common.MAX_THREADS > 1:
            threads = synthesis_common.MAX_THREADS
            assert (sec, f"factored, {threads} threads: time per sweep") in by
        assert summary["sweep_bytes"] < summary["fixed_sweep_bytes"]
        assert summary["equivalent_gbs"] == pytest.approx(
            summary["fixed_sweep_bytes"] / summary["per_sweep"]["ours"] / 1e9)
    _positive_finite(rows)


def test_synthesize_end_to_end_rows_split_the_total():
    rows, summary = synthesis.bench_synthesize(repeats=1, models=("simplified",),
                                               contended=False)
    by = _by_name(rows)
    sec = "synthesis: synthesize('centralized') end to end"
    s = summary["simplified"]
    assert by[(sec, "model=simplified: total")].value == s["total"]
    assert s["iterations"] == 80 and s["threads"] == 1
    assert s["transition_seconds"] + s["sweep_seconds"] <= s["total"]
    _positive_finite(rows)


def test_sweep_bandwidth_rows_are_bytes_over_time():
    rows, summary = synthesis_problem.bench_problem("agent2", repeats=1)
    by = _by_name(rows)
    sec = "synthesis: agent2"
    moved = summary["sweep_bytes"]
    assert by[(sec, "ours: bytes per sweep")].value == pytest.approx(moved / 2**20)
    assert summary["sweep_gbs"] == pytest.approx(moved / summary["per_sweep"]["ours"] / 1e9)
    assert by[(sec, "sweep / copy bandwidth")].value == pytest.approx(
        summary["sweep_gbs"] / summary["copy_gbs"])


def test_sweep_bytes_count_the_table_and_the_vectors():
    from twolink.fqi.tables import transition_table
    p = synthesis_common.BUILDERS["agent2"](1)
    t = transition_table(p.grid, p.next_points)
    rows, n_x = t.shape
    assert synthesis_problem.sweep_bytes(t) == \
        rows * t.index.shape[1] * (4 + 8) + 24 * rows + 16 * n_x


def test_package_threads_follow_the_summed_sweep_work():
    from twolink.fqi.factored import PARALLEL_MIN_WORK, factored_table, sweep_work
    p = synthesis_common.PACKAGE["centralized"][0]()
    t = factored_table(p.grid, p.next_points)
    assert sweep_work(t) < PARALLEL_MIN_WORK
    assert synthesis_common.package_threads(t) == synthesis_common.package_threads([t]) == 1
    assert synthesis_common.package_threads([t] * 8) == synthesis_common.MAX_THREADS


def test_worst_case_rows_and_models():
    models = synthesis_robust.worst_case_models(8)
    assert len({(m.m1, m.m2, m.b1) for m in models}) == 8
    rows, summary = synthesis_robust.bench_worst_case(2, repeats=1)
    names = {r.name for r in rows}
    assert {"total robust synthesis (worst)", "sweeps to convergence (worst)",
            "sweep bandwidth", "total robust synthesis (mean)"} <= names
    assert summary["k"] == 2 and summary["iterations"] > 0
    assert summary["threads"] == 1                       # 2 x 0.64 M gathered values
    assert {f"factored, {n}: sweeps (worst)" for n in ("1 thread", "2 threads")
            if n == "1 thread" or synthesis_common.MAX_THREADS > 1} <= names
    assert {"fixed layout: total robust synthesis (worst)", "fixed layout agreement max|dQ|",
            "fixed / factored total"} <= names
    assert summary["max_dq"] <= 1e-12 and summary["greedy_bins_differ"] == 0
    _positive_finite(rows)


def test_robust_synthesis_rows_hold_the_fixed_layout_against_synthesize():
    """The robust ``synthesize()`` section (K models drawn as the package draws them,
    :func:`twolink.synthesis.problems.parameter_draws`): its parts within the call, the
    fixed-width layout's Q equal to ``synthesize()``'s."""
    rows, summary = synthesis_robust.bench_robust_synthesis((2,), repeats=1)
    s = summary[2]
    assert s["iterations"] > 0 and s["threads"] in (1, synthesis_common.MAX_THREADS)
    assert s["model_seconds"] + s["table_seconds"] + s["sweep_seconds"] <= s["total"]
    assert s["fixed"]["iterations"] == s["iterations"]
    assert s["fixed"]["max_dq"] <= 1e-12 and s["fixed"]["greedy_bins_differ"] == 0
    sec = "synthesis: robust synthesis, centralized on (6), worst case over K = 2"
    assert {(sec, "total synthesize()"), (sec, "fixed layout: total (problems + table + sweeps)")
            } <= set(_by_name(rows))
    _positive_finite(rows)


def test_mdptoolbox_full_setup_gives_the_same_values():
    p = synthesis_common.BUILDERS["agent2"](1)
    from twolink.fqi.tables import transition_matrix
    t = transition_matrix(p.grid, p.next_points)
    fast = synthesis_peers.mdptoolbox_solver(t, p.rewards, 30, full_setup=False)()
    full = synthesis_peers.mdptoolbox_solver(t, p.rewards, 30, full_setup=True)()
    np.testing.assert_array_equal(fast[0], full[0])


def test_scaling_runs_what_fits_and_predicts_the_rest():
    rows, records = synthesis_scaling.bench_scaling((1,), (1, 2), estimate_to=3)
    names = {r.name for r in rows}
    assert {"centralized 1x bins: time", "decentralized 2x bins: time",
            "centralized 2x bins: predicted memory", "centralized 3x bins: Q size"} <= names
    q = {(r["scheme"], r["k"]): r["q_size"] for r in records}
    assert q[("centralized", 1)] == 63504 and q[("decentralized", 1)] == 9072 + 252
    assert q[("centralized", 2)] == 24 * 24 * 13 * 13 * 9
    pred = [r["predicted_bytes"] for r in records if r["scheme"] == "centralized"][1:]
    assert all(b > a > 0 for a, b in zip(pred, pred[1:]))
    _positive_finite(rows)


def test_rollout_rows_and_json(tmp_path):
    path = tmp_path / "bench.json"
    assert run.main(["--quick", "--only", "rollouts", "--json", str(path)]) == 0
    data = json.loads(path.read_text())
    assert data["mode"] == "quick" and data["machine"]["cpu_count"] >= 1
    rows = [Row(**r) for r in data["rows"]]
    names = {r.name for r in rows}
    assert {"closed loop: physics steps/s", "open loop mujoco.rollout: physics steps/s",
            "closed / open loop", "closed loop: physics steps/s per thread",
            "simplified: sample periods/s", "full: sample periods/s"} <= names
    _positive_finite(rows)


def test_open_loop_reference_does_the_closed_loop_physics():
    """With the closed loop's torques, open-loop mujoco.rollout reaches the same states
    wherever the speed limit never acted (so the two do the same work)."""
    import mujoco
    from mujoco import rollout as mj_rollout

    from twolink.sim.plants import MujocoPlant
    from twolink.sim.rollout import rollout

    x0 = rollouts.initial_states(8) * 0.2
    plant = MujocoPlant(nthread=1)
    traj = rollout(run_policy(), plant, x0, duration=0.5)
    n = plant.nstep
    state0 = np.zeros((8, mujoco.mj_stateSize(plant.model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    state0[:, 1:3], state0[:, 3:5] = x0[:, :2], x0[:, 2:]
    state, _ = mj_rollout.rollout(plant.model, mujoco.MjData(plant.model), state0,
                                  np.repeat(traj.u, n, axis=1))
    plant.close()
    free = np.all(np.abs(traj.x[..., 2:]) < 2 * np.pi - 1e-6, axis=(1, 2))
    assert free.any()
    wrapped = np.angle(np.exp(1j * (state[free, n - 1::n, 1:3] - traj.x[free, 1:, :2])))
    np.testing.assert_allclose(wrapped, 0, atol=1e-9)


def run_policy():
    return rollouts._policy()


def test_render_rows():
    from benchmarks import render
    from twolink.viz.render import RenderError
    try:
        rows, summary = render.bench_render(frames=2, repeats=1)
    except RenderError as exc:
        pytest.skip(str(exc))
    names = {r.name for r in rows}
    assert {"bare mujoco.Renderer, same scene", "twolink Renderer", "twolink / bare, same scene",
            "mp4 encoding 640x480"} <= names
    assert {r.section for r in rows} >= {"rendering: 320x240", "rendering: 640x480"}
    _positive_finite(rows)


def test_one_throughput_measurement_for_the_report_and_the_benchmarks(monkeypatch):
    from twolink.studies import throughput
    from twolink.studies.mismatch import measure as mismatch

    assert rollouts.measure is throughput.measure and mismatch.measure is throughput.measure
    calls = []

    def spy(policy, x0, **kwargs):
        calls.append((x0.shape, kwargs))
        return throughput.measure(policy, x0, **kwargs)

    monkeypatch.setattr(rollouts, "measure", spy)
    rows, summary = rollouts.bench_rollouts(batch=4, duration=0.2, repeats=1, threads=[1])
    assert calls == [((4, 4), dict(samples=4, nthread=1, repeats=1))]
    by = _by_name(rows)
    sec = "rollouts: mujoco, 1 thread"
    assert by[(sec, "closed / open loop")].value == pytest.approx(
        summary[1]["closed_steps_per_s"] / summary[1]["open_steps_per_s"], rel=1e-12)


def test_throughput_figures_are_the_steps_over_the_times():
    from twolink.studies.throughput import measure

    x0 = rollouts.initial_states(6) * 0.3
    tp = measure(run_policy(), x0, samples=3, nthread=1, repeats=1)
    d = tp.as_dict()
    assert d["mujoco_steps"] == 6 * 3 * d["nstep"] and d["nstep"] == 10
    assert d["closed_loop_steps_per_s"] == d["mujoco_steps"] / d["closed_loop_seconds"]
    assert d["open_loop_steps_per_s"] == d["mujoco_steps"] / d["open_loop_seconds"]
    assert d["ratio_closed_to_open"] == d["open_loop_seconds"] / d["closed_loop_seconds"]
    # The policy's own time is measured apart (best of the repeats), so on a loaded machine
    # it may even exceed the closed loop's: only its share is defined by the others.
    assert d["policy_seconds"] > 0
    assert d["policy_share"] == d["policy_seconds"] / d["closed_loop_seconds"]
    for bad in (dict(x0=x0[0]), dict(samples=0), dict(nthread=0), dict(samples=1.5)):
        kwargs = dict(dict(x0=x0, samples=3, nthread=1), **bad)
        with pytest.raises(ValueError):
            measure(run_policy(), kwargs.pop("x0"), repeats=1, **kwargs)


def test_vector_env_rows_and_ratio_is_the_times():
    """The vector-env section: its rows, and the ratio is the raw time over the env's."""
    from benchmarks import vector_env

    rows, summary = vector_env.bench_vector_env(num_envs=4, samples=3, repeats=1, threads=[1])
    by = _by_name(rows)
    sec = "vector env: 4 arms, 1 thread"
    for name in ("TwoLinkVectorEnv: arm-steps/s", "raw mujoco.rollout, one call per Ts: arm-steps/s",
                 "vector env / raw mujoco.rollout", "SyncVectorEnv of single envs: arm-steps/s",
                 "vector env / SyncVectorEnv"):
        assert (sec, name) in by
    m = summary[1]
    assert by[(sec, "vector env / raw mujoco.rollout")].value == pytest.approx(
        m["seconds"]["raw"] / m["seconds"]["vector"], rel=1e-12)
    assert m["vector_steps_per_s"] == pytest.approx(4 * 3 / m["seconds"]["vector"], rel=1e-12)
    _positive_finite(rows)
    assert "vector_env" in run.SECTIONS and run.MODES["quick"]["vector_samples"] >= 1


def test_evaluation_rows_and_ratio_is_the_times():
    """evaluate() against the raw rollout of the same controller and states: both rows,
    the ratio is their times, and both runs settle alike."""
    from benchmarks import evaluation

    rows, summary = evaluation.bench_evaluation(controllers=("lqr",), states=5, horizon=0.5,
                                                repeats=1, nthread=1)
    by = _by_name(rows)
    sec = "evaluation: lqr, 5 states x 10 Ts, 1 thread"
    for name in ("evaluate(): seconds", "raw rollout(): seconds", "evaluate / raw rollout",
                 "open loop mujoco.rollout: physics steps/s",
                 "evaluate / open-loop mujoco.rollout steps/s"):
        assert (sec, name) in by
    s = summary["lqr"]
    assert by[(sec, "evaluate / raw rollout")].value == pytest.approx(
        s["evaluate_seconds"] / s["raw_seconds"], rel=1e-12)
    assert s["same_settle"] and s["mujoco_steps"] > 0
    _positive_finite(rows)
    assert "evaluation" in run.SECTIONS and run.MODES["quick"]["eval_states"] >= 1


def test_mpc_rows_are_milliseconds_per_step():
    """The MPC section: ms per step of every kind, the settle time at the limit."""
    pytest.importorskip("casadi")
    from benchmarks import mpc

    rows, summary = mpc.bench_mpc(states=mpc.QUICK_STATES, duration=0.5, expand=False)
    by = _by_name(rows)
    sec = "mpc: x0 = [-0.175, 0.785, 0, 0], 10 steps"
    for name in ("first step (search and plan)", "later steps: median",
                 "later steps: 95th percentile", "later steps: most"):
        assert by[(sec, name)].unit == "ms"
    s = summary[str(mpc.QUICK_STATES[0])]
    assert s["median_ms"] <= s["p95_ms"] <= s["max_ms"]
    assert s["settle"] == pytest.approx(s["limit"]) == pytest.approx(0.25)
    assert summary["real_time"] == (s["first_ms"] <= 50 and s["max_ms"] <= 50)
    _positive_finite([r for r in rows if r.name != "steps over Ts"])
    assert "mpc" in run.SECTIONS


def test_leaderboard_rows_and_ratios_are_the_times():
    """A leaderboard row against raw mujoco.rollout of the same physics steps, and one
    controller through every level: every row there, ratios the times' ratios."""
    from benchmarks import leaderboard

    rows, summary = leaderboard.bench_leaderboard(plants=2, states=3, repeats=1,
                                                  through=("pd",), nthread=1)
    by = _by_name(rows)
    sec = "leaderboard: lqr under medium, 2 plants x 3 states x 100 Ts, 1 thread"
    assert summary["physics_steps"] == 2 * 3 * 100 * 10
    for mode in ("plain", "compensated"):
        ratio = by[(sec, f"row ({mode}) / raw mujoco.rollout steps/s")].value
        assert ratio == pytest.approx(summary["raw_seconds"]
                                      / summary["rows"][mode]["seconds"], rel=1e-12)
    through = [r for r in rows if r.section.startswith("leaderboard: pd through")]
    assert len([r for r in through if r.name.startswith("row ")]) == 7   # pd has a model
    assert set(summary["through"]["pd"]["rows"]) == {
        "none/plain", *(f"{lv}/{m}" for lv in ("easy", "medium", "hard")
                        for m in ("plain", "compensated"))}
    _positive_finite(rows)
    assert "leaderboard" in run.SECTIONS


def test_merge_keeps_the_other_sections_of_the_results_file(tmp_path):
    path = tmp_path / "results.json"
    old = {"mode": "full", "command": "python -m benchmarks.run", "machine": {"cpu_count": 2},
           "seconds": {"rollouts": 5.0, "leaderboard": 9.0, "total": 14.0},
           "rows": [{"section": "rollouts: mujoco, 1 thread", "name": "a", "value": 1.0,
                     "unit": "x", "note": ""},
                    {"section": "leaderboard: old", "name": "b", "value": 2.0, "unit": "x",
                     "note": ""}],
           "summary": {"rollouts": {"1": 1}, "leaderboard": {"old": True}}}
    path.write_text(json.dumps(old))
    new = {"mode": "quick", "command": "c", "machine": {"cpu_count": 2},
           "seconds": {"leaderboard": 3.0, "total": 3.0},
           "rows": [{"section": "leaderboard: new", "name": "c", "value": 3.0, "unit": "x",
                     "note": ""}], "summary": {"leaderboard": {"new": True}}}
    merged = run._merged(new, run._earlier(path, ["leaderboard"]))
    assert [r["name"] for r in merged["rows"]] == ["a", "c"]
    assert merged["summary"] == {"rollouts": {"1": 1}, "leaderboard": {"new": True}}
    assert merged["seconds"] == {"rollouts": 5.0, "leaderboard": 3.0, "total": 3.0}
    assert merged["earlier"]["sections"] == ["rollouts"]
    assert merged["earlier"]["mode"] == "full"
    path.write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a benchmark results file"):
        run._earlier(path, ["leaderboard"])
    with pytest.raises(SystemExit):
        run.main(["--only", "leaderboard", "--merge"])
