"""The search over the number of samples N, the windings and the initial guesses.

For one initial state x0 (angles wrapped to [-pi, pi)) and one model:

1. *windings*: link i may end in the band around 0 or around the other representative
   of 0 on its side, 2 pi k_i with k_i = -1 for theta_i < 0 and +1 for theta_i > 0 (one
   or two per link, so one to four targets);
2. *screen*: the reach problem (band at sample N, :mod:`.nlp`) at an estimate N0 for
   every winding from a smooth guess;
3. *walk*: from the best screened winding, N down while the reach problem stays
   feasible (or up until it becomes so: by the secant of the slack over N, then back
   down), each solve warm-started from the last one stretched in time; every other winding then only tries to beat that N;
4. *lower bound*: N - 1 again for every winding from ``starts`` initial guesses (the
   warm start, the smooth guess, a bang-bang rollout, then random torque rollouts);
   any feasible answer lowers N and the step repeats. A winding whose answer at some
   N' >= N - 1 still ends more than :data:`PRUNE_SLACK` band widths from its target is
   left out of this step. ``lower`` is the smallest N found
   feasible: no start found N - 1 feasible (IPOPT is a local solver, so this is the
   search's bound, not a proof);
5. *upper bound*: from N = lower up, the hold problem (band at samples N..N+T and the
   arm at rest at N+T, T = ``hold``) from the reach answer; its torques are replayed on
   the numpy model (wrap, clip and saturation included) with zero torque for 1 s after
   N+T, and ``upper`` is the first N whose replay is in the band at every sample from N
   on and at rest at its end (zero torque then holds it there for ever).
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from twolink.arm import dynamics
from twolink.arm.integrate import SUBSTEPS, rk4, sample_step, wrap_angle
from twolink.arm.parameters import TS, ArmParameters
from twolink.arm.task import in_goal_band
from twolink.limits.nlp import ProblemCache, Solution

#: Margin of slack a hold answer needs (s <= -HOLD_MARGIN: strictly inside the band).
HOLD_MARGIN = 1e-6
#: A winding whose best end state at some N' >= N - 1 lies more than this many band
#: widths from its target (slack s) is not tried at N - 1 from further starts.
PRUNE_SLACK = 8.0
#: Samples of zero torque the replay runs after the torques end (1 s).
REPLAY_AFTER = 20
#: Speeds (rad/s) under which the replay's last state counts as at rest.
REST_SPEED = 1e-6
#: Most samples one step of the walk up N may jump.
MAX_JUMP = 6
#: Names of the initial guesses, in the order ``starts`` takes them (random ones follow).
START_NAMES = ("warm", "smooth", "bang")


@dataclasses.dataclass
class SearchResult:
    """What :func:`search` found for one state (see the module docstring)."""

    lower: int
    upper: int | None
    winding: tuple
    reach: Solution | None
    hold: Solution | None
    replay: np.ndarray | None
    solves: int
    seconds: float


def wrap_state(x) -> np.ndarray:
    """States (..., 4) with their angles in [-pi, pi): those already there unchanged
    (bit for bit), the others wrapped."""
    x = np.array(x, dtype=float)
    a = x[..., :2]
    out = (a < -math.pi) | (a >= math.pi)
    x[..., :2] = np.where(out, wrap_angle(a), a)
    return x


def windings(x0) -> list:
    """The winding numbers (k1, k2) tried: per link 0 and the other side's -1 or +1."""
    per = [(0,) if x0[i] == 0 else (0, -1 if x0[i] < 0 else 1) for i in range(2)]
    return [(a, b) for a in per[0] for b in per[1]]


def targets_of(w) -> np.ndarray:
    return 2.0 * math.pi * np.asarray(w, dtype=float)


def estimate(x0, p: ArmParameters) -> int:
    """A first guess of N (the screen's): each link's bang-bang time over its shorter
    way to the band at the acceleration its motor gives it alone."""
    m = dynamics.mass_matrix(p, np.asarray(x0[1], float))
    worst = 0.0
    for i in range(2):
        d = max(abs(float(x0[i])) - 0.087, 0.0)
        a = p.tau_max[i] / m[i, i]
        v = p.speed_max[i]
        t = 2.0 * math.sqrt(d / a) if d < v * v / a else d / v + v / a
        worst = max(worst, t)
    return max(1, int(math.ceil(worst / TS)))


def smooth_guess(x0, targets, n: int, k: int) -> tuple:
    """States moving from x0 to the targets along a smoothstep over n samples, then at
    rest; zero torques."""
    t = np.minimum(np.arange(k + 1) / n, 1.0)[:, None]
    d = (targets - x0[:2])[None]
    states = np.empty((k + 1, 4))
    states[:, :2] = x0[:2] + d * (3 * t**2 - 2 * t**3)
    states[:, 2:] = d * (6 * t - 6 * t**2) / (n * TS)
    states[0] = x0
    return states, np.zeros((k, 2))


def rollout_guess(model: str, p: ArmParameters, x0, torques) -> tuple:
    """States of the numpy model under ``torques`` (unwrapped, speeds saturated): a
    guess whose defects vanish."""
    accel = dynamics.MODELS[model]
    states = np.empty((len(torques) + 1, 4))
    states[0] = x = np.asarray(x0, float)
    for j, u in enumerate(torques):
        x = rk4(accel, p, x, u, TS, SUBSTEPS)
        x[2:] = np.clip(x[2:], -p.speed_max, p.speed_max)
        states[j + 1] = x
    return states, np.asarray(torques, float)


def bang_guess(model: str, p: ArmParameters, x0, targets, n: int, k: int) -> tuple:
    """Full torque toward each link's target for the first half of n samples, full
    torque against it for the second half, then none: rolled out."""
    sign = np.sign(targets - x0[:2])
    u = np.zeros((k, 2))
    half = max(1, n // 2)
    u[:half] = sign * p.tau_max
    u[half:n] = -sign * p.tau_max
    return rollout_guess(model, p, x0, u)


def random_guess(model: str, p: ArmParameters, x0, n: int, k: int, seed: int) -> tuple:
    """Uniformly random torques (a seeded draw) over n samples, rolled out."""
    rng = np.random.default_rng(seed)
    u = np.zeros((k, 2))
    u[:n] = rng.uniform(-1.0, 1.0, (n, 2)) * p.tau_max
    return rollout_guess(model, p, x0, u)


def resample(sol: Solution, n_old: int, n: int, k: int) -> tuple:
    """The answer ``sol`` (band at n_old) stretched in time to reach at n over k
    samples: states interpolated (speeds scaled), torques scaled by the square of the
    time ratio; after n the last state at rest."""
    r = n_old / n
    old = sol.states
    idx = np.minimum(np.arange(k + 1) * r, n_old)
    states = np.empty((k + 1, 4))
    for c in range(4):
        states[:, c] = np.interp(idx, np.arange(len(old)), old[:, c])
    states[:, 2:] *= r
    states[idx >= n_old, 2:] = 0.0
    torques = np.zeros((k, 2))
    j = np.minimum(np.floor(np.arange(k) * r).astype(int), len(sol.torques) - 1)
    torques[:] = sol.torques[j] * r * r
    torques[np.arange(k) >= n] = 0.0
    return states, torques


def replay(model: str, p: ArmParameters, x0, torques, samples: int, *,
           after: int = REPLAY_AFTER) -> tuple:
    """The numpy model's states (wrapped) under ``torques`` then zero torque for ``after``
    more samples, and whether the states are in the goal band at every sample from
    ``samples`` on and the arm at rest at the end (speeds within :data:`REST_SPEED`:
    zero torque then keeps it where it is)."""
    accel = dynamics.MODELS[model]
    total = len(torques) + after
    u = np.zeros((total, 2))
    u[:len(torques)] = torques
    states = np.empty((total + 1, 4))
    states[0] = x = np.asarray(x0, float)
    for j in range(total):
        x = sample_step(accel, p, x, u[j])
        states[j + 1] = x
    rest = bool(np.all(np.abs(states[-1, 2:]) <= REST_SPEED))
    return states, bool(np.all(in_goal_band(states[samples:]))) and rest


def search(x0, model: str, cache: ProblemCache, *, max_samples: int, starts: int,
           hold: int, nearest: bool = False) -> SearchResult:
    """The lower and upper bounds of x0 on ``model`` (see the module docstring);
    ``nearest`` tries the band around 0 of the wrapped angles only (winding (0, 0))."""
    t_start = time.perf_counter()
    p = cache.params
    solves0 = cache.solves
    x0 = wrap_state(x0)
    if in_goal_band(x0):
        return SearchResult(0, 0, (0, 0), None, None, x0[None], 0, 0.0)
    ws = [(0, 0)] if nearest else windings(x0)
    tried: dict = {}

    def reach(w, n, guess, name):
        key = (w, n, name)
        if key not in tried:
            tried[key] = cache.solve(model, n, x0, targets_of(w), *guess)
        return tried[key]

    def start_guesses(w, n, warm):
        """(name, guess) of the first ``starts`` initial guesses at n, less the warm
        start when ``warm`` is an answer at n already (it counts as one)."""
        t = targets_of(w)
        names = ["smooth", "bang"] + [f"random{i}" for i in range(max(0, starts - 3))]
        if warm is not None:
            names.insert(0, "warm")
        out = []
        for name in names[:starts]:
            if name == "warm":
                if warm[0] != n or not warm[1].converged:
                    out.append((name, resample(warm[1], warm[0], n, n)))
            elif name == "smooth":
                out.append((name, smooth_guess(x0, t, n, n)))
            elif name == "bang":
                out.append((name, bang_guess(model, p, x0, t, n, n)))
            else:
                out.append((name, random_guess(model, p, x0, n, n, int(name[6:]))))
        return out

    def out_of_reach(w, n):
        """The winding's answer at some n' >= n ended PRUNE_SLACK band widths off."""
        m, sol = known[w]
        return m >= n and sol.converged and sol.s > PRUNE_SLACK

    def walk_up(w, n, sol):
        """N up from an infeasible answer until feasible: one sample at first, then
        the secant of the slack over N predicts the jump (at most MAX_JUMP)."""
        last = None
        while n < max_samples and not sol.feasible():
            step = 1
            if last is not None and sol.converged and last[1].converged:
                slope = (sol.s - last[1].s) / (n - last[0])
                if slope < 0:
                    step = int(min(MAX_JUMP, max(1, math.floor(0.8 * sol.s / -slope))))
            m = min(n + step, max_samples)
            last = (n, sol)
            n, sol = m, reach(w, m, resample(sol, n, m, m), "warm")
        return n, sol

    n0 = min(estimate(x0, p), max_samples)
    screen = {w: (n0, reach(w, n0, smooth_guess(x0, targets_of(w), n0, n0), "smooth"))
              for w in ws}
    known = dict(screen)           # winding -> (n, its latest answer) for warm starts
    lower, best = None, None
    for w in sorted(ws, key=lambda v: screen[v][1].s):
        n, sol = screen[w]
        if lower is not None:
            if lower == 1:
                break
            if out_of_reach(w, lower - 1):
                continue
            if n != lower - 1:
                n, sol = lower - 1, reach(w, lower - 1, resample(sol, n, lower - 1,
                                                                 lower - 1), "warm")
                known[w] = (n, sol)
            if not sol.feasible():
                continue
        if sol.feasible():
            while n > 1:
                nxt = reach(w, n - 1, resample(sol, n, n - 1, n - 1), "warm")
                if not nxt.feasible():
                    break
                n, sol = n - 1, nxt
        else:
            n, sol = walk_up(w, n, sol)
            if not sol.feasible():
                continue
            while n > 1:        # a jump may overshoot
                nxt = reach(w, n - 1, resample(sol, n, n - 1, n - 1), "warm")
                if not nxt.feasible():
                    break
                n, sol = n - 1, nxt
        known[w] = (n, sol)
        lower, best = n, (w, sol)
    if lower is None:
        return SearchResult(max_samples + 1, None, (0, 0), None, None, None,
                            cache.solves - solves0, time.perf_counter() - t_start)

    # The lower bound: N - 1 from every start and every winding not out of reach.
    while lower > 1:
        hit = None
        for w in sorted(ws, key=lambda v: v != best[0]):
            warm = (lower, best[1]) if w == best[0] else known[w]
            if w != best[0] and out_of_reach(w, lower - 1):
                continue
            for name, guess in start_guesses(w, lower - 1, warm):
                sol = reach(w, lower - 1, guess, name)
                if sol.feasible():
                    hit = (w, sol)
                    break
            if hit:
                break
        if hit is None:
            break
        lower, best = lower - 1, hit
        known[hit[0]] = (lower, hit[1])

    # The upper bound: hold in the band from N on, replayed on the numpy model; the
    # best winding first, then any other found feasible at this N.
    n = lower
    while n <= max_samples:
        k = n + hold
        others = [(w, known[w]) for w in ws if w != best[0] and known[w][1].feasible()]
        for w, (n_sol, sol) in [(best[0], (lower, best[1]))] + others:
            for guess in (resample(sol, n_sol, n, k), smooth_guess(x0, targets_of(w), n, k)):
                h = cache.solve(model, k, x0, targets_of(w), *guess, first=n, rest=True)
                if not h.feasible(HOLD_MARGIN):
                    continue
                # IPOPT may overstep a bound by its relaxation (1e-8 relative): clip.
                h = dataclasses.replace(h, torques=np.clip(h.torques, -p.tau_max, p.tau_max))
                states, ok = replay(model, p, x0, h.torques, n)
                if ok:
                    return SearchResult(lower, n, w, best[1], h, states,
                                        cache.solves - solves0,
                                        time.perf_counter() - t_start)
        n += 1
    return SearchResult(lower, None, best[0], best[1], None, None, cache.solves - solves0,
                        time.perf_counter() - t_start)
