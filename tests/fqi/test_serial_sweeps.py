"""Serial (in-place) sweeps of Alg. 1: the compiled path against a plain loop, the
paper's sweep counts, the CLI option and the provenance it leaves in a policy file."""
import json

import numpy as np
import pytest
from reference_fqi import fuzzy_q_iteration_reference
from reference_serial import matlab_order, serial_q_iteration_reference

from twolink.cli import main
from twolink.synthesis.problems import agent1_problem, agent2_problem, solve
from twolink.synthesis.synthesize import synthesize
from twolink.fqi.fuzzy import Axis
from twolink.fqi.iteration import fuzzy_q_iteration
from twolink.fqi.tables import transition_matrix
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.registry import SHIPPED


def _coarse_agent1():
    """Agent 1's problem (frozen context) on a coarse, non-square grid, shape (5, 4, 4, 3)."""
    axes = (Axis("theta1", tuple(np.deg2rad([-180, -60, 0, 30, 100])), circular=True),
            Axis("dtheta1", tuple(np.deg2rad([-360, 0, 40, 360]))),
            Axis("theta2", tuple(np.deg2rad([-180, -20, 0, 90])), circular=True))
    return agent1_problem(None, axes=axes)


def test_matlab_order_runs_the_first_index_fastest():
    assert matlab_order((2, 3)) == [0, 3, 1, 4, 2, 5]
    assert sorted(matlab_order((5, 4, 4, 3))) == list(range(240))


def test_serial_sweeps_equal_the_in_place_loop():
    problem = _coarse_agent1()
    q_ref, it_ref = serial_q_iteration_reference(problem.grid, problem.next_points,
                                                 problem.rewards)
    res = fuzzy_q_iteration(transition_matrix(problem.grid, problem.next_points),
                            problem.rewards, sweeps="serial", state_shape=problem.grid.shape)
    assert res.converged and res.iterations == it_ref
    np.testing.assert_allclose(res.q, q_ref, rtol=0, atol=1e-12)
    # the order matters: C order, or synchronous sweeps, give other tables and counts
    q_c, it_c = serial_q_iteration_reference(problem.grid, problem.next_points,
                                             problem.rewards, order=range(problem.grid.size))
    q_sync, it_sync = fuzzy_q_iteration_reference(problem.grid, problem.next_points,
                                                  problem.rewards)
    assert np.abs(q_c - q_ref).max() > 1e-6 and np.abs(q_sync - q_ref).max() > 1e-3
    assert it_sync > it_ref


def test_serial_sweeps_reach_the_papers_agent_counts():
    """Section IV-C: agent 2 converges in 49 sweeps and agent 1 in 192; serial sweeps
    with agent 1's frozen context give exactly these (synchronous: 54 and 195)."""
    a2 = solve(agent2_problem(), sweeps="serial")
    a1 = solve(agent1_problem(a2), sweeps="serial")
    a1_prop = solve(agent1_problem(a2, context="propagated"), sweeps="serial")
    assert (a2.info["iterations"], a1.info["iterations"]) == (49, 192)
    assert a1_prop.info["iterations"] < 150
    assert a2.info["sweeps"] == a1.info["sweeps"] == "serial"


def test_the_shipped_policies_stay_synchronous():
    assert {e.sweeps for e in SHIPPED.values()} == {"synchronous"}
    assert all(e.synthesis_options()["sweeps"] == "synchronous" for e in SHIPPED.values())


def test_cli_sweeps_option_is_recorded_in_the_policy(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["synthesize", "decentralized", "--sweeps", "serial", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["path"] == "decentralized_serial.npz"
    assert [out["agents"][a]["iterations"] for a in ("agent2", "agent1")] == [49, 192]
    pol = Policy.load(tmp_path / "decentralized_serial.npz")
    assert pol.meta["sweeps"] == "serial" and pol.meta["refine"] == 1
    assert all(a.info["sweeps"] == "serial" for a in pol.agents)
    ref = synthesize("decentralized", sweeps="serial")
    for a, b in zip(pol.agents, ref.agents):
        np.testing.assert_array_equal(a.q, b.q)
    # the default stays synchronous, and says so
    assert main(["synthesize", "decentralized", "--json"]) == 0
    capsys.readouterr()
    assert Policy.load(tmp_path / "decentralized.npz").meta["sweeps"] == "synchronous"


@pytest.mark.parametrize("argv, message", [
    (["decentralized", "--sweeps", "bogus"], "argument --sweeps: invalid choice: 'bogus'"),
    (["centralized", "--refine", "0"], "argument --refine: must be a positive whole number"),
    (["--ship", "centralized", "--sweeps", "serial"], "--ship takes everything from the registry"),
    (["centralized", "--refine", "4"], "Q-table of 12960000 values (99 MiB) is over the 64 MiB"),
])
def test_bad_sweeps_are_refused_before_any_work(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(["synthesize", *argv])
    except SystemExit as exc:          # argparse's own errors
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and list(tmp_path.iterdir()) == []


def test_bad_sweeps_in_the_library_name_the_choices():
    with pytest.raises(ValueError, match="unknown sweeps 'bogus'; choose one of synchronous, serial"):
        synthesize("centralized", sweeps="bogus")
    with pytest.raises(ValueError, match="refine must be a whole number from 1 to 16, got 0"):
        synthesize("centralized", refine=0)
