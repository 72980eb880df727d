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
import time
import warnings
from unittest import mock

import numpy as np
import scipy.sparse as sp

from benchmarks.common import (Row, available_ram_bytes, interleaved_best, peak_bytes,
                               total_ram_bytes)
from twolink import synthesis as core
from twolink.fqi import fuzzy_q_iteration, transition_matrix
from twolink.parameters import DELTA, GAMMA

SECTION = "synthesis"
SCALING = "scaling"


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
def _synthesis(problem_fn):
    """Build the problem and T, then run Alg. 1 to convergence."""
    t0 = time.perf_counter()
    problem = problem_fn()
    t1 = time.perf_counter()
    trans = transition_matrix(problem.grid, problem.next_points)
    t2 = time.perf_counter()
    result = fuzzy_q_iteration(trans, problem.rewards)
    t3 = time.perf_counter()
    if not result.converged:
        raise RuntimeError(f"Q-iteration for {problem.name} did not converge")
    return problem, trans, result, (t1 - t0, t2 - t1, t3 - t2)


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
    problem, trans, result, _ = times[-1]
    t_model, t_matrix, t_sweeps = (min(t[3][i] for t in times) for i in range(3))
    n = result.iterations
    sec = f"{SECTION}: {name}"
    rows += [
        Row(sec, "Q-table size", result.q.size, "values",
            f"{problem.grid.size} bins x {len(problem.actions)} actions"),
        Row(sec, "transition matrix nnz", trans.nnz, "entries"),
        Row(sec, "model transitions f(c_m,u)", t_model, "s", "RK4 on model (11), all pairs"),
        Row(sec, "transition matrix T", t_matrix, "s", "memberships -> scipy CSR"),
        Row(sec, "sweeps to convergence", n, "sweeps", f"delta = {DELTA}"),
        Row(sec, "sweeps (to convergence)", t_sweeps, "s"),
        Row(sec, "total synthesis", t_model + t_matrix + t_sweeps, "s",
            f"best of {len(times)}"),
    ]
    mem, _ = peak_bytes(lambda: _synthesis(build))
    rows.append(Row(sec, "peak memory (synthesis)", mem / 2**20, "MiB", "tracemalloc"))

    # Equal work: every solver does exactly n sweeps from zero on the same (T, rho).
    def ours():
        res = fuzzy_q_iteration(trans, problem.rewards, delta=1e-300, min_iterations=n,
                                max_iterations=n)
        if res.iterations != n:
            raise RuntimeError(f"forced {n} sweeps, did {res.iterations}")
        return res

    t0 = time.perf_counter()
    qe_solve, qe_sweeps = quantecon_solver(trans, problem.rewards, n)
    v_qe, sigma_qe = qe_solve()                            # first call compiles (numba)
    t_qe_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    mdp_solve = mdptoolbox_solver(trans, problem.rewards, n, full_setup=full_setup)
    t_mdp_setup = time.perf_counter() - t0

    # Interleaved repeats: on a shared machine every solver sees the same background load.
    best, out = interleaved_best({"ours": ours, "quantecon": qe_sweeps,
                                  "quantecon_solve": qe_solve, "mdptoolbox": mdp_solve},
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
    summary = {"q_size": int(result.q.size), "iterations": n,
               "total": t_model + t_matrix + t_sweeps, "per_sweep": per_sweep,
               "agreement": checks, "peak_bytes": mem}
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
            c["per_sweep"][fastest] / c["per_sweep"]["ours"], "x", ">= 1 is the target"),
    ]
    return rows, summaries


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
