"""What the model-mismatch report measures: named plans, each one row of :data:`PLANS`.

A plan names the sweep's perturbation sizes per family, the evaluation states of every
sweep cell, the random plants per joint size, the robust section (random plants per
challenge level, its evaluation set and the seed its plants and noise are drawn from) and
the throughput batch. ``full`` is the committed report (32 random plants per joint size
and per challenge level, all 65 states); ``quick`` is the CI form (5 states per cell,
fewer sizes, 4 plants per joint size and per level: its margins are coarse). The N-link
section (``twolink mismatch --links N``) takes from the plan only its number of random
poses, drawn from :data:`LINKS_SEED`.

The families are the report's axes; every point on them is a
:class:`twolink.sim.challenges.Challenge` (:func:`family_challenge`), named by its curve,
and a sweep cell (:class:`twolink.sim.cells.Cell`) is one policy under one of them:

* ``nominal`` - no perturbation (the ``none`` level's fields);
* ``parameter`` - one Table I parameter changed by ``size`` (``offsets``; relative);
* ``joint`` - every physical parameter of Table I changed at once, each uniformly in
  [-size, size] (``spread``), :attr:`Plan.joint_draws` random plants per size;
* ``noise`` - Gaussian noise on the measured state: angle std ``size`` degrees and speed
  std ``size`` * (0.1 rad/s / 5 deg), so ``size = 5`` matches the goal band;
* ``delay`` - the torque reaches the plant ``size`` sample periods late (``action_delay``);
* ``torque_limit`` - the plant's tau1_max and tau2_max both changed by ``size`` (relative).

Plants and noise come from the challenges' one seeding rule with :data:`SWEEP_SEED`.
"""
from __future__ import annotations

import dataclasses
import warnings
from typing import Iterable, Mapping

from twolink._imports import renamed
from twolink.policy.registry import TWO_LINK
from twolink.sim.cells import Cell, states_of
from twolink.sim.challenges import Challenge
from twolink.sim.perturbations import PERTURBABLE, SPEED_PER_DEG

#: Perturbation families of the robustness sweep, in report order.
FAMILIES = ("parameter", "joint", "noise", "delay", "torque_limit")
#: What a family's size measures.
UNITS = {"parameter": "relative change", "joint": "relative change (each parameter)",
         "noise": "angle noise std [deg]", "delay": "samples", "torque_limit": "relative change"}
#: Seed of the robust section's plants and noise. Chosen once for the report and used for
#: nothing else: no policy, compensator or challenge level was tuned on it.
ROBUST_SEED = 9_061_127
#: Seed of the N-link section's random poses (:func:`twolink.sim.metrics.random_poses`). Chosen
#: once for the report and used for nothing else: no construction was tuned on it.
LINKS_SEED = 7_311_011
#: Curves of the robustness analysis, in report order: one per parameter, then the rest.
CURVES = tuple(f"parameter:{n}" for n in PERTURBABLE) + FAMILIES[1:]
#: Seed of every sweep cell's plants and noise.
SWEEP_SEED = 0
#: The Challenge field a family's size sets (``parameter``: its entry of ``offsets``).
FIELDS = {"joint": "spread", "noise": "angle_noise_deg", "delay": "action_delay",
          "torque_limit": "torque_limit"}


def family_challenge(family: str, size: float = 0.0, parameter: str = "") -> Challenge:
    """The point ``size`` of ``family`` (``parameter``: the Table I parameter changed) as
    a Challenge named by its curve (``nominal``, ``parameter:m2``, ``joint``, ...); a
    one-line ValueError for an unknown family or a size the Challenge refuses."""
    if family == "nominal":
        if size:
            raise ValueError(f"the nominal family has size 0, got {size!r}")
        return Challenge("nominal")
    if family == "parameter":
        return Challenge(f"parameter:{parameter}", offsets={parameter: size})
    if family == "noise":
        return Challenge("noise", angle_noise_deg=size, speed_noise=size * SPEED_PER_DEG)
    if family in FIELDS:
        return Challenge(family, **{FIELDS[family]: size})
    raise ValueError(f"unknown perturbation family {family!r}; choose one of nominal, "
                     f"{', '.join(FAMILIES)}")


def axis(cell: dict):
    """``(curve, size)`` of a sweep cell (:meth:`twolink.sim.cells.Cell.as_dict`): its
    curve of :data:`CURVES` or ``nominal`` and its size, read from the challenge's field;
    None for a cell whose challenge is on none of them."""
    ch = cell["challenge"]
    curve = ch.get("name")
    if curve == "nominal":
        return curve, 0.0
    if isinstance(curve, str) and curve.startswith("parameter:") and curve in CURVES:
        return curve, float(ch["offsets"].get(curve.split(":", 1)[1], 0.0))
    if curve in FIELDS:
        return curve, float(ch[FIELDS[curve]])
    return None


@dataclasses.dataclass(frozen=True)
class Plan:
    """One way to run the report: sweep sizes, states per cell, throughput batch."""

    name: str
    folder: str                        # default output folder under twolink.resources.output_dir
    states: str                        # a twolink.sim.cells.STATE_SETS name
    sizes: Mapping[str, tuple]         # perturbation sizes per family of FAMILIES
    joint_draws: int                   # random plants per joint size
    robust_plants: int                 # random plants per challenge level (robust section)
    robust_states: str                 # its evaluation set (a STATE_SETS name)
    robust_seed: int                   # its plants' and noise seed: never tuned on
    throughput_rows: int               # closed-loop rollouts timed against open-loop MuJoCo
    throughput_samples: int
    throughput_repeats: int
    throughput_policy: str = "centralized_full"
    links_poses: int = 64              # random poses at rest of the N-link section

    def cells(self, policies: Iterable[str]) -> list[Cell]:
        """Every sweep cell, the nominal one first, per policy in the order given."""
        points = [family_challenge("nominal")]
        for name in PERTURBABLE:
            points += [family_challenge("parameter", s, name) for s in self.sizes["parameter"]]
        points += [family_challenge(fam, s) for fam in FAMILIES[1:] for s in self.sizes[fam]]
        return [Cell(pol, ch, plants=self.joint_draws if ch.spread else 1, seed=SWEEP_SEED,
                     states=self.states)
                for pol in policies for ch in points]

    def sweep_states(self) -> int:
        return len(states_of(self.states))

    @property
    def chain_poses(self) -> int:
        """:attr:`links_poses` under its 0.1 name, until the next release."""
        warnings.warn("Plan.chain_poses is now Plan.links_poses; the old name goes in the "
                      "next release", DeprecationWarning, stacklevel=2)
        return self.links_poses


PLANS = {p.name: p for p in (
    Plan("full", "mismatch", "full",
         {"parameter": (-0.5, -0.2, -0.1, 0.1, 0.2, 0.5), "joint": (0.1, 0.2, 0.3, 0.5),
          "noise": (0.25, 0.5, 1.0, 2.0, 5.0), "delay": (1.0, 2.0),
          "torque_limit": (-0.5, -0.3, -0.2, -0.1, 0.2)},
         joint_draws=32, robust_plants=32, robust_states="full", robust_seed=ROBUST_SEED,
         throughput_rows=520, throughput_samples=100, throughput_repeats=3),
    Plan("quick", "mismatch-quick", "quick",
         {"parameter": (-0.5, 0.5), "joint": (0.2,), "noise": (2.0,), "delay": (1.0,),
          "torque_limit": (-0.5,)},
         joint_draws=4, robust_plants=4, robust_states="quick", robust_seed=ROBUST_SEED,
         throughput_rows=130, throughput_samples=20, throughput_repeats=2, links_poses=8),
)}


def plan(name: str) -> Plan:
    """The plan ``name``, or a ValueError listing the plans."""
    try:
        return PLANS[name]
    except KeyError:
        raise ValueError(f"unknown plan {name!r}; choose one of {', '.join(PLANS)}") from None


def report_order(policies: Iterable[str]) -> tuple[str, ...]:
    """Policies without repeats, shipped two-link ones in registry order, then any others
    as given."""
    names = list(dict.fromkeys(policies))
    rank = {n: i for i, n in enumerate(TWO_LINK)}
    return tuple(sorted(names, key=lambda n: (rank.get(n, len(rank)), names.index(n))))


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "CHAIN_SEED": "LINKS_SEED"
})
