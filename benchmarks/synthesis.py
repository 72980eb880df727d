"""Synthesis benchmarks: fuzzy Q-iteration (Alg. 1) against value-iteration peers, and scaling.

Fuzzy Q-iteration with triangular memberships is value iteration on the MDP whose
transition probabilities are the memberships mu_m~(f(c_m, u)) (every row of T sums to
one) and whose rewards are rho(c_m, u). The peers (QuantEcon's ``DiscreteDP`` and
pymdptoolbox's ``ValueIteration``) are handed that identical MDP (the same sparse T,
the same rewards), forced to do the same number of sweeps from V_0 = 0, and their
values are checked against ours before any time is compared.
"""
from __future__ import annotations

import contextlib
import os
import time
import warnings
from unittest import mock

import numba
import numpy as np
import scipy.sparse as sp

from benchmarks.common import (Row, available_ram_bytes, best_time, copy_bandwidth,
                               interleaved_best, peak_bytes, total_ram_bytes)
from twolink import synthesis as core
from twolink._numba import cache_wanted
from twolink.fqi import (TransitionTable, fuzzy_q_iteration, fuzzy_q_iteration_robust,
                         robust_table, transition_matrix, transition_table)
from twolink.integrate import sample_step_compiled
from twolink.parameters import DELTA, GAMMA, TABLE_I
from twolink.policy import TIE_TOLERANCE, greedy_indices
from twolink.reward import centralized_reward

SECTION = "synthesis"
SCALING = "scaling"
#: Threads of the threaded sweeps measured beside the one-thread reference (fqi threads=).
THREADS = max(1, min(2, os.cpu_count() or 1))


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


# --------------------------------------------------------------------------- sweep variants
# Reorderings of the row sums that the package does not ship, measured beside its kernels
# (twolink.fqi_kernel) to say what each buys: the same fused sweep (V = max_u Q,
# Q' = rho + gamma T V, the change), only the row sum differs.
_REASSOC = {"reassoc", "nsz", "contract"}
_CACHE = cache_wanted(__file__)


@numba.njit(nogil=True, cache=_CACHE, fastmath=_REASSOC)
def _row_vectorised(index, weight, row, v):
    """The row in any order: the compiler reassociates and vectorises it (with gathers)."""
    s = 0.0
    for k in range(index.shape[1]):
        s += weight[row, k] * v[index[row, k]]
    return s


@numba.njit(nogil=True, cache=_CACHE)
def _row_partial4(index, weight, row, v):
    """Four independent accumulators (entries k mod 4), added pairwise at the end."""
    s0 = s1 = s2 = s3 = 0.0
    width = index.shape[1]
    k = 0
    while k + 3 < width:
        s0 += weight[row, k] * v[index[row, k]]
        s1 += weight[row, k + 1] * v[index[row, k + 1]]
        s2 += weight[row, k + 2] * v[index[row, k + 2]]
        s3 += weight[row, k + 3] * v[index[row, k + 3]]
        k += 4
    while k < width:
        s0 += weight[row, k] * v[index[row, k]]
        k += 1
    return (s0 + s1) + (s2 + s3)


@numba.njit(nogil=True, cache=_CACHE, fastmath=_REASSOC)
def _row_stream(index, weight, row, v):
    """Index and weight read, vectorised, without gathering V: the table's bytes alone
    (a floor, not a sweep)."""
    s = 0.0
    for k in range(index.shape[1]):
        s += weight[row, k] * index[row, k]
    return s * 1e-300


#: The variants by name, as :func:`_variant_sweeps` numbers them.
VARIANTS = ("vectorised", "4 partial sums", "stream only")


@numba.njit(nogil=True, cache=_CACHE)
def _variant_sweeps(variant, index, weight, r, q, q_next, v, v_next, gamma, n):
    """Exactly ``n`` synchronous sweeps with the row sum of ``VARIANTS[variant]`` (a branch
    the compiler hoists out of the loops); Q_n ends in ``q_next`` when n is odd."""
    n_rows = index.shape[0]
    n_x = v.shape[0]
    n_u = n_rows // n_x
    change = 0.0
    for _ in range(n):
        change = 0.0
        for m in range(n_x):
            best = -np.inf
            for j in range(n_u):
                row = m * n_u + j
                if variant == 0:
                    s = _row_vectorised(index, weight, row, v)
                elif variant == 1:
                    s = _row_partial4(index, weight, row, v)
                else:
                    s = _row_stream(index, weight, row, v)
                new = r[row] + gamma * s
                d = abs(new - q[row])
                if d > change:
                    change = d
                q_next[row] = new
                if new > best:
                    best = new
            v_next[m] = best
        q, q_next = q_next, q
        v, v_next = v_next, v
    return change


def _variant_run(name: str, table: TransitionTable, rewards: np.ndarray, n: int):
    """A callable running ``n`` sweeps of variant ``name`` from Q_0 = 0 on ``table``;
    returns Q_n."""
    variant = VARIANTS.index(name)
    r = np.ascontiguousarray(rewards, dtype=float).reshape(-1)
    n_x = rewards.shape[0]

    def go():
        q, q_next = np.zeros(r.size), np.empty(r.size)
        v, v_next = np.zeros(n_x), np.empty(n_x)
        _variant_sweeps(variant, table.index, table.weight, r, q, q_next, v, v_next, GAMMA, n)
        return (q_next if n % 2 else q).reshape(rewards.shape)

    return go


# --------------------------------------------------------------------------- measurements
def _synthesis(problem_fn):
    """Build the problem and T (fixed-width table), then run Alg. 1 to convergence."""
    t0 = time.perf_counter()
    problem = problem_fn()
    t1 = time.perf_counter()
    trans = transition_table(problem.grid, problem.next_points)
    t2 = time.perf_counter()
    result = fuzzy_q_iteration(trans, problem.rewards)
    t3 = time.perf_counter()
    if not result.converged:
        raise RuntimeError(f"Q-iteration for {problem.name} did not converge")
    return problem, trans, result, (t1 - t0, t2 - t1, t3 - t2)


def sweep_bytes(table: TransitionTable) -> int:
    """Bytes a synchronous sweep must move at least: T's indices and weights, rho, Q read
    (for the change), Q' written, V' written and V read once (its gathers hit cache)."""
    n_rows, n_x = table.shape
    return table.nbytes + 3 * 8 * n_rows + 2 * 8 * n_x


def compiled_centralized(problem, p=TABLE_I):
    """f(c_m, u) and rho of the centralized ``problem`` by the compiled RK4
    (``integrate.sample_step_compiled``), on its grid and actions."""
    nxt = sample_step_compiled("simplified", p, problem.grid.centers()[:, None, :],
                               problem.actions[None])
    return nxt, centralized_reward(nxt)


def _centralized_end_to_end(problem, p=TABLE_I, weights="float64", threads=1):
    """Centralized synthesis with the compiled transitions, a table of ``weights`` and
    sweeps on ``threads``: (seconds, result)."""
    t0 = time.perf_counter()
    nxt, rewards = compiled_centralized(problem, p)
    table = transition_table(problem.grid, nxt, weights=weights)
    result = fuzzy_q_iteration(table, rewards, threads=threads)
    return time.perf_counter() - t0, result


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
    """Rows for one of the paper's problems: our split timings, memory, the peers' ratios."""
    rows: list[Row] = []
    build = BUILDERS[name]
    times = [_synthesis(build) for _ in range(max(1, repeats))]
    problem, table, result, _ = times[-1]
    trans = transition_matrix(problem.grid, problem.next_points)     # the peers' T
    t_model, t_matrix, t_sweeps = (min(t[3][i] for t in times) for i in range(3))
    n = result.iterations
    sec = f"{SECTION}: {name}"
    rows += [
        Row(sec, "Q-table size", result.q.size, "values",
            f"{problem.grid.size} bins x {len(problem.actions)} actions"),
        Row(sec, "transition matrix nnz", trans.nnz, "entries",
            f"fixed width {table.index.shape[1]}: {table.nbytes / 2**20:.1f} MiB"),
        Row(sec, "model transitions f(c_m,u)", t_model, "s",
            "RK4 on model (11), all pairs, as the package builds the problem"),
        Row(sec, "transition matrix T", t_matrix, "s",
            "memberships -> fixed-width table (compiled)"),
        Row(sec, "sweeps to convergence", n, "sweeps", f"delta = {DELTA}"),
        Row(sec, "sweeps (to convergence)", t_sweeps, "s"),
        Row(sec, "total synthesis", t_model + t_matrix + t_sweeps, "s",
            f"best of {len(times)}"),
    ]
    mem, _ = peak_bytes(lambda: _synthesis(build))
    rows.append(Row(sec, "peak memory (synthesis)", mem / 2**20, "MiB", "tracemalloc"))

    # Equal work: every solver does exactly n sweeps from zero on the same (T, rho).
    def ours():
        res = fuzzy_q_iteration(table, problem.rewards, delta=1e-300, min_iterations=n,
                                max_iterations=n)
        if res.iterations != n:
            raise RuntimeError(f"forced {n} sweeps, did {res.iterations}")
        return res

    # The opt-in float32 weights, and the row-sum variants the package does not ship.
    table32 = transition_table(problem.grid, problem.next_points, weights="float32")

    def ours32():
        return fuzzy_q_iteration(table32, problem.rewards, delta=1e-300, min_iterations=n,
                                 max_iterations=n)

    def ours_threads():
        return fuzzy_q_iteration(table, problem.rewards, delta=1e-300, min_iterations=n,
                                 max_iterations=n, threads=THREADS)

    variants = {f"{vname}, {tb.weights}": _variant_run(vname, tb, problem.rewards, n)
                for vname in VARIANTS for tb in (table, table32)
                if (vname, tb.weights) != ("4 partial sums", "float32")}
    for fn in variants.values():
        fn()                                                # compile outside the timings

    t0 = time.perf_counter()
    qe_solve, qe_sweeps = quantecon_solver(trans, problem.rewards, n)
    v_qe, sigma_qe = qe_solve()                            # first call compiles (numba)
    t_qe_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    mdp_solve = mdptoolbox_solver(trans, problem.rewards, n, full_setup=full_setup)
    t_mdp_setup = time.perf_counter() - t0

    # Interleaved repeats: on a shared machine every solver sees the same background load.
    moved = sweep_bytes(table)
    copy = copy_bandwidth(moved // 2)          # a copy moving the bytes of one sweep
    copies = max(1, n // 4)

    def copy_n():
        return sum(copy() for _ in range(copies))

    best, out = interleaved_best({"ours": ours, "ours_float32": ours32,
                                  "ours_threads": ours_threads, "quantecon": qe_sweeps,
                                  "quantecon_solve": qe_solve, "mdptoolbox": mdp_solve,
                                  "copy": copy_n,
                                  **{f"variant: {k}": fn for k, fn in variants.items()}},
                                 sweep_repeats or repeats)
    res_n = out["ours"]
    # QuantEcon's policy is greedy in one more sweep, Q_{n+1} = rho + gamma T V_n.
    v_n = res_n.q.max(axis=1)
    q_next = (problem.rewards.reshape(-1) + GAMMA * (trans @ v_n)).reshape(res_n.q.shape)
    checks = {"quantecon": (_agreement(res_n.q, out["quantecon_solve"][0],
                                       out["quantecon_solve"][1])[0],
                            _agreement(q_next, q_next.max(axis=1),
                                       out["quantecon_solve"][1])[1]),
              "mdptoolbox": _agreement(res_n.q, *out["mdptoolbox"])}
    sweeps_only = _agreement(res_n.q, out["quantecon"], sigma_qe)[0]
    checks["quantecon"] = (max(checks["quantecon"][0], sweeps_only), checks["quantecon"][1])
    per_sweep = {k: best[k] / n for k in ("ours", "quantecon", "mdptoolbox")}
    t_qe_solve = best["quantecon_solve"]
    rows.append(Row(sec, "ours: time per sweep", per_sweep["ours"] * 1e3, "ms",
                    f"{n} forced sweeps, best of {sweep_repeats or repeats} interleaved"))
    sweep_gbs = moved / per_sweep["ours"] / 1e9
    copy_gbs = out["copy"] / best["copy"] / 1e9
    rows += [
        Row(sec, "ours: bytes per sweep", moved / 2**20, "MiB",
            "T (int32 index + float64 weight) + rho + Q + Q' + V + V'"),
        Row(sec, "ours: sweep bandwidth", sweep_gbs, "GB/s", "bytes per sweep / time per sweep"),
        Row(sec, "copy bandwidth (same bytes)", copy_gbs, "GB/s",
            f"numpy copyto of {moved / 2 / 2**20:.1f} MiB (read + write), same run"),
        Row(sec, "sweep / copy bandwidth", sweep_gbs / copy_gbs, "share"),
    ]
    rows += [
        Row(sec, "quantecon: time per sweep", per_sweep["quantecon"] * 1e3, "ms",
            "DiscreteDP bellman_operator, sparse s-a pairs"),
        Row(sec, "quantecon: solve()", t_qe_solve, "s",
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
                ">1: ours faster"),
            Row(sec, f"{peer} agreement max|dV|/max|V|", rel, "rel", "same MDP, same sweeps"),
            Row(sec, f"{peer} greedy action greedy in ours", same, "share",
                "ties count as agreement" + ("; its policy is greedy in Q_{n+1}"
                                             if peer == "quantecon" else "")),
        ]
    # float32 weights and the variants, from the same interleaved run
    per_sweep["float32"] = best["ours_float32"] / n
    moved32 = sweep_bytes(table32)
    gbs32 = moved32 / per_sweep["float32"] / 1e9
    dq32 = float(np.max(np.abs(out["ours_float32"].q - res_n.q)))
    rows += [
        Row(sec, "float32 weights: time per sweep", per_sweep["float32"] * 1e3, "ms",
            f"fqi weights='float32' (opt-in); float64 / float32 = "
            f"{per_sweep['ours'] / per_sweep['float32']:.2f}x"),
        Row(sec, "float32 weights: bytes per sweep", moved32 / 2**20, "MiB",
            "T (int32 index + float32 weight) + rho + Q + Q' + V + V'"),
        Row(sec, "float32 weights: sweep bandwidth", gbs32, "GB/s"),
        Row(sec, "float32 weights: sweep / copy bandwidth", gbs32 / copy_gbs, "share"),
        Row(sec, "quantecon / ours float32 per sweep", per_sweep["quantecon"]
            / per_sweep["float32"], "x", ">1: ours faster"),
        Row(sec, "float32 agreement max|dQ|", dq32, "abs",
            f"after the same {n} sweeps; target < delta/100 = {DELTA / 100:g}"),
    ]
    per_sweep["threads"] = best["ours_threads"] / n
    if not np.array_equal(out["ours_threads"].q, res_n.q):
        raise RuntimeError("threaded sweeps differ from one thread")
    rows += [
        Row(sec, f"{THREADS} threads: time per sweep", per_sweep["threads"] * 1e3, "ms",
            f"fqi threads={THREADS} (opt-in; bins split, same Q bit for bit); one / "
            f"{THREADS} threads = {per_sweep['ours'] / per_sweep['threads']:.2f}x"),
        Row(sec, f"quantecon / ours {THREADS} threads per sweep", per_sweep["quantecon"]
            / per_sweep["threads"], "x", ">1: ours faster (QuantEcon runs one thread)"),
        Row(sec, f"{THREADS} threads: sweep bandwidth", moved / per_sweep["threads"] / 1e9,
            "GB/s", f"share of the copy: {moved / per_sweep['threads'] / 1e9 / copy_gbs:.2f}"),
    ]
    summary_variants = {}
    for key in variants:
        t = best[f"variant: {key}"] / n
        dq = float(np.max(np.abs(out[f"variant: {key}"] - res_n.q)))
        summary_variants[key] = {"per_sweep": t, "max_dq": dq}
        what = ("not a sweep: T's bytes without the V gathers" if key.startswith("stream")
                else f"max|dQ| {dq:.2g}")
        rows.append(Row(sec, f"variant {key}: time per sweep", t * 1e3, "ms",
                        f"ours / variant = {per_sweep['ours'] / t:.2f}x; {what}"))
    summary = {"q_size": int(result.q.size), "iterations": n,
               "total": t_model + t_matrix + t_sweeps, "per_sweep": per_sweep,
               "agreement": checks, "peak_bytes": mem, "sweep_bytes": moved,
               "sweep_gbs": sweep_gbs, "copy_gbs": copy_gbs,
               "float32": {"sweep_bytes": moved32, "sweep_gbs": gbs32, "max_dq": dq32},
               "variants": summary_variants}
    if name == "centralized":
        nxt, rewards = compiled_centralized(problem)
        if not (np.array_equal(nxt, problem.next_points)
                and np.array_equal(rewards, problem.rewards)):
            raise RuntimeError("compiled transitions differ from the package's")
        ends, ends32, ends_threads = [], [], []
        for _ in range(max(1, repeats)):                   # interleaved
            ends.append(_centralized_end_to_end(problem))
            ends32.append(_centralized_end_to_end(problem, weights="float32"))
            ends_threads.append(_centralized_end_to_end(problem, threads=THREADS))
        t_rk4, _ = best_time(lambda: compiled_centralized(problem), max(1, repeats))
        end, res_end = min(ends, key=lambda e: e[0])
        end32, res32 = min(ends32, key=lambda e: e[0])
        end_threads, res_threads = min(ends_threads, key=lambda e: e[0])
        if not np.array_equal(res_threads.q, result.q):
            raise RuntimeError("end-to-end synthesis with threads differs")
        if not np.array_equal(res_end.q, result.q):
            raise RuntimeError("end-to-end synthesis with compiled transitions differs")
        moved_bins = int(np.sum(greedy_indices(res32.q) != greedy_indices(result.q)))
        rows += [
            Row(sec, "model transitions, compiled RK4", t_rk4, "s",
                "integrate.sample_step_compiled + rewards; bit-equal to the numpy path"),
            Row(sec, "total synthesis, compiled transitions", end, "s",
                f"compiled RK4 + table + sweeps, best of {len(ends)}; same Q bit for bit"),
            Row(sec, "total synthesis, compiled transitions, float32", end32, "s",
                f"compiled RK4 + float32 table + sweeps, best of {len(ends32)}; "
                f"{res32.iterations} sweeps, max|dQ| {np.max(np.abs(res32.q - result.q)):.2g}, "
                f"{moved_bins} greedy bins moved (tie tolerance {TIE_TOLERANCE:g}); "
                f"target 0.05 s"),
            Row(sec, f"total synthesis, compiled transitions, {THREADS} threads", end_threads,
                "s", f"compiled RK4 + table + sweeps on {THREADS} threads, best of "
                f"{len(ends_threads)}; same Q bit for bit; target 0.05 s"),
        ]
        summary["total_compiled_threads"] = end_threads
        summary["total_compiled"] = end
        summary["total_compiled_float32"] = end32
    return rows, summary


def bench_synthesis(*, repeats: int = 3, sweep_repeats: int | None = None,
                    full_setup: bool = False) -> tuple[list[Row], dict]:
    """The centralized problem and both decentralized agents, with the peers."""
    rows, summaries = [], {}
    for name in ("centralized", "agent2", "agent1"):
        r, s = bench_problem(name, repeats=repeats, sweep_repeats=sweep_repeats,
                             full_setup=full_setup)
        rows += r
        summaries[name] = s
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
            c["per_sweep"][fastest] / c["per_sweep"]["ours"], "x", ">= 1.5 is the target"),
        Row(sec, f"fastest peer ({fastest}) / ours float32 per sweep, centralized",
            c["per_sweep"][fastest] / c["per_sweep"]["float32"], "x",
            ">= 1.5 is the target (issue 13)"),
        Row(sec, "float32 sweep / copy bandwidth, centralized",
            c["float32"]["sweep_gbs"] / c["copy_gbs"], "share", ">= 0.7 is the target"),
        Row(sec, f"fastest peer ({fastest}) / ours {THREADS} threads per sweep, centralized",
            c["per_sweep"][fastest] / c["per_sweep"]["threads"], "x",
            ">= 1.5 is the target (the peer runs one thread)"),
    ]
    r, summaries["worst_case"] = bench_worst_case(8, repeats=repeats)
    rows += r
    r, summaries["robust"] = bench_robust_synthesis((1, 8), repeats=repeats)
    rows += r
    jit = jit_compile_seconds()
    summaries["jit_seconds"] = jit
    sec = f"{SECTION}: compiled kernels"
    rows += [Row(sec, f"JIT compile: {name}", secs, "s",
                 "first call, fresh process, empty numba cache") for name, secs in jit.items()]
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


def bench_worst_case(k: int = 8, *, repeats: int = 3) -> tuple[list[Row], dict]:
    """Robust centralized synthesis over K models: min (and mean) over k of
    rho_k + gamma T_k V in one compiled sweep; transitions by the compiled RK4."""
    problem = BUILDERS["centralized"]()
    models = worst_case_models(k)

    def synthesize(mode="worst"):
        t0 = time.perf_counter()
        tables, rewards = [], []
        for p in models:
            nxt, r = compiled_centralized(problem, p)
            tables.append(transition_table(problem.grid, nxt))
            rewards.append(r)
        t1 = time.perf_counter()
        res = fuzzy_q_iteration_robust(tables, rewards, mode=mode)
        t2 = time.perf_counter()
        if not res.converged:
            raise RuntimeError(f"robust Q-iteration ({mode}) did not converge")
        return (t1 - t0, t2 - t1), res, tables

    runs = [synthesize() for _ in range(max(1, repeats))]
    t_build = min(r[0][0] for r in runs)
    t_sweeps = min(r[0][1] for r in runs)
    total = min(sum(r[0]) for r in runs)
    _, res, tables = runs[-1]
    mean_runs = [synthesize("mean") for _ in range(max(1, repeats))]
    moved = sum(t.nbytes for t in tables) + 8 * k * tables[0].shape[0] \
        + sweep_bytes(tables[0]) - tables[0].nbytes
    per_sweep = t_sweeps / res.iterations
    sec = f"{SECTION}: worst case over K = {k} models, centralized"
    rows = [
        Row(sec, "transitions + tables (K models)", t_build, "s",
            "compiled RK4 + rewards + fixed-width tables, m1, m2, b1 scaled by 0.8/1.2"),
        Row(sec, "sweeps to convergence (worst)", res.iterations, "sweeps", f"delta = {DELTA}"),
        Row(sec, "sweeps (worst)", t_sweeps, "s", "min over k of rho_k + gamma T_k V"),
        Row(sec, "total robust synthesis (worst)", total, "s", f"best of {len(runs)}"),
        Row(sec, "time per sweep (worst)", per_sweep * 1e3, "ms"),
        Row(sec, "bytes per sweep", moved / 2**20, "MiB", "K tables + K rho + Q + Q' + V + V'"),
        Row(sec, "sweep bandwidth", moved / per_sweep / 1e9, "GB/s"),
        Row(sec, "sweeps to convergence (mean)", mean_runs[-1][1].iterations, "sweeps"),
        Row(sec, "total robust synthesis (mean)", min(sum(r[0]) for r in mean_runs), "s",
            f"best of {len(mean_runs)}"),
    ]
    return rows, {"k": k, "total": total, "sweeps_seconds": t_sweeps,
                  "iterations": res.iterations, "per_sweep": per_sweep,
                  "sweep_gbs": moved / per_sweep / 1e9}


def bench_robust_synthesis(draws=(1, 8), *, repeats: int = 3) -> tuple[list[Row], dict]:
    """The package's robust synthesis (``synthesize(..., robust="worst")``, as
    ``twolink synthesize centralized --model full --robust worst`` runs it) for K in
    ``draws``, spread 0.2, the shipped seed: model transitions (compiled RK4 over one theta1
    slice, rewards), fixed-width tables, sweeps, and the whole call, best of ``repeats``
    after one warm-up call (JIT compile times are their own rows). For K > 1 also its steps
    through the public pieces with float32 tables, and with float64 sweeps on
    :data:`THREADS` threads (checked equal to ``synthesize()`` bit for bit), best of
    ``repeats - 1``, interleaved."""
    from twolink.registry import ROBUST_SEED

    def once(k):
        t0, c0 = time.perf_counter(), time.process_time()
        pol = core.synthesize("centralized", model="full", robust="worst", draws=k,
                              spread=0.2, seed=ROBUST_SEED)
        return (time.perf_counter() - t0, pol.agents[0].info, time.process_time() - c0,
                pol.agents[0].q)

    def mirror(k, weights, threads=1):
        """``solve_robust``'s steps through the public pieces, the tables in ``weights``,
        the sweeps on ``threads``: (seconds, Q, sweeps, (model, table, sweep seconds))."""
        t0 = time.perf_counter()
        problems = [core.centralized_problem(m, model="full", compiled=True)
                    for m in core.parameter_draws(TABLE_I, k, 0.2, ROBUST_SEED)]
        t1 = time.perf_counter()
        table = robust_table(problems[0].grid, [pr.next_points for pr in problems],
                             weights=weights)
        t2 = time.perf_counter()
        res = fuzzy_q_iteration_robust(table, [pr.rewards for pr in problems], mode="worst",
                                       threads=threads)
        t3 = time.perf_counter()
        return t3 - t0, res.q, res.iterations, (t1 - t0, t2 - t1, t3 - t2)

    once(2)                                   # loads the compiled kernels
    mirror(2, "float32", THREADS)
    threaded = f"float64, {THREADS} threads"
    rows, summary = [], {}
    for k in draws:
        runs, fast = [], ({"float32": [], threaded: []} if k > 1 else {})
        for i in range(max(1, repeats)):                   # interleaved
            runs.append(once(k))
            for w in fast if i < max(1, repeats - 1) else ():
                fast[w].append(mirror(k, "float64", THREADS) if w == threaded
                               else mirror(k, w))
        best = min(r[0] for r in runs)
        part = {name: min(r[1][name] for r in runs)
                for name in ("model_seconds", "table_seconds", "sweep_seconds")}
        sweeps = runs[-1][1]["iterations"]
        sec = f"{SECTION}: robust synthesis, centralized on (6), worst case over K = {k}"
        rows += [
            Row(sec, "model transitions (K models)", part["model_seconds"], "s",
                "compiled RK4 over one theta1 slice, shifted; rewards"),
            Row(sec, "fixed-width tables (K models)", part["table_seconds"], "s",
                "memberships written straight into the layout"),
            Row(sec, "sweeps", part["sweep_seconds"], "s",
                f"{sweeps} sweeps of min_k rho_k + gamma T_k V (tables side by side)"),
            Row(sec, "total synthesize()", best, "s",
                f"best of {len(runs)}; targets: <= 1.5 s (issue 9), 0.5 s (issue 13)"),
            Row(sec, "total synthesize(), CPU time", min(r[2] for r in runs), "s",
                "process time: close to the wall time of an otherwise idle machine"),
        ]
        summary[k] = {"total": best, "cpu": min(r[2] for r in runs), "iterations": sweeps,
                      **part}
        q64 = runs[-1][3]
        if fast and not np.array_equal(fast[threaded][-1][1], q64):
            raise RuntimeError("the mirrored robust synthesis (float64, threads) differs "
                               "from synthesize()")
        for w, wruns in fast.items():
            w_best = min(r[0] for r in wruns)
            split = [min(r[3][i] for r in wruns) for i in range(3)]
            dq = float(np.max(np.abs(wruns[-1][1] - q64)))
            bins = int(np.sum(greedy_indices(wruns[-1][1]) != greedy_indices(q64)))
            rows.append(Row(sec, f"robust_table, {w}: total (problems + table + sweeps)",
                            w_best, "s",
                            f"best of {len(wruns)}, interleaved with synthesize(); models "
                            f"{split[0]:.3f} s, table {split[1]:.3f} s, {wruns[-1][2]} sweeps "
                            f"{split[2]:.3f} s; max|dQ| vs synthesize() {dq:.2g}, {bins} "
                            f"greedy bins moved; target 0.5 s"))
            summary[k][w] = {"total": w_best, "model_seconds": split[0],
                             "table_seconds": split[1], "sweep_seconds": split[2],
                             "iterations": wruns[-1][2], "max_dq": dq,
                             "greedy_bins_moved": bins}
    return rows, summary


def jit_compile_seconds() -> dict:
    """Seconds the first call of each compiled kernel takes in a fresh process with an
    empty numba cache (compile time; the cached load is a few milliseconds)."""
    import json
    import os
    import subprocess
    import sys
    import tempfile

    code = (
        "import json, time, numpy as np\n"
        "from twolink import fqi, integrate\n"
        "from twolink.fuzzy import Grid, angle_axis, speed_axis\n"
        "from twolink.parameters import TABLE_I\n"
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
    """Both schemes on grids refined k times: Q size, nnz, time, peak memory.

    The centralized problem runs for k in ``central``, the decentralized pair for k in
    ``decentral``, each only when its predicted peak memory fits ``budget_fraction`` of
    the memory available now. The prediction is peak bytes per (state-action pair x 2**d)
    measured on the largest centralized run made; up to ``estimate_to`` the rows give each
    scheme's predicted need against the machine's RAM.
    """
    rows, records = [], []
    avail = available_ram_bytes() or total_ram_bytes() or 0
    ram = total_ram_bytes() or avail
    budget = budget_fraction * avail
    coeff = None          # peak bytes per (pair * 2**d), measured
    asked = {"centralized": set(central), "decentralized": set(decentral)}
    for k in range(1, max(max(central), max(decentral), estimate_to) + 1):
        for scheme, parts in (("centralized", ("centralized",)),
                              ("decentralized", ("agent2", "agent1"))):
            dims = [_pairs(p, k) for p in parts]
            q_size = sum(n * u for n, u, _ in dims)
            work = sum(n * u * 2 ** d for n, u, d in dims)
            need = coeff * work if coeff else None
            rec = {"k": k, "scheme": scheme, "q_size": q_size,
                   "bins": [n for n, _, _ in dims], "predicted_bytes": need}
            run = k in asked[scheme] and (need is None or need <= budget)
            if run:
                total, peak, nnz, sweeps = 0.0, 0, 0, 0
                for part in parts:
                    mem, (problem, trans, result, t) = peak_bytes(
                        lambda part=part: _synthesis(lambda: BUILDERS[part](k)))
                    total += sum(t)
                    peak = max(peak, mem)
                    nnz += trans.nnz
                    sweeps = max(sweeps, result.iterations)
                    rec[f"{part}_seconds"] = t
                    rec[f"{part}_sweeps"] = result.iterations
                    del problem, trans, result
                if scheme == "centralized":
                    coeff = peak / work
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
