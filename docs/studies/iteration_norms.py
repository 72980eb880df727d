"""Alg. 1's sweep count under different norms in its stopping test ||Q_l - Q_(l-1)|| <= delta,
with synchronous sweeps (as printed), and with serial sweeps (each Q(m, u) overwritten at
once, bins in Matlab's order, as ApproxRL's fuzzyqi.m; infinity norm) in the last column,
for the paper's problems synthesised on the simplified model (11) and on the full model (6).

``--json PATH`` also writes the counts to PATH (schema ``twolink.iteration_norms``,
version 1), from which ``python docs/generate.py`` writes the iteration-count part of
docs/results/reproduction.md.

Run: .venv/bin/python docs/studies/iteration_norms.py
     [--json renders/iteration_norms/iteration_norms.json]   (about 15 s)
"""
import argparse
import time

import numpy as np

from twolink.arm.parameters import DELTA, GAMMA
from twolink.artifacts import check_outputs, provenance, write_json
from twolink.synthesis.problems import (
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
MODELS = ("simplified", "full")
#: What the --json file calls itself; docs/generate.py refuses any other.
SCHEMA, VERSION = "twolink.iteration_norms", 1


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


def measure(model: str) -> list:
    """One row per problem of ``model``: its sweeps under each norm and serial."""
    a2_problem = agent2_problem(model=model)
    a2 = solve(a2_problem)
    a2_serial = solve(a2_problem, sweeps="serial")
    problems = {"centralized": centralized_problem(model=model),
                "agent1 (frozen)": agent1_problem(a2, model=model),
                "agent1 (propagated)": agent1_problem(a2, model=model, context="propagated"),
                "agent2": a2_problem}
    # agent 1's context reads agent 2's policy: serial sweeps use the serial one
    serial_problems = {"centralized": problems["centralized"],
                       "agent1 (frozen)": agent1_problem(a2_serial, model=model),
                       "agent1 (propagated)": agent1_problem(a2_serial, model=model,
                                                             context="propagated"),
                       "agent2": a2_problem}
    return [{"model": model, "problem": name, "paper": paper.ITERATIONS[name.split()[0]],
             "norms": {n: sweeps(prob, n) for n in NORMS},
             "serial_inf": serial_sweeps(serial_problems[name])}
            for name, prob in problems.items()]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", default=None, metavar="PATH",
                        help="also write the counts to PATH (versioned JSON)")
    args = parser.parse_args(argv)
    if args.json:
        try:
            check_outputs({"--json": args.json})
        except (OSError, ValueError) as exc:
            parser.error(str(exc))
    start = time.perf_counter()
    rows = [row for model in MODELS for row in measure(model)]
    seconds = time.perf_counter() - start
    print(f"{'model':<12}{'problem':<22}{'paper':>7}" + "".join(f"{n + '-norm':>10}" for n in NORMS)
          + f"{'serial inf':>12}")
    for r in rows:
        print(f"{r['model']:<12}{r['problem']:<22}{r['paper']:>7}"
              + "".join(f"{str(r['norms'][n]):>10}" for n in NORMS) + f"{r['serial_inf']:>12}")
    if args.json:
        write_json(args.json, {"schema": SCHEMA, "version": VERSION, "delta": DELTA,
                               "gamma": GAMMA, "norms": list(NORMS), "seconds": seconds,
                               "provenance": provenance(), "rows": rows})
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
