"""The machinery of the tuning: many candidate controllers run side by side in one
batched closed loop on the full model (6), and a coordinate grid search over them.

Rows are laid out plant-major, then candidate, then pose: row (p, c, s). Every row runs
the challenge's closed loop of :func:`twolink.sim.evaluation.closed_loop` (delays, noise
and faults drawn per (plant, pose) key, so every candidate meets the very same noise:
common random numbers), on a numpy plant whose parameters differ row by row.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from twolink.arm.dynamics import full_acceleration
from twolink.arm.integrate import sample_step
from twolink.arm.parameters import HORIZON, ArmParameters
from twolink.sim.challenges import Challenge
from twolink.sim.evaluation import closed_loop
from twolink.sim.metrics import settle_time, success, wilson_interval
from twolink.sim.plants import SimulationError, check_states
from twolink.sim.rollout import rollout, steps_for


class RowParameters:
    """The numbers the full model (6) and the sample step read, one per batch row."""

    links = 2

    def __init__(self, params: Sequence[ArmParameters]):
        for name in ("P1", "P2", "P3", "b1", "b2"):
            setattr(self, name, np.array([getattr(p, name) for p in params]))
        self.tau_max = np.stack([p.tau_max for p in params])
        self.speed_max = np.stack([p.speed_max for p in params])


class RowPlant:
    """The full model (6) with a parameter set per batch row, stepped as the ``full``
    plant steps (RK4 substeps, torques clipped, angles wrapped, speeds saturated)."""

    name = "full"
    links = 2

    def __init__(self, params: Sequence[ArmParameters]):
        self.rows = len(params)
        self.params = RowParameters(params)
        self._speed_max = self.params.speed_max

    def check_states(self, x, *, what: str = "state") -> np.ndarray:
        return check_states(x, what=what, speed_max=self._speed_max)

    def step(self, x, tau) -> np.ndarray:
        with np.errstate(all="ignore"):
            out = sample_step(full_acceleration, self.params, np.asarray(x, dtype=float),
                              np.asarray(tau, dtype=float))
        if not np.all(np.isfinite(out)):
            raise SimulationError("the full model reached a non-finite state")
        return out


class Stack:
    """Candidate controllers side by side: row r goes to candidate ``which[r]``."""

    def __init__(self, controllers: Sequence, which: np.ndarray):
        self.controllers = list(controllers)
        self.rows = [np.flatnonzero(which == c) for c in range(len(self.controllers))]
        self.size = len(which)

    def reset(self, rows: int) -> None:
        for ctrl, idx in zip(self.controllers, self.rows):
            reset = getattr(ctrl, "reset", None)
            if callable(reset):
                reset(len(idx))

    def __call__(self, x) -> np.ndarray:
        out = np.empty(x.shape[:-1] + (2,))
        for ctrl, rows in zip(self.controllers, self.rows):
            out[rows] = ctrl(x[rows])
        return out


def run_candidates(controllers: Sequence, x0: np.ndarray, plants: Sequence[ArmParameters],
                   challenge: Challenge, *, seed: int, horizon: float = HORIZON
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Success (C, P, S) and settle time (C, P, S) of every candidate controller on every
    plant from every pose, in the challenge's closed loop without compensation."""
    c, p, s = len(controllers), len(plants), len(x0)
    plant_of = np.repeat(np.arange(p), c * s)
    cand_of = np.tile(np.repeat(np.arange(c), s), p)
    pose_of = np.tile(np.arange(s), c * p)
    keys = list(zip(plant_of.tolist(), pose_of.tolist()))
    steps = steps_for(horizon, rows=len(keys))
    act, observe = closed_loop(Stack(controllers, cand_of), challenge, keys=keys,
                               seed=seed, steps=steps, compensate=False)
    plant = RowPlant([plants[i] for i in plant_of])
    traj = rollout(act, plant, x0[pose_of], duration=horizon, observe=observe)
    shape = (p, c, s)
    ok = success(traj).reshape(shape).transpose(1, 0, 2)
    settle = settle_time(traj).reshape(shape).transpose(1, 0, 2)
    return ok, settle


def score(ok: np.ndarray, settle: np.ndarray, horizon: float = HORIZON) -> dict:
    """Successes of n runs, 95 % Wilson interval, median settle (failures never settle:
    None when half or more fail) and mean settle with failures counted at the horizon, of
    one candidate's runs (the key spellings of twolink.sim.metrics' scores)."""
    n, k = int(ok.size), int(ok.sum())
    med = round(float(np.median(settle)), 9)       # settle times are multiples of Ts
    return {"successes": k, "n": n, "rate": k / n, "wilson_95": list(wilson_interval(k, n)),
            "median_settle": med if math.isfinite(med) else None,
            "mean_settle_capped": round(float(np.mean(np.minimum(settle, horizon))), 9)}


def rank(s: dict) -> tuple:
    """Order of merit: success count, then shorter median settle, then shorter mean
    (capped) settle."""
    med = s["median_settle"]
    return (s["successes"], -(math.inf if med is None else med), -s["mean_settle_capped"])


def coordinate_search(evaluate: Callable[[list], list], start: dict, grid: dict, *,
                      rounds: int = 6) -> tuple[dict, dict, list]:
    """Best point of a coordinate-wise grid search: each round sweeps every coordinate
    over its grid (the others held), one batch per sweep, and moves to the best value
    (:func:`rank`; a tie keeps the current one). Stops after a round without a move or
    after ``rounds``. ``evaluate(points) -> scores``. Returns (point, score, history)."""
    point = dict(start)
    cache: dict = {}

    def key(pt):
        return tuple(float(pt[k]) for k in sorted(pt))

    def scores(points):
        todo = [pt for pt in points if key(pt) not in cache]
        todo = list({key(pt): pt for pt in todo}.values())
        for pt, sc in zip(todo, evaluate(todo) if todo else []):
            cache[key(pt)] = sc
        return [cache[key(pt)] for pt in points]

    history = []
    for r in range(rounds):
        moved = False
        for name, values in grid.items():
            values = sorted(set(values) | {point[name]})
            points = [{**point, name: v} for v in values]
            got = scores(points)
            current = got[values.index(point[name])]
            best = max(range(len(values)), key=lambda i: rank(got[i]))
            if rank(got[best]) > rank(current):
                point, moved = points[best], True
            history.append({"round": r + 1, "coordinate": name, "value": point[name],
                            "successes": cache[key(point)]["successes"],
                            "median_settle": cache[key(point)]["median_settle"]})
        if not moved:
            break
    return point, cache[key(point)], history
