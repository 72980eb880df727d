"""The leaderboard's measurement: one :func:`twolink.sim.evaluation.evaluate` per
controller x level x mode, summed up as a :class:`twolink.sim.metrics.Score` plus the
settle time relative to the time-optimal limit T*(x0) and the mean torque.

A mode is ``plain`` (the controller reads the challenge's readings as they are) or
``compensated`` (through :func:`twolink.sim.evaluation.controller`'s delay predictor and
observer, which needs the model the controller names in ``meta["model"]``; a controller
without one has no compensated row). Level ``none`` has nothing to compensate, so it has
one row per controller. ``settle / T*`` divides each run's settle time by the limit of
its initial state (a failed run counts as never settled, inf); the median and the worst
run are reported. ``mean |tau|`` is the mean absolute torque the controller commanded,
over every sample, row and joint.

The rows run one after another in this process (``executor="local"``) or as tasks on a
Ray cluster (``executor="ray"``, :func:`twolink.sim.cells.ray_session`): every row is one
deterministic :func:`measure_row` of the same inputs, so both give the same numbers (only
``seconds`` differs). A controller given by its spec (a string) is resolved again in the
worker; a controller object travels pickled. Progress is one ``log`` line per finished
row; ``progress=True`` adds each local row's evaluation bar
(:func:`twolink.sim.progress.progress_bar`), off by default so that a log holds the
row lines only.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from twolink.sim.challenges import LEVELS, challenge
from twolink.sim.controller import checked
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import Score

#: The plain and the compensated mode.
MODES = ("plain", "compensated")
#: Seed of the leaderboard's plants, noise and faults: fixed before any controller was
#: tuned, and never used to tune one.
SEED = 2026
#: Most controllers x levels x modes one leaderboard runs.
MAX_CELLS = 2000


class TorqueMeter:
    """A controller that passes ``controller``'s torques on and sums their magnitudes."""

    def __init__(self, controller):
        self.controller = controller
        self.name = getattr(controller, "name", "controller")
        self.total, self.count = 0.0, 0

    @property
    def meta(self) -> dict:
        return getattr(self.controller, "meta", {})

    def reset(self, n: int) -> None:
        reset = getattr(self.controller, "reset", None)
        if callable(reset):
            reset(n)

    def __call__(self, x):
        u = self.controller(x)
        self.total += float(np.abs(u).sum())
        self.count += int(np.size(u))
        return u

    @property
    def mean(self) -> float:
        return self.total / self.count if self.count else 0.0


@dataclasses.dataclass(frozen=True)
class Entry:
    """One row: ``controller`` under ``level`` in ``mode``."""

    controller: str
    level: str
    mode: str
    score: Score
    settle_ratio_median: float      # settle / T*, failures as inf
    settle_ratio_worst: float
    mean_abs_torque: float
    seconds: float
    grid: dict | None = None        # the worst case over the level's grid (plant_grid)

    def as_dict(self) -> dict:
        def finite(v):
            return float(v) if math.isfinite(v) else None
        return {"controller": self.controller, "level": self.level, "mode": self.mode,
                **self.score.as_dict(),
                "settle_ratio_median": finite(self.settle_ratio_median),
                "settle_ratio_worst": finite(self.settle_ratio_worst),
                "mean_abs_torque": self.mean_abs_torque, "seconds": self.seconds,
                **({"grid": self.grid} if self.grid is not None else {})}


def has_model(controller) -> bool:
    """Whether a compensator can predict for ``controller`` (it names its model)."""
    meta = getattr(controller, "meta", None)
    return isinstance(meta, dict) and meta.get("model") is not None


def modes_for(controller, level: str) -> tuple:
    """The modes a controller runs under ``level``: plain always; compensated where the
    level has something to compensate and the controller names a model."""
    ch = LEVELS[level]
    something = ch.action_delay or ch.observation_delay or ch.observes_imperfectly()
    return MODES if something and has_model(controller) else MODES[:1]


def settle_ratios(settle: np.ndarray, success: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """settle / T*(x0) per run (P, n): failures inf; ``limits`` (n,) seconds per state."""
    limits = np.asarray(limits, dtype=float)
    if limits.shape != settle.shape[-1:] or not np.all(limits > 0):
        raise ValueError(f"need a positive limit per initial state ({settle.shape[-1]}), got "
                         f"shape {limits.shape}")
    return np.where(success, settle, np.inf) / limits


#: Where the rows run: this process, or tasks on Ray.
EXECUTORS = ("local", "ray")


def measure_row(controller, name: str, level: str, mode: str, x0: np.ndarray,
                limits: np.ndarray, plants: int, seed: int, nthread=None,
                progress: bool = False, timeout: float | None = None,
                worst_case: bool = False) -> Entry:
    """One row: ``controller`` (a controller, or a spec for
    :func:`twolink.control.controllers.resolve_controller`) under ``level`` in ``mode``,
    evaluated from ``x0`` against ``limits``; ``progress`` shows the evaluation's bar;
    ``timeout`` limits each call of the controller (:func:`twolink.sim.controller.checked`);
    ``worst_case`` adds the run on the level's grid of plants
    (:func:`twolink.sim.plant_grid.worst_case`: its centre and 24 corners, the same
    states, seed and mode) for a level that perturbs the plant."""
    if isinstance(controller, str):
        from twolink.control.controllers import resolve_controller
        controller = resolve_controller(controller)
    meter = TorqueMeter(checked(controller, name=name, timeout=timeout))
    ch = LEVELS[level]
    t0 = time.perf_counter()
    ev = evaluate(meter, x0=x0, challenge=ch, seed=seed,
                  count=plants if ch.perturbs_plant() else 1,
                  compensate=mode == "compensated", label=name, nthread=nthread,
                  progress=progress)
    ratio = settle_ratios(ev.settle, ev.success, limits)
    grid = None
    if worst_case and ch.perturbs_plant():
        from twolink.sim.plant_grid import worst_case as on_grid

        grid = on_grid(meter.controller, ch, x0=x0, compensate=mode == "compensated",
                       seed=seed, nthread=nthread).as_dict()
    return Entry(name, level, mode, ev.score, float(np.median(ratio)), float(ratio.max()),
                 meter.mean, time.perf_counter() - t0, grid)


def _ray_rows(tasks, done, *, address, timeout=None, worst_case=False) -> list:
    """Every task of :func:`measure_row` on Ray, one CPU each; ``done(i, entry)`` as each
    ends; the entries in task order."""
    from twolink.sim.cells import ray_session

    with ray_session(address, None, "--address") as ray:
        remote = ray.remote(num_cpus=1)(measure_row)
        refs = [remote.remote(*task, nthread=1, timeout=timeout, worst_case=worst_case)
                for task in tasks]
        index = {ref: i for i, ref in enumerate(refs)}
        out = [None] * len(refs)
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            i = index[ready[0]]
            out[i] = ray.get(ready[0])
            done(i, out[i])
    return out


def run(controllers: dict, x0: np.ndarray, limits: np.ndarray, *, levels=tuple(LEVELS),
        plants: int = 32, seed: int = SEED, log=None, executor: str = "local",
        address: str | None = None, specs: dict | None = None,
        progress: bool = False, timeout: float | None = None,
        worst_case: bool = False) -> list[Entry]:
    """Every controller (``{name: controller}``) x level x mode (:func:`modes_for`) from
    the states ``x0`` (n, 4) whose limits are ``limits`` (n,) seconds; ``plants`` plants
    per level that perturbs the plant. ``log(line)`` hears of every finished row.
    ``executor``: ``local`` (this process) or ``ray`` (the cluster at ``address``, an
    initialised Ray or a new local one); ``specs`` (``{name: spec}``) sends those
    controllers to Ray by spec instead of pickled (a file's callable then imports there).
    ``progress``: each local row's evaluation bar besides the ``log`` lines (Ray rows
    have none). ``timeout``: seconds one call of a controller may take (none by default).
    ``worst_case``: every row of a perturbing level also runs on the level's grid of plants
    (:func:`measure_row`), about doubling the time."""
    if executor not in EXECUTORS:
        raise ValueError(f"unknown executor {executor!r}; choose one of {', '.join(EXECUTORS)}")
    levels = [challenge(name).name for name in levels]
    cells = [(name, level, mode) for name, c in controllers.items() for level in levels
             for mode in modes_for(c, level)]
    if len(cells) > MAX_CELLS:
        raise ValueError(f"{len(cells)} leaderboard rows are more than {MAX_CELLS}; name "
                         f"fewer controllers or levels")
    x0, limits = np.asarray(x0, dtype=float), np.asarray(limits, dtype=float)
    specs = specs or {}
    finished = [0]

    def done(i, entry):
        finished[0] += 1
        if log is not None:
            s = entry.score
            log(f"[{finished[0]}/{len(cells)}] {entry.controller} {entry.level} "
                f"{entry.mode}: {s.successes}/{s.n} ({entry.seconds:.1f} s)")

    if executor == "ray":
        from twolink.control.controllers import absolute_spec

        tasks = [(absolute_spec(specs.get(name, controllers[name])), name, level, mode, x0,
                  limits, plants, seed) for name, level, mode in cells]
        return _ray_rows(tasks, done, address=address, timeout=timeout,
                         worst_case=worst_case)
    rows = []
    for i, (name, level, mode) in enumerate(cells):
        rows.append(measure_row(controllers[name], name, level, mode, x0, limits, plants,
                                seed, progress=progress, timeout=timeout,
                                worst_case=worst_case))
        done(i, rows[-1])
    return rows
