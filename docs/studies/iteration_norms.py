"""Alg. 1's sweep count under different norms in its stopping test ||Q_l - Q_(l-1)|| <= delta,
with synchronous sweeps (as printed), and with serial sweeps (each Q(m, u) overwritten at
once, bins in Matlab's order, as ApproxRL's fuzzyqi.m; infinity norm) in the last column.

Run: .venv/bin/python docs/studies/iteration_norms.py
Used in docs/findings/reproduction.md to show which reading of the paper's norm its
iteration counts fit.
"""
import numpy as np

from twolink.arm.parameters import DELTA, GAMMA
from twolink.control.problems import (
    agent1_problem,
    agent2_problem,
    centralized_problem,
    solve,
)
from twolink.fqi.iteration import fuzzy_q_iteration
from twolink.fqi.tables import transition_matrix
from twolink.studies.reproduce import paper

NORMS = {"inf": lambda d: np.abs(d).max(), "2": np.linalg.norm,
         "1": lambda d: np.abs(d).sum(), "rms": lambda d: np.sqrt((d ** 2).mean())}


def sweeps(problem, norm, max_iterations=5000):
    t = transition_matrix(problem.grid, problem.next_points)
    r = problem.rewards.reshape(-1)
    n_u = problem.rewards.shape[1]
    q = np.zeros_like(r)
    for ell in range(1, max_iterations + 1):
        q_new = r + GAMMA * (t @ q.reshape(-1, n_u).max(1))
        change = NORMS[norm](q_new - q)
        q = q_new
        if change <= DELTA:
            return ell
    return None


def serial_sweeps(problem):
    """Sweeps of serial (in-place) Alg. 1 with the infinity norm."""
    t = transition_matrix(problem.grid, problem.next_points)
    return fuzzy_q_iteration(t, problem.rewards, sweeps="serial",
                             state_shape=problem.grid.shape).iterations


def main():
    a2_problem = agent2_problem()
    a2 = solve(a2_problem)
    a2_serial = solve(a2_problem, sweeps="serial")
    problems = {"centralized": centralized_problem(), "agent1 (frozen)": agent1_problem(a2),
                "agent1 (propagated)": agent1_problem(a2, context="propagated"),
                "agent2": a2_problem}
    # agent 1's propagated context reads agent 2's policy: serial sweeps use the serial one
    serial_problems = dict(problems)
    serial_problems["agent1 (propagated)"] = agent1_problem(a2_serial, context="propagated")
    print(f"{'problem':<22}{'paper':>7}" + "".join(f"{n + '-norm':>10}" for n in NORMS)
          + f"{'serial inf':>12}")
    for name, prob in problems.items():
        ref = paper.ITERATIONS[name.split()[0]]
        print(f"{name:<22}{ref:>7}" + "".join(f"{sweeps(prob, n):>10}" for n in NORMS)
              + f"{serial_sweeps(serial_problems[name]):>12}")


if __name__ == "__main__":
    main()
