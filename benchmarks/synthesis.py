"""Synthesis benchmarks: fuzzy Q-iteration (Alg. 1) against value-iteration peers, and scaling.

Fuzzy Q-iteration with triangular memberships is value iteration on the MDP whose
transition probabilities are the memberships mu_m~(f(c_m, u)) (every row of T sums to
one) and whose rewards are rho(c_m, u). The peers (QuantEcon's ``DiscreteDP`` and
pymdptoolbox's ``ValueIteration``) are handed that identical MDP (the same sparse T,
the same rewards), forced to do the same number of sweeps from V_0 = 0, and their
values are checked against ours before any time is compared.

"Ours" is the package's path as :func:`twolink.synthesis.synthesize.synthesize` runs it: for the
centralized problem the factored table (:mod:`twolink.fqi.factored`) on the threads the
package picks for it (:func:`package_threads`: one for the paper's grid, two for K models),
measured beside explicit one- and two-thread runs and the fixed-width layout
(:mod:`twolink.fqi.iteration`); for the agents the fixed-width layout on one thread.

The parts: :mod:`benchmarks.synthesis_common` (sections, threads, the problems as the
package builds them), :mod:`benchmarks.synthesis_peers` (the peers and the reference),
:mod:`benchmarks.synthesis_problem` (one problem against the peers),
:mod:`benchmarks.synthesis_robust` (robust synthesis) and
:mod:`benchmarks.synthesis_scaling` (grids refined k times); this module runs the
section (:func:`bench_synthesis`) with ``synthesize()`` end to end and the kernels'
compile times.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np

from benchmarks.common import Row
from benchmarks.synthesis_common import (
    MAX_THREADS,
    PACKAGE,
    SECTION,
    busy_process,
    package_threads,
    threads_text,
)
from benchmarks.synthesis_problem import bench_problem
from benchmarks.synthesis_robust import bench_robust_synthesis, bench_worst_case
from twolink.fqi.factored import factored_table
from twolink.synthesis import synthesize as core


def bench_synthesize(*, repeats: int = 5, models=("simplified", "full"),
                     contended: bool = True) -> tuple[list[Row], dict]:
    """``synthesize("centralized", model=...)`` end to end as the command runs it, best of
    ``repeats`` after one warm-up call per model (numba's cache loaded), interleaved over
    the models; the split from the policy's ``info`` (transitions = model + table). With
    ``contended``, also model (11) with :func:`busy_process` spinning beside it."""
    threads = {}
    for m in models:
        info = core.synthesize("centralized", model=m).agents[0].info
        if info["layout"] != PACKAGE["centralized"][1]:
            raise RuntimeError(f"synthesize() now uses the {info['layout']} layout: "
                               f"update benchmarks.synthesis_common.PACKAGE")
        problem = core.centralized_problem(model=m, compiled=True)
        threads[m] = package_threads(factored_table(problem.grid, problem.next_points))

    def timed(m):
        t0 = time.perf_counter()
        pol = core.synthesize("centralized", model=m)
        return time.perf_counter() - t0, pol.agents[0].info

    runs = {m: [] for m in models}
    for _ in range(max(1, repeats)):
        for m in models:
            runs[m].append(timed(m))
    rows, summary = [], {}
    sec = f"{SECTION}: synthesize('centralized') end to end"
    for m in models:
        total, info = min(runs[m], key=lambda r: r[0])
        rows += [
            Row(sec, f"model={m}: total", total, "s",
                f"best of {len(runs[m])}, warm numba cache; target <= 0.05 s (issue 13)"),
            Row(sec, f"model={m}: transitions (model + table)", info["transition_seconds"],
                "s", "of the best run: compiled RK4 over one theta1 slice + factored table"),
            Row(sec, f"model={m}: sweeps", info["sweep_seconds"], "s",
                f"of the best run: {info['iterations']} sweeps, {info['layout']} layout, "
                f"{threads_text(threads[m])} (the package's choice)"),
        ]
        summary[m] = {"total": total, "threads": threads[m],
                      "transition_seconds": info["transition_seconds"],
                      "sweep_seconds": info["sweep_seconds"], "iterations": info["iterations"],
                      "median_total": float(np.median([r[0] for r in runs[m]]))}
    if contended:
        m = models[0]
        with busy_process():
            busy = [timed(m) for _ in range(max(1, repeats))]
        total, info = min(busy, key=lambda r: r[0])
        rows.append(Row(sec, f"model={m}, one busy process beside it: total", total, "s",
                        f"best of {len(busy)}: transitions {info['transition_seconds']:.3f} s, "
                        f"sweeps {info['sweep_seconds']:.3f} s on {threads_text(threads[m])}; "
                        f"{total / summary[m]['total']:.1f}x the idle machine's"))
        summary[m]["contended"] = {"total": total,
                                   "transition_seconds": info["transition_seconds"],
                                   "sweep_seconds": info["sweep_seconds"]}
    return rows, summary


def bench_synthesis(*, repeats: int = 3, sweep_repeats: int | None = None,
                    full_setup: bool = False, jit: bool | None = None
                    ) -> tuple[list[Row], dict]:
    """The centralized problem and both decentralized agents, with the peers;
    ``synthesize()`` end to end; the robust syntheses. ``jit`` (default ``full_setup``,
    that is full mode) adds the kernels' compile times in a fresh process (some 15 s)."""
    rows, summaries = [], {}
    for name in ("centralized", "agent2", "agent1"):
        r, s = bench_problem(name, repeats=repeats, sweep_repeats=sweep_repeats,
                             full_setup=full_setup)
        rows += r
        summaries[name] = s
    r, summaries["synthesize"] = bench_synthesize(repeats=repeats)
    rows += r
    c, a1, a2 = summaries["centralized"], summaries["agent1"], summaries["agent2"]
    sec = f"{SECTION}: centralized vs decentralized"
    fastest = min(("quantecon", "mdptoolbox"), key=lambda k: c["per_sweep"][k])
    rows += [
        Row(sec, "decentralized total (agent 2 + agent 1)", a1["total"] + a2["total"], "s"),
        Row(sec, "centralized / decentralized time", c["total"] / (a1["total"] + a2["total"]),
            "x"),
        Row(sec, "centralized / decentralized Q size", c["q_size"] / (a1["q_size"] + a2["q_size"]),
            "x", "paper: 63504 / (9072 + 252)"),
        Row(sec, "paper / ours centralized time", 18300.0 / c["total"], "x",
            "paper: ~18300 s CPU, Matlab 7.1, Centrino Duo 1.83 GHz"),
        Row(sec, f"fastest peer ({fastest}) / ours per sweep, centralized",
            c["per_sweep"][fastest] / c["per_sweep"]["ours"], "x",
            f">= 1.5 is the target; ours on {threads_text(c['threads'])} (the package's "
            f"choice), the peer on one"),
        *[Row(sec, f"fastest peer ({fastest}) / ours {threads_text(t)} per sweep, centralized",
              c["per_sweep"][fastest] / c["per_sweep"][f"factored, {threads_text(t)}"], "x",
              ">= 1.5 is the target; explicit threads=" + str(t)
              + ("; per core" if t == 1 else ""))
          for t in sorted({1, MAX_THREADS})],
        Row(sec, "sweep / copy bandwidth, centralized", c["sweep_gbs"] / c["copy_gbs"], "share",
            ">= 0.7 is the target (bytes actually moved)"),
        Row(sec, "equivalent / copy bandwidth, centralized",
            c["equivalent_gbs"] / c["fixed_copy_gbs"], "share",
            "the fixed layout's bytes over ours' time; not bytes moved"),
    ]
    r, summaries["worst_case"] = bench_worst_case(8, repeats=repeats)
    rows += r
    r, summaries["robust"] = bench_robust_synthesis((1, 8), repeats=repeats)
    rows += r
    if full_setup if jit is None else jit:
        compile_seconds = jit_compile_seconds()
        summaries["jit_seconds"] = compile_seconds
        sec = f"{SECTION}: compiled kernels"
        rows += [Row(sec, f"JIT compile: {name}", secs, "s",
                     "first call, fresh process, empty numba cache")
                 for name, secs in compile_seconds.items()]
    return rows, summaries


def jit_compile_seconds() -> dict:
    """Seconds the first call of each compiled kernel takes in a fresh process with an
    empty numba cache (compile time; the cached load is a few milliseconds)."""
    import json
    import tempfile

    code = (
        "import json, time, numpy as np\n"
        "from twolink.arm import integrate\n"
        "from twolink.fqi import factored as fqi_factored\n"
        "from twolink.fqi.iteration import fuzzy_q_iteration, fuzzy_q_iteration_robust\n"
        "from twolink.fqi.tables import robust_table, transition_table\n"
        "from twolink.fqi.fuzzy import Grid, angle_axis, speed_axis\n"
        "from twolink.arm.parameters import TABLE_I\n"
        "g = Grid((angle_axis('a'), speed_axis('s')))\n"
        "x = np.zeros((g.size, 4)); tau = np.zeros((3, 2))\n"
        "out = {}\n"
        "t0 = time.perf_counter(); nxt = integrate.sample_step_compiled("
        "'simplified', TABLE_I, x[:, None], tau[None]); out['rk4'] = time.perf_counter() - t0\n"
        "t0 = time.perf_counter(); t = transition_table(g, nxt[..., [1, 3]]); "
        "out['table'] = time.perf_counter() - t0\n"
        "r = np.zeros((g.size, 3)) - 1\n"
        "for s in ('synchronous', 'serial'):\n"
        "    t0 = time.perf_counter(); fuzzy_q_iteration(t, r, sweeps=s); "
        "out[s] = time.perf_counter() - t0\n"
        "t0 = time.perf_counter(); fuzzy_q_iteration_robust([t, t], [r, r]); "
        "out['robust'] = time.perf_counter() - t0\n"
        "t0 = time.perf_counter(); rt = robust_table(g, [nxt[..., [1, 3]]] * 2); "
        "out['robust_table'] = time.perf_counter() - t0\n"
        "ft = fqi_factored.factored_table(g, nxt[..., [1, 3]])\n"
        "for n in (1, 2):\n"
        "    t0 = time.perf_counter(); fqi_factored.factored_q_iteration(ft, r, threads=n); "
        "out[f'factored, threads={n}'] = time.perf_counter() - t0\n"
        "    t0 = time.perf_counter(); fqi_factored.factored_q_iteration_robust([ft, ft], "
        "[r, r], threads=n); out[f'factored robust, threads={n}'] = time.perf_counter() - t0\n"
        "print(json.dumps(out))\n")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        done = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                              capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])
