"""Robust synthesis benchmarks: the worst case over K corner models through the public
pieces in both layouts (:func:`bench_worst_case`) and the package's robust
``synthesize()`` as the command runs it (:func:`bench_robust_synthesis`).
"""
from __future__ import annotations

import time

import numpy as np

from benchmarks.common import Row, interleaved_best
from benchmarks.synthesis_common import MAX_THREADS, SECTION, package_threads, threads_text
from twolink.arm.parameters import DELTA, TABLE_I
from twolink.fqi.factored import factored_q_iteration_robust, factored_table
from twolink.fqi.iteration import fuzzy_q_iteration_robust
from twolink.fqi.tables import robust_table
from twolink.policy.fuzzy_policy import TIE_TOLERANCE, greedy_indices
from twolink.synthesis import synthesize as core
from twolink.synthesis.problems import parameter_draws


def worst_case_models(k: int = 8, spread: float = 0.2) -> list:
    """K parameter sets around Table I: the corners of m1, m2, b1 scaled by 1 +- spread
    (the first 8; more repeat the corners with I1 and I2 scaled too)."""
    corners = [dict(m1=a, m2=b, b1=c) for a in (1 - spread, 1 + spread)
               for b in (1 - spread, 1 + spread) for c in (1 - spread, 1 + spread)]
    out = []
    for i in range(k):
        f = dict(corners[i % 8])
        if i >= 8:
            f.update(I1=1 + spread, I2=1 - spread)
        out.append(TABLE_I.scaled(**f))
    return out


def _robust_run(models, model: str, layout: str, mode: str = "worst"):
    """Robust centralized synthesis over ``models`` through the public pieces, the tables
    in ``layout``: (model seconds, table seconds, sweep seconds), result, tables, rewards.
    Factored: :func:`factored_table` per model + :func:`factored_q_iteration_robust` (the
    package's threads), as ``synthesize`` runs it; fixed: :func:`robust_table` +
    :func:`fuzzy_q_iteration_robust` (1 thread), the layout it ran before."""
    t0 = time.perf_counter()
    problems = [core.centralized_problem(p, model=model, compiled=True) for p in models]
    t1 = time.perf_counter()
    if layout == "factored":
        tables = [factored_table(problems[0].grid, pr.next_points) for pr in problems]
    else:
        tables = robust_table(problems[0].grid, [pr.next_points for pr in problems])
    t2 = time.perf_counter()
    solver = factored_q_iteration_robust if layout == "factored" else fuzzy_q_iteration_robust
    rewards = [pr.rewards for pr in problems]
    res = solver(tables, rewards, mode=mode)
    t3 = time.perf_counter()
    if not res.converged:
        raise RuntimeError(f"robust Q-iteration ({mode}, {layout}) did not converge")
    return (t1 - t0, t2 - t1, t3 - t2), res, tables, rewards


def _robust_bytes(tables) -> int:
    """Bytes a robust sweep moves: the K tables (a list of :class:`FactoredTable` or one
    :class:`RobustTable`), K rho, Q, Q', V, V'."""
    if isinstance(tables, list):
        k, body = len(tables), sum(t.nbytes for t in tables)
        n_rows, n_x = tables[0].shape
    else:
        k, body = tables.models, tables.nbytes
        n_rows, n_x = tables.index.shape[0], tables.n_states
    return body + 8 * k * n_rows + 2 * 8 * n_rows + 2 * 8 * n_x


def bench_worst_case(k: int = 8, *, repeats: int = 3) -> tuple[list[Row], dict]:
    """Robust centralized synthesis over K corner models (:func:`worst_case_models`, model
    (11)): min over k of rho_k + gamma T_k V in one compiled sweep, the factored layout (the
    package's, on the threads it picks for K tables) interleaved with the fixed-width one,
    best of ``repeats``; then the factored sweeps alone on explicit one and two threads,
    interleaved; the mean over k once, factored."""
    models = worst_case_models(k)
    runs = {"factored": [], "fixed": []}
    for _ in range(max(1, repeats)):                        # interleaved
        for layout in runs:
            runs[layout].append(_robust_run(models, "simplified", layout))
    mean_runs = [_robust_run(models, "simplified", "factored", "mean")]
    sec = f"{SECTION}: worst case over K = {k} models, centralized"
    threads = package_threads(runs["factored"][-1][2])
    rows, summary = [], {"k": k, "threads": threads}
    q = {layout: r[-1][1].q for layout, r in runs.items()}
    for layout, rr in runs.items():
        parts = [min(r[0][i] for r in rr) for i in range(3)]
        total = min(sum(r[0]) for r in rr)
        res, tables = rr[-1][1], rr[-1][2]
        moved = _robust_bytes(tables)
        per_sweep = parts[2] / res.iterations
        pre = "" if layout == "factored" else "fixed layout: "
        how = (f"factored tables, {threads_text(threads)} (synthesize's layout and threads)"
               if layout == "factored"
               else "robust_table side by side, 1 thread (the layout before)")
        rows += [
            Row(sec, f"{pre}transitions + tables (K models)", parts[0] + parts[1], "s",
                f"compiled RK4 {parts[0]:.3f} s + tables {parts[1]:.3f} s; m1, m2, b1 "
                f"scaled by 0.8/1.2"),
            Row(sec, f"{pre}sweeps to convergence (worst)", res.iterations, "sweeps",
                f"delta = {DELTA}"),
            Row(sec, f"{pre}sweeps (worst)", parts[2], "s",
                f"min over k of rho_k + gamma T_k V; {how}"),
            Row(sec, f"{pre}total robust synthesis (worst)", total, "s",
                f"best of {len(rr)}, interleaved; target 0.5 s (issue 13)"),
            Row(sec, f"{pre}time per sweep (worst)", per_sweep * 1e3, "ms"),
            Row(sec, f"{pre}bytes per sweep", moved / 2**20, "MiB",
                "K tables + K rho + Q + Q' + V + V'"),
            Row(sec, f"{pre}sweep bandwidth", moved / per_sweep / 1e9, "GB/s"),
        ]
        summary[layout] = {"total": total, "model_seconds": parts[0],
                           "table_seconds": parts[1], "sweeps_seconds": parts[2],
                           "iterations": res.iterations, "per_sweep": per_sweep,
                           "sweep_bytes": moved, "sweep_gbs": moved / per_sweep / 1e9}
    # The same factored sweeps on explicit thread counts (the tables and rewards reused).
    tables, rewards = runs["factored"][-1][2], runs["factored"][-1][3]
    explicit = {t: lambda t=t: factored_q_iteration_robust(tables, rewards, threads=t)
                for t in sorted({1, MAX_THREADS})}
    best, out = interleaved_best(explicit, repeats)
    for t, secs in best.items():
        rows.append(Row(sec, f"factored, {threads_text(t)}: sweeps (worst)", secs, "s",
                        f"explicit threads={t}; {out[t].iterations} sweeps, best of "
                        f"{max(1, repeats)} interleaved"))
    summary["explicit_sweeps_seconds"] = best
    dq = float(np.max(np.abs(q["factored"] - q["fixed"])))
    bins = int(np.sum(greedy_indices(q["factored"]) != greedy_indices(q["fixed"])))
    rows += [
        Row(sec, "fixed / factored total", summary["fixed"]["total"]
            / summary["factored"]["total"], "x", ">1: the package's layout faster"),
        Row(sec, "fixed layout agreement max|dQ|", dq, "abs",
            f"converged Q; {bins} greedy bins differ (tie tolerance {TIE_TOLERANCE:g})"),
        Row(sec, "sweeps to convergence (mean)", mean_runs[-1][1].iterations, "sweeps"),
        Row(sec, "total robust synthesis (mean)", sum(mean_runs[0][0]), "s", "one run"),
    ]
    f = summary["factored"]
    summary |= {"total": f["total"], "sweeps_seconds": f["sweeps_seconds"],
                "iterations": f["iterations"], "per_sweep": f["per_sweep"],
                "sweep_gbs": f["sweep_gbs"], "max_dq": dq, "greedy_bins_differ": bins}
    return rows, summary


def bench_robust_synthesis(draws=(1, 8), *, repeats: int = 3) -> tuple[list[Row], dict]:
    """The package's robust synthesis (``synthesize(..., robust="worst")``, as
    ``twolink synthesize centralized --model full --robust worst`` runs it) for K in
    ``draws``, spread 0.2, the shipped seed: model transitions, factored tables, sweeps and
    the whole call, best of ``repeats`` after one warm-up call per K (JIT compile times are
    their own rows), with the threads the package picks for K tables. For K > 1 also the
    same models through the fixed-width layout the package used before
    (:func:`robust_table` + :func:`fuzzy_q_iteration_robust`, 1 thread), interleaved, its
    Q held against ``synthesize()``'s."""
    from twolink.policy.registry import ROBUST_SEED

    def once(k):
        t0, c0 = time.perf_counter(), time.process_time()
        pol = core.synthesize("centralized", model="full", robust="worst", draws=k,
                              spread=0.2, seed=ROBUST_SEED)
        return (time.perf_counter() - t0, pol.agents[0].info, time.process_time() - c0,
                pol.agents[0].q)

    for k in draws:
        once(k)                               # loads the compiled kernels K's threads take
    rows, summary = [], {}
    for k in draws:
        models = parameter_draws(TABLE_I, k, 0.2, ROBUST_SEED)
        problems = [core.centralized_problem(p, model="full", compiled=True) for p in models]
        threads = package_threads([factored_table(pr.grid, pr.next_points)
                                   for pr in problems])
        del problems
        runs, fixed = [], []
        for _ in range(max(1, repeats)):                   # interleaved
            runs.append(once(k))
            if k > 1:
                fixed.append(_robust_run(models, "full", "fixed"))
        best = min(r[0] for r in runs)
        part = {name: min(r[1][name] for r in runs)
                for name in ("model_seconds", "table_seconds", "sweep_seconds")}
        sweeps = runs[-1][1]["iterations"]
        sec = f"{SECTION}: robust synthesis, centralized on (6), worst case over K = {k}"
        rows += [
            Row(sec, "model transitions (K models)", part["model_seconds"], "s",
                "compiled RK4 over one theta1 slice, shifted; rewards"),
            Row(sec, "factored tables (K models)", part["table_seconds"], "s",
                "theta1 factored out (synthesize's layout)"),
            Row(sec, "sweeps", part["sweep_seconds"], "s",
                f"{sweeps} sweeps of min_k rho_k + gamma T_k V, {threads_text(threads)} "
                f"(the package's choice for K tables)"),
            Row(sec, "total synthesize()", best, "s",
                f"best of {len(runs)}; targets: <= 1.5 s (issue 9), 0.5 s (issue 13)"),
            Row(sec, "total synthesize(), CPU time", min(r[2] for r in runs), "s",
                f"process time (every thread's CPU counted; sweeps on {threads_text(threads)})"),
        ]
        summary[k] = {"total": best, "cpu": min(r[2] for r in runs), "iterations": sweeps,
                      "threads": threads, **part}
        if fixed:
            split = [min(r[0][i] for r in fixed) for i in range(3)]
            res = fixed[-1][1]
            dq = float(np.max(np.abs(res.q - runs[-1][3])))
            bins = int(np.sum(greedy_indices(res.q) != greedy_indices(runs[-1][3])))
            rows.append(Row(sec, "fixed layout: total (problems + table + sweeps)", sum(split),
                            "s", f"robust_table + fuzzy_q_iteration_robust, 1 thread, best of "
                            f"{len(fixed)} interleaved; models {split[0]:.3f} s, table "
                            f"{split[1]:.3f} s, {res.iterations} sweeps {split[2]:.3f} s; "
                            f"max|dQ| vs synthesize() {dq:.2g}, {bins} greedy bins differ"))
            summary[k]["fixed"] = {"total": sum(split), "model_seconds": split[0],
                                   "table_seconds": split[1], "sweep_seconds": split[2],
                                   "iterations": res.iterations, "max_dq": dq,
                                   "greedy_bins_differ": bins}
    return rows, summary
