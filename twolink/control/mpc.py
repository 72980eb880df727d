"""Receding-horizon time-optimal control: the limit's problem re-solved every sample.

At the first sample of a run, :func:`.search.search` finds the fewest samples N in which
the band can be reached and held from the measured state, and the hold answer's torques
(band at samples N..N+hold, at rest at N+hold; :mod:`.nlp`). At every later sample the
same hold problem is solved again from the measured state, with N one sample shorter
(at least 1), warm-started from the last plan shifted by one sample: one IPOPT solve per
sample. The first torque of the answer is applied (clipped to +-tau_max); a row that
starts in the band, or for which the search finds no way into it, gets zero torque. An
answer that misses the band (slack s > 0, the plant not being the model) keeps N for the
next sample instead of shortening it, and its torques still drive the arm as near as
they can.

Each batch row has its own plan (a Python loop over the rows, one NLP each): this is a
controller of the protocol of :mod:`twolink.sim.controller`, but a slow one; ``timings``
records the seconds of every sample's computation per row. CasADi is needed
(``pip install 'twolink[limits]'``).
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from twolink.arm.parameters import TABLE_I, ArmParameters
from twolink.arm.task import in_goal_band
from twolink.limits.nlp import ProblemCache
from twolink.limits.search import search, targets_of, wrap_state
from twolink.limits.symbolic import check_model, require_casadi

#: IPOPT's settings for the re-solves: the problem expanded to scalar symbols (SX) and a
#: limited-memory Hessian (no second derivatives of the RK4 step); measured the fastest
#: of the settings tried (benchmarks/mpc.py).
FAST_OPTIONS = {"expand": True, "ipopt.hessian_approximation": "limited-memory"}


@dataclasses.dataclass
class Plan:
    """One row's plan: ``n`` samples to the band, the targets (2,), the planned states
    (K+1, 4, angles unwrapped) and torques (K, 2), K = n + hold."""

    n: int
    targets: np.ndarray
    states: np.ndarray
    torques: np.ndarray


#: The plan of a row whose first search found no way into the band within
#: ``max_samples``: it gets zero torque from then on.
UNREACHABLE = "unreachable"


def _fit(states: np.ndarray, torques: np.ndarray, k: int) -> tuple:
    """States (k+1, 4) and torques (k, 2): cut, or padded with the last state at rest and
    zero torque."""
    if len(torques) >= k:
        return states[:k + 1].copy(), torques[:k].copy()
    last = states[-1].copy()
    last[2:] = 0.0
    pad = k - len(torques)
    return (np.r_[states, np.tile(last, (pad, 1))], np.r_[torques, np.zeros((pad, 2))])


class TimeOptimalMPC:
    """The receding-horizon controller of the module docstring on ``model`` (``full`` or
    ``simplified``) with ``params``; ``hold`` samples of band after N, ``max_samples`` and
    ``starts`` for the first search (:func:`.search.search`). ``expand`` builds each
    horizon's solver in scalar symbols (about a second per horizon to build, faster
    solves after); ``options`` replace IPOPT's settings of the re-solves
    (:data:`FAST_OPTIONS`)."""

    name = "time_optimal_mpc"
    kind = "centralized"

    def __init__(self, model: str = "full", params: ArmParameters = TABLE_I, *,
                 hold: int = 4, max_samples: int = 60, starts: int = 1,
                 expand: bool = True, options: dict | None = None):
        require_casadi()
        self.model = check_model(model)
        self.params = params
        self.hold, self.max_samples, self.starts = int(hold), int(max_samples), int(starts)
        fast = dict(FAST_OPTIONS if options is None else options, expand=bool(expand))
        self.search_cache = ProblemCache(params, {"expand": bool(expand)})
        self.cache = ProblemCache(params, fast)
        self.meta = {"model": model, "parameters": params.as_dict()}
        self.reset(1)

    def reset(self, n: int) -> None:
        """Forget every plan: the next call plans each of ``n`` rows from scratch."""
        self.plans: list = [None] * int(n)
        self.timings: list = [[] for _ in range(int(n))]

    def _first(self, x: np.ndarray) -> Plan | None:
        r = search(x, self.model, self.search_cache, max_samples=self.max_samples,
                   starts=self.starts, hold=self.hold, nearest=False)
        if r.hold is None:                       # out of reach in max_samples, or in band
            return None
        return Plan(int(r.upper), targets_of(r.winding), r.hold.states, r.hold.torques)

    def _again(self, plan: Plan, x: np.ndarray) -> Plan:
        predicted = plan.states[1]
        x = x.copy()
        x[:2] += 2.0 * math.pi * np.round((predicted[:2] - x[:2]) / (2.0 * math.pi))
        n = max(plan.n - 1, 1)
        k = n + self.hold
        guess = _fit(plan.states[1:], plan.torques[1:], k)
        sol = self.cache.solve(self.model, k, x, plan.targets, *guess, first=n, rest=True)
        if not sol.converged:
            sol = self.cache.solve(self.model, k, x, plan.targets, *_fit(
                np.r_[x[None], plan.states[2:]], plan.torques[1:], k), first=n, rest=True)
        if not sol.feasible():
            n = min(plan.n, self.max_samples)   # not reached: keep N, not shorter
        return Plan(n, plan.targets, sol.states, sol.torques)

    def _row(self, i: int, x: np.ndarray) -> np.ndarray:
        plan = self.plans[i]
        if plan is UNREACHABLE:
            return np.zeros(2)
        plan = self._first(x) if plan is None else self._again(plan, x)
        if plan is None and not in_goal_band(x):
            plan = UNREACHABLE                   # no plan in max_samples: search no more
        self.plans[i] = plan
        if plan is None or plan is UNREACHABLE:
            return np.zeros(2)
        return np.clip(plan.torques[0], -self.params.tau_max, self.params.tau_max)

    def __call__(self, x) -> np.ndarray:
        x = wrap_state(np.asarray(x, dtype=float).reshape(-1, 4))
        if len(self.plans) != len(x):
            self.reset(len(x))
        u = np.empty((len(x), 2))
        for i, row in enumerate(x):
            t0 = time.perf_counter()
            u[i] = self._row(i, row)
            self.timings[i].append(time.perf_counter() - t0)
        return u
