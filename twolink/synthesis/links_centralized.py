"""The centralized policy (16) for an arm of N links, where it fits in memory.

The problem (16) for N links: the grid over x = [theta_1..theta_N, dtheta_1..dtheta_N]
(each angle :func:`twolink.fqi.fuzzy.angle_axis`, each speed :func:`twolink.fqi.fuzzy.speed_axis`),
the 3**N joint actions {-tau_k max, 0, tau_k max} (the last joint varying fastest), reward
(15) over every link (0 when all are in the goal band, else -0.5) on the state reached,
and transitions of the full N-link model (:func:`twolink.arm.dynamics.links_acceleration`;
(6) itself for two links) over Ts. That is 7056 x 9 Q-values for N = 2, 592 704 x 27 = 16 M
for N = 3 and 4.0e9 for N = 4.

The horizontal arm's dynamics do not depend on theta_1, so only the theta_1 = 0 slice is
integrated (in blocks, so the model's working set stays bounded) and T is stored factored
(:class:`twolink.fqi.factored.FactoredTable`): 0.9 GB for N = 3 instead of 12 GB.
:func:`estimate` says what a synthesis needs before any work; :func:`synthesize_centralized`
refuses one over :data:`MAX_BYTES` with that estimate.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import os
import resource
import time
from typing import Optional

import numpy as np

from twolink.arm import dynamics
from twolink.arm.integrate import SUBSTEPS, sample_step, wrap_angle
from twolink.arm.parameters import (
    DELTA,
    GAMMA,
    REWARD_GOAL,
    REWARD_OTHER,
    TS,
    ArmParameters,
    LinksParameters,
    check_links,
    state_names,
)
from twolink.arm.task import link_in_band
from twolink.artifacts import VERSION as __version__
from twolink.fqi import fuzzy
from twolink.fqi.factored import FactoredBuilder, default_threads, factored_q_iteration
from twolink.policy.fuzzy_policy import Agent, Policy
from twolink.sim.progress import progress_bar
from twolink.validate import whole


def _physical_memory() -> int:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 8 << 30


#: The share of the machine's physical memory a centralized synthesis may use by default.
MEMORY_SHARE = 0.6
#: The default cap on a synthesis's estimated peak memory (bytes): MEMORY_SHARE of this
#: machine's physical memory.
MAX_BYTES = int(MEMORY_SHARE * _physical_memory())
#: (slice bin, action) pairs integrated at once: bounds the model's working set.
BLOCK_PAIRS = 1 << 15

# CPU rates measured on the development machine (N = 3 tapered, 2-core, numpy RK4), for
# the time estimate only: seconds per (slice bin, action) pair and link squared of the RK4
# over Ts, per stored membership of building the table, per membership read in a sweep.
_RK4_SECONDS = 0.7e-6
_TABLE_SECONDS = 3.7e-8
_SWEEP_SECONDS = 0.94e-9
# Bytes per pair alive while a block is integrated and its memberships computed.
_BLOCK_BYTES_PER_PAIR = 4096


@dataclasses.dataclass(frozen=True)
class Estimate:
    """What a centralized synthesis of an N-link arm needs, known before any work.

    ``states`` x ``actions`` = ``q_values``; ``nnz`` the logical non-zeros of T (2**(2N)
    memberships per row), ``dense_bytes`` T as index + weight pairs (12 bytes each),
    ``stored_bytes`` the factored table actually built, ``q_bytes`` one Q-table (float64),
    ``peak_bytes`` everything alive at once (Q twice, V twice, the rewards, the table and
    one block of transitions; the interpreter's own 0.2 GiB come on top); ``sweeps_bound`` the most sweeps Alg. 1 can take
    (gamma**(l-1) * 0.5 <= delta) and ``seconds`` the CPU time at that bound, from rates
    measured on the development machine (an upper estimate: N = 2 stops after 78 sweeps,
    N = 3 after about 100; the sweeps share two threads, so wall time can be half).
    """

    links: int
    refine: int
    states: int
    actions: int
    q_values: int
    nnz: int
    dense_bytes: int
    stored_bytes: int
    q_bytes: int
    peak_bytes: int
    sweeps_bound: int
    seconds: float

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def grid(links: int, refine: int = 1) -> fuzzy.Grid:
    """The grid of (16) for ``links`` links: an angle axis per theta_k, then a speed axis
    per dtheta_k, the paper's bins each subdivided ``refine`` times."""
    n = check_links(links)
    refine = whole(refine, "refine", 1)
    names = state_names(n)
    axes = [fuzzy.angle_axis(a) for a in names[:n]] + [fuzzy.speed_axis(s) for s in names[n:]]
    return fuzzy.Grid(tuple(a.refined(refine) for a in axes))


def actions(p) -> np.ndarray:
    """The joint actions of (16): every combination of {-tau_k max, 0, tau_k max}, shape
    (3**N, N), the last joint varying fastest (``synthesis.centralized_actions`` for N = 2)."""
    levels = [(-t, 0.0, t) for t in np.asarray(p.tau_max, dtype=float)]
    return np.array(list(itertools.product(*levels)))


def estimate(links: int, refine: int = 1, *, gamma: float = GAMMA,
             delta: float = DELTA) -> Estimate:
    """The :class:`Estimate` of a centralized synthesis for ``links`` links on the paper's
    grid refined ``refine`` times (pure arithmetic, no allocation)."""
    n = check_links(links)
    refine = whole(refine, "refine", 1)
    _check_gamma_delta(gamma, delta)
    angles = len(fuzzy.ANGLE_BINS_DEG) * refine
    speeds = (len(fuzzy.SPEED_BINS_DEG) - 1) * refine + 1
    states = angles ** n * speeds ** n
    n_u = 3 ** n
    q_values = states * n_u
    pairs = states // angles * n_u          # (slice bin, action) pairs of the theta_1 = 0 slice
    width = 2 ** (2 * n - 1)
    nnz = q_values * 2 ** (2 * n)
    stored = pairs * 12 * (width + 2 * angles)
    q_bytes = 8 * q_values
    peak = stored + 3 * q_bytes + 16 * states + min(pairs, BLOCK_PAIRS) * _BLOCK_BYTES_PER_PAIR
    bound = 1 + math.ceil(math.log(delta / abs(REWARD_OTHER)) / math.log(gamma))
    seconds = pairs * (_RK4_SECONDS * n * n + _TABLE_SECONDS * (width + 2 * angles)) \
        + bound * _SWEEP_SECONDS * pairs * angles * (width + 2)
    return Estimate(n, refine, states, n_u, q_values, nnz, 12 * nnz, stored, q_bytes, peak,
                    bound, seconds)


def _check_gamma_delta(gamma, delta) -> None:
    if not isinstance(gamma, (int, float)) or not 0.0 < gamma < 1.0:
        raise ValueError(f"gamma must lie in (0, 1), got {gamma!r}")
    if not isinstance(delta, (int, float)) or not 0.0 < delta < abs(REWARD_OTHER):
        raise ValueError(f"delta must lie in (0, {abs(REWARD_OTHER)}), got {delta!r}")


def _duration(seconds: float) -> str:
    for unit, size in (("years", 365.25 * 86400.0), ("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.2g} s"


def _size(b: int) -> str:
    """Bytes in GiB, TiB, PiB or EiB, three digits."""
    for unit in ("GiB", "TiB", "PiB"):
        if b < 1000 * 2 ** 30:
            return f"{b / 2 ** 30:.3g} {unit}"
        b /= 1024
    return f"{b / 2 ** 30:.3g} EiB"


def check_size(links: int, refine: int = 1, max_bytes: Optional[int] = None, *,
               gamma: float = GAMMA, delta: float = DELTA) -> Estimate:
    """:func:`estimate`, or a ValueError with it when its peak exceeds ``max_bytes``
    (default :data:`MAX_BYTES`)."""
    cap = MAX_BYTES if max_bytes is None else max_bytes
    whole(cap, "max_bytes", 1)
    est = estimate(links, refine, gamma=gamma, delta=delta)
    if est.peak_bytes > cap:
        raise ValueError(
            f"centralized {est.links}-link synthesis needs about {_size(est.peak_bytes)} "
            f"(Q-table {_size(est.q_bytes)} for {est.q_values:.3g} Q-values, T "
            f"{_size(est.stored_bytes)} factored, {_size(est.dense_bytes)} as a plain "
            f"sparse matrix; up to {_duration(est.seconds)} of CPU), over the cap of "
            f"{_size(int(cap))}; use the decentralized agents, or raise the cap "
            f"(max_bytes) on a larger machine")
    return est


def _model(p):
    """(parameters, acceleration) of the full model: (6) itself for two links."""
    if p.links == 2:
        arm = p if isinstance(p, ArmParameters) else p.as_arm()
        return arm, dynamics.full_acceleration
    return p, dynamics.links_acceleration


def factored_problem(p, g: Optional[fuzzy.Grid] = None, *, progress: bool = False) -> tuple:
    """(T, rewards, clocks) of (16) for arm ``p`` on grid ``g`` (default :func:`grid`; its
    axes in the order of :func:`twolink.arm.parameters.state_names`, theta_1 first): the
    :class:`~twolink.fqi.factored.FactoredTable` of the transitions, the rewards (15) on the
    states reached (N_X, N_U), and the seconds (wall, CPU) of the model and of the table.
    The theta_1 = 0 slice is integrated in blocks of :data:`BLOCK_PAIRS` pairs and every
    theta_1 bin's reached angle is theta_1 + the slice's (the dynamics ignore theta_1)."""
    g = grid(p.links) if g is None else g
    if g.names != state_names(p.links):
        raise ValueError(f"a {p.links}-link grid needs axes {', '.join(state_names(p.links))}, "
                         f"got {', '.join(g.names)}")
    acts = actions(p)
    n, n_u = p.links, len(acts)
    params, accel = _model(p)
    theta1 = np.asarray(g.axes[0].centers)
    builder = FactoredBuilder(g, n_u)
    rest = builder.rest.centers()
    n_slice = len(rest)
    rewards = np.empty((g.axes[0].size, n_slice, n_u))
    step = max(1, BLOCK_PAIRS // n_u)
    clocks = {"model": [0.0, 0.0], "table": [0.0, 0.0]}
    with progress_bar(total=n_slice, desc=f"transitions {n}-link", unit=" bins", leave=False,
                      enabled=progress, mininterval=0.25) as bar:
        for r0 in range(0, n_slice, step):
            t0, c0 = time.perf_counter(), time.process_time()
            block = rest[r0:r0 + step]
            x = np.concatenate([np.zeros((len(block), 1)), block], axis=1)
            y = sample_step(accel, params, x[:, None, :], acts[None, :, :])
            first = wrap_angle(theta1[None, None, :] + y[..., :1])      # (n, N_U, B)
            inside = link_in_band(first, y[..., n:n + 1])
            for k in range(1, n):
                inside &= link_in_band(y[..., k], y[..., n + k])[..., None]
            rewards[:, r0:r0 + len(x)] = np.where(inside, REWARD_GOAL,
                                                  REWARD_OTHER).transpose(2, 0, 1)
            t1, c1 = time.perf_counter(), time.process_time()
            builder.add(r0, y[..., 1:], first)
            clocks["model"][0] += t1 - t0
            clocks["model"][1] += c1 - c0
            clocks["table"][0] += time.perf_counter() - t1
            clocks["table"][1] += time.process_time() - c1
            bar.update(len(x))
    return builder.table(), rewards.reshape(-1, n_u), clocks


def synthesize_centralized(p, *, max_bytes: Optional[int] = None, progress: bool = False,
                           gamma: float = GAMMA, delta: float = DELTA, refine: int = 1,
                           threads: Optional[int] = None) -> Policy:
    """The centralized policy (16) of an N-link arm ``p`` (a LinksParameters, or Table I's
    ArmParameters), synthesised by synchronous sweeps of Alg. 1 on the full model, or a
    ValueError with the :func:`estimate` when that exceeds ``max_bytes`` (default
    :data:`MAX_BYTES`). One agent, "centralized", reads theta1..thetaN, dtheta1..dthetaN and
    outputs tau1..tauN; ``meta`` records the parameters, links, gamma, delta, the timings
    (wall and CPU: model, table, sweeps), sweeps, non-zeros and bytes. For two links it is
    the shipped ``centralized_full`` up to round-off. The Q-table stays in memory (for
    N >= 3 it exceeds what a policy file may hold)."""
    if not isinstance(p, (ArmParameters, LinksParameters)):
        raise ValueError(f"p must be ArmParameters or LinksParameters, got {type(p).__name__}")
    est = check_size(p.links, refine, max_bytes, gamma=gamma, delta=delta)
    threads = default_threads() if threads is None else threads
    whole(threads, "threads", 1)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    g = grid(p.links, refine)
    table, rewards, clocks = factored_problem(p, g, progress=progress)
    nnz, stored = table.nnz, table.nbytes
    c0 = time.process_time()
    with progress_bar(desc=f"Q-iteration centralized {p.links}-link", unit=" sweeps",
                      leave=False, enabled=progress, mininterval=0.25) as bar:
        def tick(ell, change):
            bar.update(1)
            bar.set_postfix(change=f"{change:.3g}")
        result = factored_q_iteration(table, rewards, gamma=gamma, delta=delta,
                                      callback=tick, threads=threads)
    sweep_cpu = time.process_time() - c0
    del table, rewards
    if not result.converged:
        raise RuntimeError(f"Q-iteration for the centralized {p.links}-link arm did not "
                           f"converge")
    timings = {"model_seconds": clocks["model"][0], "model_cpu_seconds": clocks["model"][1],
               "table_seconds": clocks["table"][0], "table_cpu_seconds": clocks["table"][1],
               "sweep_seconds": result.seconds, "sweep_cpu_seconds": sweep_cpu,
               "seconds": time.perf_counter() - wall0,
               "cpu_seconds": time.process_time() - cpu0, "threads": threads}
    sizes = {"stored_bytes": stored, "dense_bytes": 12 * nnz, "q_bytes": 8 * result.q.size,
             "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
             "estimate": est.as_dict()}
    info = {"iterations": result.iterations, "sweeps": "synchronous", "converged": True,
            "final_change": float(result.history[-1]), "q_size": int(result.q.size),
            "transition_nnz": nnz, **timings}
    agent = Agent("centralized", g, actions(p), result.q, tuple(f"tau{k}" for k in
                                                          range(1, p.links + 1)), info)
    meta = {"parameters": p.as_dict(), "links": p.links, "model": "full", "gamma": gamma,
            "delta": delta, "ts": TS, "substeps": SUBSTEPS,
            "reward": "r_{k+1} on the state reached", "twolink_version": __version__,
            "sweeps": "synchronous", "iterations": result.iterations, "refine": refine,
            "transitions": "theta_1 = 0 slice, T factored (twolink.fqi.factored)",
            "timings": timings, "nnz": nnz, "bytes": sizes}
    return Policy("centralized", [agent], meta)
