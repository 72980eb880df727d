"""Named challenge levels: the arm's real-world perturbations, in the shape of RWRL.

A :class:`Challenge` bundles what DeepMind's real-world RL suite (RWRL) calls
perturbation, delay and noise specs, fitted to this arm at Ts = 0.05 s: every one of
the ten physical parameters of Table I (:data:`twolink.sim.perturbations.PHYSICAL`) changed
jointly, each by a relative change uniform in +-``spread`` drawn anew for every plant;
the plant's torque limits changed by ``torque_limit`` (the controller keeps its own
action levels, the plant clips them); named parameters of Table I
(:data:`twolink.sim.perturbations.PERTURBABLE`) changed by fixed relative amounts,
``offsets`` (``{"m2": 0.2}`` is m2 * 1.2; given as a mapping or (name, change) pairs,
held as pairs in PERTURBABLE's order, each change in (-0.9, 1]; the base every random
plant is drawn around); the torque reaching the arm ``action_delay``
sample periods late and the readings reaching the controller ``observation_delay``
sample periods late; Gaussian noise on the measured angles (``angle_noise_deg``, std in
degrees) and speeds (``speed_noise``, std in rad/s); readings dropped with probability
``dropout`` (the previous one is repeated) or stuck for
:data:`twolink.sim.perturbations.STUCK_SAMPLES` samples with probability ``stuck`` per
sample. The goal band of (15) is +-5 deg and +-0.1 rad/s, so the noise levels are read
against it.

:data:`LEVELS` is the one table of named levels that the environments, the evaluation
call (:func:`twolink.sim.evaluation.evaluate`), the report, the tests and the README read.
The perturbations themselves are implemented once, in :mod:`twolink.sim.perturbations`.

One seeding rule for everything a challenge draws from a ``seed``: plant i from
``SeedSequence([seed, PLANT_STREAM], spawn_key=(i,))`` (:func:`draw_plants`); the run of
plant p from state s its noise from ``SeedSequence([seed, NOISE_STREAM], spawn_key=(p, s))``
and its faults from ``SeedSequence([seed, FAULT_STREAM], spawn_key=(p, s))``
(:meth:`Challenge.generators`). The evaluation call and the robustness sweeps
(:mod:`twolink.sim.cells`) both draw through it, so the same challenge and seed give the
same runs in either.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Mapping, Sequence

import numpy as np

from twolink.arm.parameters import TABLE_I, TS, ArmParameters
from twolink.sim.perturbations import (
    MAX_SPREAD,
    NOISE_STREAM,
    PERTURBABLE,
    PHYSICAL,
    SPEED_PER_DEG,
    STUCK_SAMPLES,
    Sensors,
    keyed_generators,
    perturbed,
    random_perturbation,
    torque_limited,
)
from twolink.validate import real, whole

#: Most samples a delay may be (50 s): beyond that it is a typing slip.
MAX_DELAY = 1000
#: Most plants one draw makes.
MAX_PLANTS = 10_000
#: The message of a bad plant count (a :func:`twolink.validate.whole` template).
PLANT_COUNT = "{what} must be a whole number of plants from {low} to {high}, got {value!r}"
#: Second word of the plant draws' seed: plant i of ``draw_plants(..., seed)`` draws from
#: ``SeedSequence([seed, PLANT_STREAM], spawn_key=(i,))``.
PLANT_STREAM = 104_729
#: Second word of the seeds of a run's reading faults (its noise: ``NOISE_STREAM``).
FAULT_STREAM = 7927


@dataclasses.dataclass(frozen=True)
class Challenge:
    """One challenge level (see the module docstring for what each field means)."""

    name: str
    spread: float = 0.0
    torque_limit: float = 0.0
    offsets: tuple = ()
    action_delay: int = 0
    observation_delay: int = 0
    angle_noise_deg: float = 0.0
    speed_noise: float = 0.0
    dropout: float = 0.0
    stuck: float = 0.0
    description: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"challenge name must be a non-empty string, got {self.name!r}")
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name not in ("name", "description", "offsets"):
                real(v, f"challenge {f.name}")
        object.__setattr__(self, "offsets", _check_offsets(self.offsets))
        _check_spread(self.spread)
        if not -MAX_SPREAD < self.torque_limit <= 1.0:
            raise ValueError(f"torque_limit must be a relative change in (-{MAX_SPREAD}, 1], "
                             f"got {self.torque_limit}")
        for name in ("action_delay", "observation_delay"):
            d = getattr(self, name)
            if d != int(d) or not 0 <= d <= MAX_DELAY:
                raise ValueError(f"{name} must be a whole number of samples from 0 to "
                                 f"{MAX_DELAY}, got {d}")
            object.__setattr__(self, name, int(d))
        for name in ("angle_noise_deg", "speed_noise"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be non-negative, got {getattr(self, name)}")
        for name in ("dropout", "stuck"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"{name} must be a probability in [0, 1), "
                                 f"got {getattr(self, name)}")

    # ------------------------------------------------------------------ plants
    def perturbs_plant(self) -> bool:
        return self.spread > 0 or self.torque_limit != 0 or bool(self.offsets)

    def offset(self, base: ArmParameters = TABLE_I) -> ArmParameters:
        """``base`` with the challenge's ``offsets`` applied (``base`` itself without any)."""
        return perturbed(base, **dict(self.offsets)) if self.offsets else base

    def plant(self, rng: np.random.Generator, base: ArmParameters = TABLE_I) -> ArmParameters:
        """One plant: ``base`` with the ``offsets`` applied, then every PHYSICAL parameter
        changed by a relative change uniform in +-spread drawn from ``rng`` (in PHYSICAL's
        order; nothing drawn when spread is 0), then the torque limits changed by
        ``torque_limit``."""
        p = self.offset(base)
        p = random_perturbation(rng, self.spread, p, PHYSICAL) if self.spread > 0 else p
        return torque_limited(p, self.torque_limit) if self.torque_limit else p

    def plants(self, count: int, seed, base: ArmParameters = TABLE_I) -> list[ArmParameters]:
        """``count`` plants: :func:`draw_plants` under the challenge's spread around
        ``base`` with the ``offsets`` applied, each with the challenge's torque limits."""
        return [torque_limited(p, self.torque_limit) if self.torque_limit else p
                for p in draw_plants(self.spread, count, seed, self.offset(base))]

    # ------------------------------------------------------------------ readings
    @property
    def angle_std(self) -> float:
        """Angle noise std in rad."""
        return math.radians(self.angle_noise_deg)

    def observes_imperfectly(self) -> bool:
        return bool(self.angle_noise_deg or self.speed_noise or self.dropout or self.stuck
                    or self.observation_delay)

    def generators(self, seed, keys) -> tuple[list, list]:
        """The noise and the fault generators of the runs ``keys`` ((plant, state) index
        pairs, one per batch row) drawn from ``seed`` by the module's seeding rule; a
        row's generator is None where the challenge draws nothing of that kind."""
        seed = whole(seed, "seed", 0)
        noisy = self.angle_noise_deg > 0 or self.speed_noise > 0
        faulty = self.dropout > 0 or self.stuck > 0
        return (keyed_generators([seed, NOISE_STREAM], keys) if noisy else [None] * len(keys),
                keyed_generators([seed, FAULT_STREAM], keys) if faulty else [None] * len(keys))

    def sensors(self, *, rngs: Sequence, fault_rngs: Sequence | None = None,
                block: int = 1) -> Sensors:
        """The challenge's noise, faults and observation delay for ``len(rngs)`` rows
        (:class:`twolink.sim.perturbations.Sensors`)."""
        return Sensors(self.angle_std, self.speed_noise, self.dropout, self.stuck,
                       self.observation_delay, rngs=rngs, fault_rngs=fault_rngs, block=block)

    def as_dict(self) -> dict:
        """The fields, JSON-ready (``offsets`` as ``{name: change}``);
        ``Challenge(**c.as_dict()) == c``."""
        return {**dataclasses.asdict(self), "offsets": dict(self.offsets)}


def _check_offsets(offsets) -> tuple:
    """``offsets`` as (name, change) pairs in PERTURBABLE's order, or a one-line ValueError."""
    if isinstance(offsets, Mapping):
        pairs = list(offsets.items())
    else:
        try:
            pairs = [tuple(p) for p in offsets]
        except TypeError:
            pairs = None
        if pairs is None or isinstance(offsets, str) or any(len(p) != 2 for p in pairs):
            raise ValueError(f"offsets must map Table I parameter names to relative changes, "
                             f"got {offsets!r}")
    names = [n for n, _ in pairs]
    for n in names:
        if n not in PERTURBABLE:
            raise ValueError(f"unknown parameter {n!r} in offsets; perturbable: "
                             f"{', '.join(PERTURBABLE)}")
    if len(set(names)) < len(names):
        raise ValueError(f"offsets name a parameter twice: {', '.join(names)}")
    for n, v in pairs:
        real(v, f"offset of {n}", -MAX_SPREAD, 1.0, open_low=True,
             message="{what} must be a relative change in ({low:g}, 1], got {value!r}")
    return tuple((n, float(v)) for n, v in sorted(pairs, key=lambda p: PERTURBABLE.index(p[0])))


def _check_spread(spread) -> float:
    return real(spread, "spread", 0.0, MAX_SPREAD, open_high=True,
                message="{what} must be a relative change in [0, {high}), got {value!r}")


#: The named levels, mildest first; ``medium`` combines every kind of challenge.
LEVELS: dict[str, Challenge] = {c.name: c for c in (
    Challenge("none", description="the nominal arm of Table I, measured perfectly"),
    Challenge("easy", spread=0.1, angle_noise_deg=0.5, speed_noise=0.01,
              description="+-10 % plants, sensor noise a tenth of the goal band"),
    Challenge("medium", spread=0.2, action_delay=1, angle_noise_deg=1.0, speed_noise=0.02,
              description="+-20 % plants, torque one sample (50 ms) late, noise a fifth "
                          "of the goal band"),
    Challenge("hard", spread=0.3, torque_limit=-0.2, action_delay=1, observation_delay=1,
              angle_noise_deg=2.0, speed_noise=0.05, dropout=0.05, stuck=0.01,
              description="+-30 % plants with 20 % less torque, 100 ms round-trip delay, "
                          "noise 40-50 % of the goal band, 5 % dropped and 1 % stuck "
                          "readings"),
)}


def challenge(name) -> Challenge:
    """The level ``name`` of :data:`LEVELS` (a :class:`Challenge` or None, for "none",
    pass through); a ValueError listing the names otherwise."""
    if isinstance(name, Challenge):
        return name
    if name is None:
        return LEVELS["none"]
    if isinstance(name, str) and name in LEVELS:
        return LEVELS[name]
    raise ValueError(f"unknown challenge {name!r}; choose one of {', '.join(LEVELS)}")


#: Joins the levels of a :class:`Mix` in its name (``"none+medium+hard"``).
MIX_JOIN = "+"


@dataclasses.dataclass(frozen=True)
class Mix:
    """Levels trained side by side: arm i of a batch of arms runs under
    ``levels[i % len(levels)]`` for every episode (its plants, noise, faults and delays),
    so a batch of a multiple of ``len(levels)`` arms holds each level equally. Build it
    with :func:`mix` from its name."""

    levels: tuple

    def __post_init__(self):
        levels = tuple(self.levels) if isinstance(self.levels, (tuple, list)) else ()
        if len(levels) < 2 or not all(isinstance(c, Challenge) for c in levels):
            raise ValueError(f"a mix holds two or more Challenge levels, got {self.levels!r}")
        object.__setattr__(self, "levels", levels)

    @property
    def name(self) -> str:
        return MIX_JOIN.join(c.name for c in self.levels)

    def level(self, row: int) -> Challenge:
        """The level of arm ``row``."""
        return self.levels[row % len(self.levels)]

    def perturbs_plant(self) -> bool:
        return any(c.perturbs_plant() for c in self.levels)

    def action_delays(self, rows: int) -> np.ndarray:
        """Each of ``rows`` arms' actuation delay in samples."""
        return np.array([self.level(i).action_delay for i in range(rows)])

    def sensors(self, *, rngs: Sequence) -> Sensors:
        """The noise, faults and observation delay of ``len(rngs)`` arms, each its level's
        (:class:`twolink.sim.perturbations.Sensors` with per-row settings)."""
        rows = [self.level(i) for i in range(len(rngs))]
        return Sensors(np.array([c.angle_std for c in rows]),
                       np.array([c.speed_noise for c in rows]),
                       np.array([c.dropout for c in rows]), np.array([c.stuck for c in rows]),
                       np.array([c.observation_delay for c in rows]), rngs=rngs)


def is_mix(name) -> bool:
    """Whether ``name`` is a :class:`Mix` or spells one (levels joined by ``+``)."""
    return isinstance(name, Mix) or (isinstance(name, str) and MIX_JOIN in name)


def mix(name) -> Mix:
    """The :class:`Mix` of ``name`` (a Mix passes through): two or more distinct levels of
    :data:`LEVELS` joined by ``+`` in the table's order (``"none+medium+hard"``); a
    one-line ValueError otherwise."""
    if isinstance(name, Mix):
        return name
    parts = name.split(MIX_JOIN) if isinstance(name, str) else []
    order = list(LEVELS)
    if (len(parts) < 2 or any(p not in LEVELS for p in parts) or len(set(parts)) != len(parts)
            or parts != sorted(parts, key=order.index)):
        raise ValueError(f"unknown challenge {name!r}: a level ({', '.join(LEVELS)}) or two "
                         f"or more distinct levels joined by {MIX_JOIN!r} in that order, "
                         f"e.g. 'none{MIX_JOIN}medium{MIX_JOIN}hard'")
    return Mix(tuple(LEVELS[p] for p in parts))


def levels_of(name) -> tuple:
    """The levels a training run under ``name`` meets: the one level, or a mix's."""
    return mix(name).levels if is_mix(name) else (challenge(name),)


def draw_plants(spread: float, count: int, seed, base: ArmParameters = TABLE_I
                ) -> list[ArmParameters]:
    """``count`` plants, each with every PHYSICAL parameter of ``base`` changed jointly
    by relative changes uniform in +-``spread``. Plant i draws from its own generator
    (``SeedSequence([seed, PLANT_STREAM], spawn_key=(i,))``), so the first k plants are
    the same whatever ``count``."""
    _check_spread(spread)
    whole(count, "count", 1, MAX_PLANTS, message=PLANT_COUNT)
    if spread == 0:
        return [base] * int(count)
    return [random_perturbation(rng, float(spread), base, PHYSICAL)
            for rng in keyed_generators(_entropy(seed), [(i,) for i in range(int(count))])]


def _entropy(seed) -> list[int]:
    return [whole(seed, "seed", 0), PLANT_STREAM]


#: Columns of :func:`table`, with their headings.
_COLUMNS = {"name": "level", "spread": "plants (joint +-)", "torque_limit": "torque limits",
            "action_delay": "action delay", "observation_delay": "observation delay",
            "angle_noise_deg": "angle noise", "speed_noise": "speed noise",
            "dropout": "dropped", "stuck": f"stuck ({STUCK_SAMPLES} samples)"}


def table() -> list[dict]:
    """One row per level of :data:`LEVELS`: its fields, as numbers (for reports)."""
    return [c.as_dict() for c in LEVELS.values()]


def markdown_table() -> str:
    """:func:`table` as a Markdown table (README, reports)."""
    def cell(c: Challenge, key: str) -> str:
        v = getattr(c, key)
        if key == "name":
            return f"`{v}`"
        if key in ("spread", "torque_limit", "dropout", "stuck"):
            return f"{100 * v:+.0f} %" if key == "torque_limit" and v else f"{100 * v:.0f} %"
        if key in ("action_delay", "observation_delay"):
            return f"{v} ({1000 * v * TS:.0f} ms)" if v else "0"
        return f"{v:g} deg" if key == "angle_noise_deg" else f"{v:g} rad/s"
    lines = ["| " + " | ".join(_COLUMNS.values()) + " |",
             "|" + "---|" * len(_COLUMNS)]
    lines += ["| " + " | ".join(cell(c, k) for k in _COLUMNS) + " |" for c in LEVELS.values()]
    return "\n".join(lines)


def requested(name=None, *, delay: int = 0, angle_noise_deg: float = 0.0) -> Challenge:
    """The challenge a command line asks for: the level ``name``, or (without one) a
    ``custom`` challenge of ``delay`` actuation samples and ``angle_noise_deg`` of noise
    (speed noise :data:`SPEED_PER_DEG` rad/s per degree), as
    :func:`twolink.sim.evaluation.evaluate` builds it; None when nothing is asked for."""
    if name is not None:
        if delay or angle_noise_deg:
            raise ValueError("give either --challenge or --delay/--angle-noise-deg, not both "
                             "(a challenge sets its own delays and noise)")
        return challenge(name)
    if not delay and not angle_noise_deg:
        return None
    if angle_noise_deg < 0 or not math.isfinite(angle_noise_deg):
        raise ValueError(f"--angle-noise-deg must be a non-negative number of degrees, "
                         f"got {angle_noise_deg:g}")
    if delay < 0:
        raise ValueError(f"--delay must be a non-negative whole number of samples, got {delay}")
    return Challenge("custom", action_delay=delay, angle_noise_deg=angle_noise_deg,
                     speed_noise=angle_noise_deg * SPEED_PER_DEG,
                     description=f"{delay}-sample delay, {angle_noise_deg:g} deg noise")


def check_horizon(ch: Challenge | None, steps: int, duration: float) -> None:
    """A ValueError when the challenge's delays are not shorter than the horizon of
    ``steps`` sample periods (``duration`` seconds)."""
    latency = 0 if ch is None else ch.action_delay + ch.observation_delay
    if latency >= steps:
        raise ValueError(f"a delay of {latency} samples is not shorter than the horizon of "
                         f"{steps} samples ({duration:g} s)")
