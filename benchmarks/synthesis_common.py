"""What the synthesis benchmarks share: their section names, the threads the package's
sweeps take (:func:`package_threads`), the problems as the package builds them
(:data:`BUILDERS`, :data:`PACKAGE`) and one synthesis run timed in its parts
(:func:`run_synthesis`), and a busy process beside a measurement (:func:`busy_process`).
"""
from __future__ import annotations

import contextlib
import subprocess
import sys
import time

from twolink.fqi.factored import default_threads, factored_q_iteration, factored_table, \
    sweep_work
from twolink.fqi.iteration import fuzzy_q_iteration
from twolink.fqi.tables import transition_table
from twolink.synthesis import synthesize as core

SECTION = "synthesis"
SCALING = "scaling"
#: The most threads the package's sweeps take (:func:`default_threads` without a work
#: figure: two on this 2-core machine): the explicit multi-thread rows beside one thread.
MAX_THREADS = default_threads()


def package_threads(tables) -> int:
    """Threads the package's factored sweeps take over ``tables`` (one
    :class:`FactoredTable`, or the K of a robust sweep): :func:`default_threads` of their
    summed :func:`sweep_work`, as :func:`factored_q_iteration` (``_robust``) choose them."""
    tables = tables if isinstance(tables, (list, tuple)) else [tables]
    return default_threads(sum(sweep_work(t) for t in tables))


def threads_text(n: int) -> str:
    """``n`` threads in words: "1 thread", "2 threads", ..."""
    return f"{n} thread" + ("s" if n > 1 else "")


#: The package's problem builders on grids refined k times (k = 1: the paper's grids);
#: agent 1 in its default (frozen) context, which needs no agent-2 controller.
BUILDERS = {"centralized": lambda k=1: core.centralized_problem(refine=k),
            "agent2": lambda k=1: core.agent2_problem(refine=k),
            "agent1": lambda k=1: core.agent1_problem(None, refine=k)}


#: The problems as :func:`twolink.synthesis.synthesize.synthesize` builds and solves them: the
#: centralized one on compiled transitions (one theta1 slice, shifted) in the factored
#: layout, the agents on numpy transitions in the fixed-width layout
#: (:func:`bench_synthesize` checks the centralized layout against ``synthesize``'s).
PACKAGE = {"centralized": (lambda k=1: core.centralized_problem(refine=k, compiled=True),
                           "factored"),
           "agent2": (BUILDERS["agent2"], "fixed"),
           "agent1": (BUILDERS["agent1"], "fixed")}


def run_synthesis(problem_fn, layout: str = "fixed"):
    """Build the problem and T in ``layout`` (fixed-width or factored, default threads),
    then run Alg. 1 to convergence: (problem, table, result, (model, table, sweep seconds))."""
    t0 = time.perf_counter()
    problem = problem_fn()
    t1 = time.perf_counter()
    if layout == "factored":
        trans = factored_table(problem.grid, problem.next_points)
    else:
        trans = transition_table(problem.grid, problem.next_points)
    t2 = time.perf_counter()
    solver = factored_q_iteration if layout == "factored" else fuzzy_q_iteration
    result = solver(trans, problem.rewards)
    t3 = time.perf_counter()
    if not result.converged:
        raise RuntimeError(f"Q-iteration for {problem.name} did not converge")
    return problem, trans, result, (t1 - t0, t2 - t1, t3 - t2)


@contextlib.contextmanager
def busy_process():
    """A second Python process spinning on one core while the block runs (a shared
    machine's other job), ended when the block exits."""
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.2)                                    # let it start spinning
        yield hog
    finally:
        hog.kill()
        hog.wait()
