"""One of the paper's problems benchmarked (:func:`bench_problem`): the package's
synthesis split into its parts, then equal-work sweeps of every layout and thread count
of ours and of the peers (:mod:`benchmarks.synthesis_peers`), interleaved, with their
ratios, the bytes a sweep moves against a copy of as many bytes, and their agreement.
"""
from __future__ import annotations

import time

import numpy as np

from benchmarks.common import Row, copy_bandwidth, interleaved_best, peak_bytes
from benchmarks.synthesis_common import (
    MAX_THREADS,
    PACKAGE,
    SECTION,
    busy_process,
    package_threads,
    run_synthesis,
    threads_text,
)
from benchmarks.synthesis_peers import agreement, mdptoolbox_solver, quantecon_solver, \
    scipy_sweeps
from twolink.arm.parameters import DELTA, GAMMA
from twolink.fqi.factored import factored_q_iteration, sweep_work
from twolink.fqi.iteration import fuzzy_q_iteration
from twolink.fqi.tables import transition_matrix, transition_table
from twolink.policy.fuzzy_policy import TIE_TOLERANCE, greedy_indices


def sweep_bytes(table) -> int:
    """Bytes a synchronous sweep must move at least: the table (a :class:`TransitionTable`'s
    indices and weights, or a :class:`FactoredTable`'s four arrays), rho, Q read (for the
    change), Q' written, V' written and V read once (its gathers hit cache)."""
    n_rows, n_x = table.shape
    return table.nbytes + 3 * 8 * n_rows + 2 * 8 * n_x


def forced(solver, table, rewards, n: int, **kwargs):
    """A callable running exactly ``n`` sweeps of ``solver`` from Q_0 = 0."""
    def go():
        res = solver(table, rewards, delta=1e-300, min_iterations=n, max_iterations=n,
                     **kwargs)
        if res.iterations != n:
            raise RuntimeError(f"forced {n} sweeps, did {res.iterations}")
        return res
    return go


def bench_problem(name: str, *, repeats: int, sweep_repeats: int | None = None,
                  full_setup: bool = False) -> tuple[list[Row], dict]:
    """Rows for one of the paper's problems: the package's split timings and memory, then
    equal-work sweeps of every layout and the peers, interleaved, with their ratios,
    bytes and agreement."""
    rows: list[Row] = []
    build, layout = PACKAGE[name]
    factored = layout == "factored"
    times = [run_synthesis(build, layout) for _ in range(max(1, repeats))]
    problem, table, result, _ = times[-1]
    fixed = transition_table(problem.grid, problem.next_points) if factored else table
    trans = transition_matrix(problem.grid, problem.next_points)     # the peers' T
    t_model, t_matrix, t_sweeps = (min(t[3][i] for t in times) for i in range(3))
    n = result.iterations
    rewards = problem.rewards
    sec = f"{SECTION}: {name}"
    threads = package_threads(table) if factored else 1
    where = (f"factored table, {threads_text(threads)} (synthesize's path: default_threads of "
             f"{sweep_work(table):,} gathered values per sweep)" if factored
             else "fixed-width table, 1 thread (synthesize's path)")
    rows += [
        Row(sec, "Q-table size", result.q.size, "values",
            f"{problem.grid.size} bins x {len(problem.actions)} actions"),
        Row(sec, "transition matrix nnz", trans.nnz, "entries",
            f"fixed width {fixed.index.shape[1]}: {fixed.nbytes / 2**20:.2f} MiB"
            + (f"; factored: {table.nbytes / 2**20:.2f} MiB" if factored else "")),
        Row(sec, "model transitions f(c_m,u)", t_model, "s",
            "compiled RK4 over one theta1 slice, shifted; rewards" if factored
            else "RK4 on model (11), numpy, all pairs; rewards"),
        Row(sec, "transition matrix T", t_matrix, "s",
            "memberships -> factored table (theta1's two per block)" if factored
            else "memberships -> fixed-width table (compiled)"),
        Row(sec, "sweeps to convergence", n, "sweeps", f"delta = {DELTA}"),
        Row(sec, "sweeps (to convergence)", t_sweeps, "s", where),
        Row(sec, "total synthesis", t_model + t_matrix + t_sweeps, "s",
            f"best of {len(times)} (each part's best)"),
    ]
    mem, _ = peak_bytes(lambda: run_synthesis(build, layout))
    rows.append(Row(sec, "peak memory (synthesis)", mem / 2**20, "MiB", "tracemalloc"))

    # Equal work: every solver does exactly n sweeps from zero on the same (T, rho).
    table32 = transition_table(problem.grid, problem.next_points, weights="float32")
    solver = factored_q_iteration if factored else fuzzy_q_iteration
    ours = {"ours": forced(solver, table, rewards, n)}       # the package's threads
    explicit = {f"factored, {threads_text(t)}": t for t in sorted({1, MAX_THREADS})} \
        if factored else {}
    ours |= {key: forced(factored_q_iteration, table, rewards, n, threads=t)
             for key, t in explicit.items()}
    if factored:
        ours |= {"fixed layout": forced(fuzzy_q_iteration, fixed, rewards, n)}
    multi = f"fixed layout, {threads_text(MAX_THREADS)}"
    if MAX_THREADS > 1:
        ours |= {multi: forced(fuzzy_q_iteration, fixed, rewards, n, threads=MAX_THREADS)}
    ours |= {"fixed layout, float32 weights": forced(fuzzy_q_iteration, table32, rewards, n)}
    notes = {
        "ours": where,
        **{key: f"factored_q_iteration threads={t} (explicit)" for key, t in explicit.items()},
        "fixed layout": "transition_table + fuzzy_q_iteration (1 thread)",
        multi: f"fuzzy_q_iteration threads={MAX_THREADS} (bins split; same Q bit for bit)",
        "fixed layout, float32 weights": "transition_table weights='float32' (opt-in)"}
    for fn in ours.values():
        fn()                                               # compile/load outside the timings

    t0 = time.perf_counter()
    qe_solve, qe_sweeps = quantecon_solver(trans, rewards, n)
    v_qe, sigma_qe = qe_solve()                            # first call compiles (numba)
    t_qe_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    mdp_solve = mdptoolbox_solver(trans, rewards, n, full_setup=full_setup)
    t_mdp_setup = time.perf_counter() - t0

    # Interleaved repeats: on a shared machine every solver sees the same background load.
    # Each copy moves the bytes of one sweep of its layout, n / 4 times.
    moved = sweep_bytes(table)
    moved_fixed = sweep_bytes(fixed)
    copies = {"copy": copy_bandwidth(moved // 2)}
    if factored:
        copies["copy, fixed layout's bytes"] = copy_bandwidth(moved_fixed // 2)

    def copy_n(copy):
        return lambda: sum(copy() for _ in range(max(1, n // 4)))

    best, out = interleaved_best({**ours, "quantecon": qe_sweeps, "quantecon_solve": qe_solve,
                                  "mdptoolbox": mdp_solve,
                                  **{k: copy_n(c) for k, c in copies.items()}},
                                 sweep_repeats or repeats)
    res_n = out["ours"]
    for key in ours:
        if key.startswith("factored") and not np.array_equal(out[key].q, res_n.q):
            raise RuntimeError(f"{key} differs from the package's sweeps bit for bit")
    # QuantEcon's policy is greedy in one more sweep, Q_{n+1} = rho + gamma T V_n.
    v_n = res_n.q.max(axis=1)
    q_next = (rewards.reshape(-1) + GAMMA * (trans @ v_n)).reshape(res_n.q.shape)
    checks = {"quantecon": (agreement(res_n.q, out["quantecon_solve"][0],
                                       out["quantecon_solve"][1])[0],
                            agreement(q_next, q_next.max(axis=1),
                                       out["quantecon_solve"][1])[1]),
              "mdptoolbox": agreement(res_n.q, *out["mdptoolbox"])}
    sweeps_only = agreement(res_n.q, out["quantecon"], sigma_qe)[0]
    checks["quantecon"] = (max(checks["quantecon"][0], sweeps_only), checks["quantecon"][1])
    per_sweep = {k: best[k] / n for k in (*ours, "quantecon", "mdptoolbox")}
    reps = sweep_repeats or repeats
    for key in ours:
        rows.append(Row(sec, f"{key}: time per sweep", per_sweep[key] * 1e3, "ms",
                        f"{notes[key]}; {n} forced sweeps, best of {reps} interleaved"))
    rows += [
        Row(sec, "quantecon: time per sweep", per_sweep["quantecon"] * 1e3, "ms",
            "DiscreteDP bellman_operator, sparse s-a pairs, one thread"),
        Row(sec, "quantecon: solve()", best["quantecon_solve"], "s",
            f"{n} sweeps + greedy policy; first call {t_qe_first:.2f} s (setup + numba JIT)"),
        Row(sec, "mdptoolbox: time per sweep", per_sweep["mdptoolbox"] * 1e3, "ms",
            "ValueIteration.run, per-action sparse P"),
        Row(sec, "mdptoolbox: setup", t_mdp_setup, "s",
            "split T per action + ValueIteration(): " + (
                "input check and iteration bound included" if full_setup else
                "input check and iteration bound skipped (quick mode)")),
    ]
    for peer in ("quantecon", "mdptoolbox"):
        rel, same = checks[peer]
        rows += [
            Row(sec, f"{peer} / ours per sweep", per_sweep[peer] / per_sweep["ours"], "x",
                f">1: ours faster (ours on {threads_text(threads)}; the peer on one)"),
            Row(sec, f"{peer} agreement max|dV|/max|V|", rel, "rel", "same MDP, same sweeps"),
            Row(sec, f"{peer} greedy action greedy in ours", same, "share",
                "ties count as agreement" + ("; its policy is greedy in Q_{n+1}"
                                             if peer == "quantecon" else "")),
        ]
    for key in ours:
        if key != "ours":
            rows.append(Row(sec, f"quantecon / {key} per sweep",
                            per_sweep["quantecon"] / per_sweep[key], "x", ">1: ours faster"))

    # Bytes moved and bandwidth, against a numpy copy of the same bytes in the same run.
    copy_gbs = {k: out[k] / best[k] / 1e9 for k in copies}
    sweep_gbs = moved / per_sweep["ours"] / 1e9
    rows += [
        Row(sec, "ours: bytes per sweep", moved / 2**20, "MiB",
            ("factored table (index, weight, index1, weight1)" if factored
             else "T (int32 index + float64 weight)") + " + rho + Q + Q' + V + V'"),
        Row(sec, "ours: sweep bandwidth", sweep_gbs, "GB/s",
            "bytes per sweep / time per sweep (bytes actually moved)"),
        Row(sec, "copy bandwidth (same bytes)", copy_gbs["copy"], "GB/s",
            f"numpy copyto of {moved / 2 / 2**20:.2f} MiB (read + write), one thread, same run"),
        Row(sec, "sweep / copy bandwidth", sweep_gbs / copy_gbs["copy"], "share",
            "target >= 0.7 (issue 13)"),
    ]
    summary = {"q_size": int(result.q.size), "iterations": n, "layout": layout,
               "threads": threads,
               "total": t_model + t_matrix + t_sweeps,
               "split": {"model": t_model, "table": t_matrix, "sweeps": t_sweeps},
               "per_sweep": per_sweep, "agreement": checks, "peak_bytes": mem,
               "sweep_bytes": moved, "sweep_gbs": sweep_gbs, "copy_gbs": copy_gbs["copy"]}
    if factored:
        explicit_gbs = {key: moved / per_sweep[key] / 1e9 for key in explicit}
        gbs_fixed = moved_fixed / per_sweep["fixed layout"] / 1e9
        copy_fixed = copy_gbs["copy, fixed layout's bytes"]
        equiv = moved_fixed / per_sweep["ours"] / 1e9
        rows += [Row(sec, f"{key}: sweep bandwidth", gbs, "GB/s",
                     f"share of the copy: {gbs / copy_gbs['copy']:.2f}; equivalent "
                     f"{moved_fixed / per_sweep[key] / 1e9:.1f} GB/s, "
                     f"{moved_fixed / per_sweep[key] / 1e9 / copy_fixed:.2f} of the "
                     f"fixed-bytes copy")
                 for key, gbs in explicit_gbs.items()]
        rows += [
            Row(sec, "fixed layout: bytes per sweep", moved_fixed / 2**20, "MiB",
                f"T (int32 index + float64 weight) + rho + Q + Q' + V + V'; "
                f"{moved_fixed / moved:.1f}x the factored sweep's"),
            Row(sec, "fixed layout: sweep bandwidth", gbs_fixed, "GB/s", "1 thread"),
            Row(sec, "copy bandwidth (fixed layout's bytes)", copy_fixed, "GB/s",
                f"numpy copyto of {moved_fixed / 2 / 2**20:.2f} MiB, same run"),
            Row(sec, "fixed layout: sweep / copy bandwidth", gbs_fixed / copy_fixed, "share"),
            Row(sec, "equivalent bandwidth: fixed layout's bytes / ours time per sweep",
                equiv, "GB/s", f"not bytes moved; ours on {threads_text(threads)}; share of "
                f"the fixed-bytes copy: {equiv / copy_fixed:.2f}"),
            Row(sec, "equivalent bandwidth / copy bandwidth (fixed layout's bytes)",
                equiv / copy_fixed, "share", "the fixed layout's bytes at ours' speed"),
        ]
        if MAX_THREADS > 1:
            # Why the package takes one thread here: the explicit runs again, a process
            # spinning beside them (a shared machine's other job).
            with busy_process():
                busy, _ = interleaved_best({key: ours[key] for key in explicit}, reps)
            rows += [Row(sec, f"{key}, one busy process beside it: time per sweep",
                         busy[key] / n * 1e3, "ms", f"{n} forced sweeps, best of {reps} "
                         f"interleaved; {busy[key] / best[key]:.1f}x its idle time")
                     for key in explicit]
            summary["busy_per_sweep"] = {key: busy[key] / n for key in explicit}
        # Agreement with the fixed layout and the scipy reference, same n sweeps.
        q_ref = scipy_sweeps(trans, rewards, n)
        q_fixed = out["fixed layout"].q
        dq_ref = float(np.max(np.abs(res_n.q - q_ref)))
        dq_fixed = float(np.max(np.abs(res_n.q - q_fixed)))
        moved_ref = int(np.sum(greedy_indices(res_n.q) != greedy_indices(q_ref)))
        moved_fix = int(np.sum(greedy_indices(res_n.q) != greedy_indices(q_fixed)))
        rows += [
            Row(sec, "scipy reference agreement max|dQ|", dq_ref, "abs",
                f"after the same {n} sweeps; target <= 1e-12; {moved_ref} greedy bins differ "
                f"(tie tolerance {TIE_TOLERANCE:g})"),
            Row(sec, "fixed layout agreement max|dQ|", dq_fixed, "abs",
                f"after the same {n} sweeps; {moved_fix} greedy bins differ"),
        ]
        summary |= {"fixed_sweep_bytes": moved_fixed, "fixed_sweep_gbs": gbs_fixed,
                    "fixed_copy_gbs": copy_fixed, "equivalent_gbs": equiv,
                    "explicit_gbs": explicit_gbs,
                    "max_dq": {"scipy": dq_ref, "fixed": dq_fixed},
                    "greedy_bins_differ": {"scipy": moved_ref, "fixed": moved_fix}}
    return rows, summary
