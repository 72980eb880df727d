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
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
import warnings
from unittest import mock

import numpy as np
import scipy.sparse as sp

from benchmarks.common import (
    Row,
    available_ram_bytes,
    copy_bandwidth,
    interleaved_best,
    peak_bytes,
    total_ram_bytes,
)
from twolink.arm.parameters import DELTA, GAMMA, TABLE_I
from twolink.synthesis import synthesize as core
from twolink.fqi.factored import (
    default_threads,
    factored_q_iteration,
    factored_q_iteration_robust,
    factored_table,
    sweep_work,
)
from twolink.fqi.iteration import fuzzy_q_iteration, fuzzy_q_iteration_robust
from twolink.fqi.tables import robust_table, transition_matrix, transition_table
from twolink.policy.fuzzy_policy import TIE_TOLERANCE, greedy_indices

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


def _threads(n: int) -> str:
    return f"{n} thread" + ("s" if n > 1 else "")


# --------------------------------------------------------------------------- problems
#: The package's problem builders on grids refined k times (k = 1: the paper's grids);
#: agent 1 in its default (frozen) context, which needs no agent-2 controller.
BUILDERS = {"centralized": lambda k=1: core.centralized_problem(refine=k),
            "agent2": lambda k=1: core.agent2_problem(refine=k),
            "agent1": lambda k=1: core.agent1_problem(None, refine=k)}


# --------------------------------------------------------------------------- peers
def _index_pairs(n_x: int, n_u: int) -> tuple[np.ndarray, np.ndarray]:
    """State and action index of every row m * N_U + j of T."""
    return np.repeat(np.arange(n_x), n_u), np.tile(np.arange(n_u), n_x)


def quantecon_solver(trans: sp.csr_matrix, rewards: np.ndarray, sweeps: int):
    """QuantEcon ``DiscreteDP`` in its state-action-pairs form on (T, rho): a callable
    doing ``sweeps`` value-iteration sweeps from V_0 = 0, returning (V, greedy action)."""
    from quantecon.markov import DiscreteDP

    n_x, n_u = rewards.shape
    s_idx, a_idx = _index_pairs(n_x, n_u)
    ddp = DiscreteDP(rewards.reshape(-1), trans, GAMMA, s_idx, a_idx)

    def solve():
        res = ddp.solve(method="value_iteration", v_init=np.zeros(n_x),
                        epsilon=1e-300, max_iter=sweeps)
        if res.num_iter != sweeps:
            raise RuntimeError(f"quantecon did {res.num_iter} sweeps, not {sweeps}")
        return res.v, res.sigma

    def sweeps_only():
        v = np.zeros(n_x)
        done = ddp.operator_iteration(ddp.bellman_operator, v, sweeps, tol=-1.0,
                                      Tv=np.empty(n_x))
        if done != sweeps:
            raise RuntimeError(f"quantecon did {done} sweeps, not {sweeps}")
        return v

    return solve, sweeps_only


def _per_action(trans: sp.csr_matrix, n_u: int) -> list:
    return [sp.csr_matrix(trans[j::n_u]) for j in range(n_u)]


def mdptoolbox_solver(trans: sp.csr_matrix, rewards: np.ndarray, sweeps: int, *,
                      full_setup: bool = True):
    """pymdptoolbox ``ValueIteration`` on (T split into per-action (S, S) matrices, rho):
    a callable doing exactly ``sweeps`` sweeps from V_0 = 0, returning (V, greedy action).

    ``full_setup=False`` skips two steps of its constructor that do not change the
    sweeps: the input check (``mdptoolbox.util.check``, a dense comparison per action)
    and the iteration bound (``_boundIter``, a column slice of every P per state); on
    the centralized T they take minutes.
    """
    import mdptoolbox.util
    from mdptoolbox.mdp import ValueIteration

    per_action = _per_action(trans, rewards.shape[1])
    with contextlib.ExitStack() as stack:
        stack.enter_context(warnings.catch_warnings())
        warnings.simplefilter("ignore", sp.SparseEfficiencyWarning)
        if not full_setup:
            stack.enter_context(mock.patch.object(mdptoolbox.util, "check", _no_op))
            stack.enter_context(mock.patch.object(ValueIteration, "_boundIter", _no_op))
        vi = ValueIteration(per_action, rewards, GAMMA, epsilon=DELTA, max_iter=sweeps)

    def solve():
        # Its constructor caps max_iter by an epsilon-optimality bound; force the count
        # and a stopping threshold no span can fall under.
        vi.V, vi.iter, vi.max_iter, vi.thresh = np.zeros(vi.S), 0, sweeps, -1.0
        vi.run()
        if vi.iter != sweeps:
            raise RuntimeError(f"mdptoolbox did {vi.iter} sweeps, not {sweeps}")
        return np.asarray(vi.V), np.asarray(vi.policy)

    return solve


def _no_op(*args, **kwargs):
    return None


# --------------------------------------------------------------------------- measurements
#: The problems as :func:`twolink.synthesis.synthesize.synthesize` builds and solves them: the
#: centralized one on compiled transitions (one theta1 slice, shifted) in the factored
#: layout, the agents on numpy transitions in the fixed-width layout
#: (:func:`bench_synthesize` checks the centralized layout against ``synthesize``'s).
PACKAGE = {"centralized": (lambda k=1: core.centralized_problem(refine=k, compiled=True),
                           "factored"),
           "agent2": (BUILDERS["agent2"], "fixed"),
           "agent1": (BUILDERS["agent1"], "fixed")}


def _synthesis(problem_fn, layout: str = "fixed"):
    """Build the problem and T in ``layout`` (fixed-width or factored, default threads),
    then run Alg. 1 to convergence."""
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


def sweep_bytes(table) -> int:
    """Bytes a synchronous sweep must move at least: the table (a :class:`TransitionTable`'s
    indices and weights, or a :class:`FactoredTable`'s four arrays), rho, Q read (for the
    change), Q' written, V' written and V read once (its gathers hit cache)."""
    n_rows, n_x = table.shape
    return table.nbytes + 3 * 8 * n_rows + 2 * 8 * n_x


def _forced(solver, table, rewards, n: int, **kwargs):
    """A callable running exactly ``n`` sweeps of ``solver`` from Q_0 = 0."""
    def go():
        res = solver(table, rewards, delta=1e-300, min_iterations=n, max_iterations=n,
                     **kwargs)
        if res.iterations != n:
            raise RuntimeError(f"forced {n} sweeps, did {res.iterations}")
        return res
    return go


def _scipy_sweeps(trans: sp.csr_matrix, rewards: np.ndarray, n: int) -> np.ndarray:
    """Q_n of ``n`` synchronous sweeps from Q_0 = 0 by scipy's CSR product: the reference."""
    r = rewards.reshape(-1)
    q = np.zeros(rewards.shape)
    for _ in range(n):
        q = (r + GAMMA * (trans @ q.max(axis=1))).reshape(rewards.shape)
    return q


def _agreement(ours_q: np.ndarray, v: np.ndarray, greedy: np.ndarray) -> tuple[float, float]:
    """Max |V_peer - V_ours| relative to max |V_ours|, and the share of bins whose peer
    greedy action is greedy in our Q too (ties, to 1e-12 relative, count as agreement)."""
    v_ours = ours_q.max(axis=1)
    scale = max(1e-300, float(np.max(np.abs(v_ours))))
    rel = float(np.max(np.abs(np.asarray(v) - v_ours)) / scale)
    picked = np.take_along_axis(ours_q, np.asarray(greedy, dtype=int)[:, None], 1)[:, 0]
    same = float(np.mean(picked >= v_ours - 1e-12 * scale))
    return rel, same


def bench_problem(name: str, *, repeats: int, sweep_repeats: int | None = None,
                  full_setup: bool = False) -> tuple[list[Row], dict]:
    """Rows for one of the paper's problems: the package's split timings and memory, then
    equal-work sweeps of every layout and the peers, interleaved, with their ratios,
    bytes and agreement."""
    rows: list[Row] = []
    build, layout = PACKAGE[name]
    factored = layout == "factored"
    times = [_synthesis(build, layout) for _ in range(max(1, repeats))]
    problem, table, result, _ = times[-1]
    fixed = transition_table(problem.grid, problem.next_points) if factored else table
    trans = transition_matrix(problem.grid, problem.next_points)     # the peers' T
    t_model, t_matrix, t_sweeps = (min(t[3][i] for t in times) for i in range(3))
    n = result.iterations
    rewards = problem.rewards
    sec = f"{SECTION}: {name}"
    threads = package_threads(table) if factored else 1
    where = (f"factored table, {_threads(threads)} (synthesize's path: default_threads of "
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
    mem, _ = peak_bytes(lambda: _synthesis(build, layout))
    rows.append(Row(sec, "peak memory (synthesis)", mem / 2**20, "MiB", "tracemalloc"))

    # Equal work: every solver does exactly n sweeps from zero on the same (T, rho).
    table32 = transition_table(problem.grid, problem.next_points, weights="float32")
    solver = factored_q_iteration if factored else fuzzy_q_iteration
    ours = {"ours": _forced(solver, table, rewards, n)}       # the package's threads
    explicit = {f"factored, {_threads(t)}": t for t in sorted({1, MAX_THREADS})} \
        if factored else {}
    ours |= {key: _forced(factored_q_iteration, table, rewards, n, threads=t)
             for key, t in explicit.items()}
    if factored:
        ours |= {"fixed layout": _forced(fuzzy_q_iteration, fixed, rewards, n)}
    multi = f"fixed layout, {_threads(MAX_THREADS)}"
    if MAX_THREADS > 1:
        ours |= {multi: _forced(fuzzy_q_iteration, fixed, rewards, n, threads=MAX_THREADS)}
    ours |= {"fixed layout, float32 weights": _forced(fuzzy_q_iteration, table32, rewards, n)}
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
    checks = {"quantecon": (_agreement(res_n.q, out["quantecon_solve"][0],
                                       out["quantecon_solve"][1])[0],
                            _agreement(q_next, q_next.max(axis=1),
                                       out["quantecon_solve"][1])[1]),
              "mdptoolbox": _agreement(res_n.q, *out["mdptoolbox"])}
    sweeps_only = _agreement(res_n.q, out["quantecon"], sigma_qe)[0]
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
                f">1: ours faster (ours on {_threads(threads)}; the peer on one)"),
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
                equiv, "GB/s", f"not bytes moved; ours on {_threads(threads)}; share of "
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
        q_ref = _scipy_sweeps(trans, rewards, n)
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
                               f"update benchmarks.synthesis.PACKAGE")
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
                f"{_threads(threads[m])} (the package's choice)"),
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
                        f"sweeps {info['sweep_seconds']:.3f} s on {_threads(threads[m])}; "
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
            f">= 1.5 is the target; ours on {_threads(c['threads'])} (the package's "
            f"choice), the peer on one"),
        *[Row(sec, f"fastest peer ({fastest}) / ours {_threads(t)} per sweep, centralized",
              c["per_sweep"][fastest] / c["per_sweep"][f"factored, {_threads(t)}"], "x",
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


# --------------------------------------------------------------------------- robust
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
        how = (f"factored tables, {_threads(threads)} (synthesize's layout and threads)"
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
        rows.append(Row(sec, f"factored, {_threads(t)}: sweeps (worst)", secs, "s",
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
    their own rows), with the threads the package picks for K tables. For K > 1 also the same models through the fixed-width layout the package
    used before (:func:`robust_table` + :func:`fuzzy_q_iteration_robust`, 1 thread),
    interleaved, its Q held against ``synthesize()``'s."""
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
        models = core.parameter_draws(TABLE_I, k, 0.2, ROBUST_SEED)
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
                f"{sweeps} sweeps of min_k rho_k + gamma T_k V, {_threads(threads)} "
                f"(the package's choice for K tables)"),
            Row(sec, "total synthesize()", best, "s",
                f"best of {len(runs)}; targets: <= 1.5 s (issue 9), 0.5 s (issue 13)"),
            Row(sec, "total synthesize(), CPU time", min(r[2] for r in runs), "s",
                f"process time (every thread's CPU counted; sweeps on {_threads(threads)})"),
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


def jit_compile_seconds() -> dict:
    """Seconds the first call of each compiled kernel takes in a fresh process with an
    empty numba cache (compile time; the cached load is a few milliseconds)."""
    import json
    import tempfile

    code = (
        "import json, time, numpy as np\n"
        "from twolink import fqi, fqi_factored, integrate\n"
        "from twolink.fqi.fuzzy import Grid, angle_axis, speed_axis\n"
        "from twolink.arm.parameters import TABLE_I\n"
        "g = Grid((angle_axis('a'), speed_axis('s')))\n"
        "x = np.zeros((g.size, 4)); tau = np.zeros((3, 2))\n"
        "out = {}\n"
        "t0 = time.perf_counter(); nxt = integrate.sample_step_compiled("
        "'simplified', TABLE_I, x[:, None], tau[None]); out['rk4'] = time.perf_counter() - t0\n"
        "t0 = time.perf_counter(); t = fqi.transition_table(g, nxt[..., [1, 3]]); "
        "out['table'] = time.perf_counter() - t0\n"
        "r = np.zeros((g.size, 3)) - 1\n"
        "for s in ('synchronous', 'serial'):\n"
        "    t0 = time.perf_counter(); fqi.fuzzy_q_iteration(t, r, sweeps=s); "
        "out[s] = time.perf_counter() - t0\n"
        "t0 = time.perf_counter(); fqi.fuzzy_q_iteration_robust([t, t], [r, r]); "
        "out['robust'] = time.perf_counter() - t0\n"
        "t0 = time.perf_counter(); rt = fqi.robust_table(g, [nxt[..., [1, 3]]] * 2); "
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


# --------------------------------------------------------------------------- scaling
def _pairs(name: str, k: int) -> tuple[int, int, int]:
    """(bins, actions, dimensions) of a problem refined k times, without building it."""
    ang, spd = 12 * k, 6 * k + 1
    return {"centralized": (ang * ang * spd * spd, 9, 4), "agent2": (ang * spd, 3, 2),
            "agent1": (ang * spd * ang * 3, 3, 4)}[name]


def bench_scaling(central=(1, 2), decentral=(1, 2), *, budget_fraction: float = 0.5,
                  estimate_to: int = 8) -> tuple[list[Row], list[dict]]:
    """Both schemes on grids refined k times, each built as :func:`core.synthesize` builds
    it (:data:`PACKAGE`: the centralized problem from the compiled RK4 over one theta1 slice
    and T factored along theta1; the agents' numpy RK4 and fixed-width tables): Q size,
    nnz, time, peak memory.

    The centralized problem runs for k in ``central``, the decentralized pair for k in
    ``decentral``, each only when its predicted peak memory fits ``budget_fraction`` of
    the memory available now. The prediction is each scheme's peak bytes per unit of its
    work measured on its largest run made (centralized: per state-action pair, as the
    factored table grows with the pairs; decentralized: per state-action pair x 2**d
    memberships); up to ``estimate_to`` the rows give each scheme's predicted need against
    the machine's RAM.
    """
    rows, records = [], []
    avail = available_ram_bytes() or total_ram_bytes() or 0
    ram = total_ram_bytes() or avail
    budget = budget_fraction * avail
    coeff = {}            # per scheme: peak bytes per unit of work, measured
    asked = {"centralized": set(central), "decentralized": set(decentral)}
    for k in range(1, max(max(central), max(decentral), estimate_to) + 1):
        for scheme, parts in (("centralized", ("centralized",)),
                              ("decentralized", ("agent2", "agent1"))):
            dims = [_pairs(p, k) for p in parts]
            q_size = sum(n * u for n, u, _ in dims)
            work = sum(n * u * (1 if scheme == "centralized" else 2 ** d) for n, u, d in dims)
            need = coeff[scheme] * work if scheme in coeff else None
            rec = {"k": k, "scheme": scheme, "q_size": q_size,
                   "bins": [n for n, _, _ in dims], "predicted_bytes": need}
            run = k in asked[scheme] and (need is None or need <= budget)
            if run:
                total, peak, nnz, sweeps = 0.0, 0, 0, 0
                for part in parts:
                    build, layout = PACKAGE[part]
                    mem, (problem, trans, result, t) = peak_bytes(
                        lambda build=build, layout=layout: _synthesis(lambda: build(k), layout))
                    total += sum(t)
                    peak = max(peak, mem)
                    nnz += trans.nnz
                    sweeps = max(sweeps, result.iterations)
                    rec[f"{part}_seconds"] = t
                    rec[f"{part}_sweeps"] = result.iterations
                    del problem, trans, result
                coeff[scheme] = peak / work
                rec.update(seconds=total, peak_bytes=peak, nnz=nnz)
                note = f"{nnz:,} nnz, {sweeps} sweeps, peak {peak / 2**20:,.0f} MiB"
                rows.append(Row(SCALING, f"{scheme} {k}x bins: time", total, "s", note))
            elif need is not None:
                why = (f"over the {budget / 2**30:,.1f} GiB budget" if need > budget
                       else "not in this mode's grids")
                fits = "exceeds" if need > ram else "within"
                rows.append(Row(SCALING, f"{scheme} {k}x bins: predicted memory",
                                need / 2**20, "MiB",
                                f"not run ({why}); {fits} the machine's {ram / 2**30:,.1f} GiB"))
            rows.append(Row(SCALING, f"{scheme} {k}x bins: Q size", q_size, "values",
                            " + ".join(f"{n:,}x{u}" for n, u, _ in dims)))
            records.append(rec)
    return rows, records
