"""The worst case over a challenge level's parameter box, beside the average over random
plants (robust RL benchmarks' "worst case over a grid of the uncertainty set").

A level perturbs the ten physical parameters of Table I
(:data:`twolink.sim.perturbations.PHYSICAL`) jointly, each by a relative change in
+-``spread`` (:class:`twolink.sim.challenges.Challenge`). The random plants of
:meth:`Challenge.plants` sample that box's inside; the worst cases of a box lie at its
corners, and the ten parameters have 1024 of them. :func:`grid_plants` takes the box's
centre and 24 of its corners chosen by a two-level screening design: the 12-run
Plackett-Burman design on the ten parameters and its fold-over (every sign reversed), so
that every parameter is at +spread in half of the corners and at -spread in the other
half, every pair of parameters meets in all four sign pairs, and the main effect of a
parameter is not confounded with any two-parameter interaction (resolution IV). Each
grid plant also carries the level's fixed offsets and torque limits, as every random
plant does. A level that does not perturb the plant has one grid plant, its centre.

:func:`worst_case` runs a controller on every grid plant from the same initial states,
with the level's delays, noise and faults, and reports every plant's successes and the
worst plant.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from twolink.arm.parameters import TABLE_I, ArmParameters
from twolink.sim.challenges import Challenge
from twolink.sim.challenges import challenge as challenge_named
from twolink.sim.metrics import wilson_interval
from twolink.sim.perturbations import PHYSICAL, perturbed, torque_limited

#: The first row of the 12-run Plackett-Burman design (Plackett & Burman, 1946); the
#: other rows are its cyclic shifts and a row of minus signs.
_PB12_GENERATOR = (+1, +1, -1, +1, +1, +1, -1, -1, -1, +1, -1)


def plackett_burman_12() -> np.ndarray:
    """The 12 x 11 two-level Plackett-Burman design (entries +-1, orthogonal columns)."""
    g = np.array(_PB12_GENERATOR)
    rows = [np.roll(g, k) for k in range(11)] + [-np.ones(11, dtype=int)]
    return np.array(rows, dtype=int)


def corner_signs(factors: int = len(PHYSICAL)) -> np.ndarray:
    """The signs (24, ``factors``) of the grid's corners: the Plackett-Burman design's first
    ``factors`` columns and its fold-over."""
    if not 1 <= factors <= 11:
        raise ValueError(f"the 12-run design screens 1 to 11 factors, got {factors}")
    design = plackett_burman_12()[:, :factors]
    return np.vstack([design, -design])


@dataclasses.dataclass(frozen=True)
class GridPlant:
    """One plant of the grid: ``label`` ("centre" or the signs of PHYSICAL's parameters,
    e.g. ``"+l1 +l2 -m1 ..."``), its relative changes and its parameters."""

    label: str
    changes: dict
    params: ArmParameters


def grid_plants(level, base: ArmParameters = TABLE_I) -> list:
    """The centre and the 24 corners (:func:`corner_signs`) of ``level``'s parameter box
    around ``base`` (a :class:`Challenge` or a level name), as :class:`GridPlant`; only
    the centre when the level perturbs no parameter."""
    ch = level if isinstance(level, Challenge) else challenge_named(level)
    centre = ch.offset(base)

    def finish(p):
        return torque_limited(p, ch.torque_limit) if ch.torque_limit else p

    plants = [GridPlant("centre", {}, finish(centre))]
    if ch.spread == 0:
        return plants
    for signs in corner_signs():
        changes = {n: float(s * ch.spread) for n, s in zip(PHYSICAL, signs)}
        label = " ".join(f"{'+' if s > 0 else '-'}{n}" for n, s in zip(PHYSICAL, signs))
        plants.append(GridPlant(label, changes, finish(perturbed(centre, **changes))))
    return plants


@dataclasses.dataclass(frozen=True)
class WorstCase:
    """A controller on a level's grid: per grid plant its successes out of ``states``, the
    worst plant, and every run together as k/n with the 95 % Wilson interval."""

    level: str
    compensated: bool
    labels: tuple
    successes: tuple
    states: int

    @property
    def worst(self) -> int:
        """Index of the worst plant (the first of the fewest successes)."""
        return int(np.argmin(self.successes))

    @property
    def worst_rate(self) -> float:
        return self.successes[self.worst] / self.states

    @property
    def total(self) -> int:
        return int(sum(self.successes))

    def as_dict(self) -> dict:
        n = self.states * len(self.successes)
        return {"level": self.level, "compensated": self.compensated,
                "plants": len(self.successes), "states": self.states,
                "successes": self.total, "n": n,
                "wilson_95": list(wilson_interval(self.total, n)),
                "worst_plant": self.labels[self.worst],
                "worst_plant_successes": int(self.successes[self.worst]),
                "per_plant": dict(zip(self.labels, map(int, self.successes)))}


def worst_case(controller, level, *, x0=None, compensate: bool = False, seed: int = 0,
               base: ArmParameters = TABLE_I, **kwargs) -> WorstCase:
    """``controller`` on every plant of :func:`grid_plants` (``level``'s delays, noise and
    faults drawn from ``seed``), from ``x0`` (default the evaluation set); other keyword
    arguments go to :func:`twolink.sim.evaluation.evaluate`."""
    from twolink.sim.evaluation import evaluate

    ch = level if isinstance(level, Challenge) else challenge_named(level)
    plants = grid_plants(ch, base)
    e = evaluate(controller, params=[g.params for g in plants], x0=x0, challenge=ch,
                 seed=seed, compensate=compensate, **kwargs)
    return WorstCase(ch.name, bool(compensate), tuple(g.label for g in plants),
                     tuple(int(k) for k in e.success.sum(axis=1)), int(e.success.shape[1]))
