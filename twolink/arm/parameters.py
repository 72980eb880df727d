"""Table I of the paper: the one place where the arm's physical numbers live.

Everything else (the numpy models, the MJCF file, the fuzzy grids, the docs) is
derived from :data:`TABLE_I` and the constants below.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink._imports import renamed
from twolink.validate import whole

#: Sample time Ts of the discrete-time system (Section IV-B).
TS = 0.05
#: Discount factor gamma of Alg. 1.
GAMMA = 0.98
#: Convergence threshold delta of Alg. 1 (infinity norm of the change in Q).
DELTA = 0.01
#: Goal band (15)/(17): |theta_i| <= 5 deg and |dtheta_i| <= 0.1 rad/s.
GOAL_ANGLE = 5.0 * math.pi / 180.0
GOAL_SPEED = 0.1
#: Rewards of (15)/(17): inside the goal band, outside it.
REWARD_GOAL = 0.0
REWARD_OTHER = -0.5
#: The paper's initial state x0 = [theta1, theta2, dtheta1, dtheta2] (Fig. 3).
PAPER_X0 = (-1.0, -3.0, 0.0, 0.0)
#: Evaluation horizon of the metrics (docs/conventions.md): 5 s, success = settled 1 s before the end.
HORIZON = 5.0
SUCCESS_MARGIN = 1.0
#: Horizon of arms of three links or more (:func:`horizon`): the tapered links' torque
#: limits (0.05 N m for link 3, halving after) need more than the paper's 5 s.
LINKS_HORIZON = 8.0

#: Arms of this many links can be built (:func:`links_parameters`): two (Table I) to six.
MIN_LINKS = 2
MAX_LINKS = 6
#: How the links beyond the second are made (:func:`links_parameters`).
LINK_RULES = ("tapered", "copied")
#: The tapered rule: each link beyond the second is the previous one with its mass,
#: inertia and torque limit multiplied by this factor (length, centre of mass, damping
#: and speed limit copied).
TAPER = 0.5


def check_links(links) -> int:
    """``links`` as an int if it is a whole number in [MIN_LINKS, MAX_LINKS], else a
    ValueError naming the supported range."""
    return whole(links, "links", MIN_LINKS, MAX_LINKS)


def state_names(links: int = 2) -> tuple:
    """Names of the state components of an arm of ``links`` links, in the order used
    everywhere: x = [theta_1..theta_N, dtheta_1..dtheta_N]."""
    n = check_links(links)
    return tuple(f"theta{i}" for i in range(1, n + 1)) + \
        tuple(f"dtheta{i}" for i in range(1, n + 1))


#: Names of the state components of the paper's arm: x = [theta, dtheta].
STATE_NAMES = state_names(2)


def horizon(links: int = 2) -> float:
    """Evaluation and episode horizon (s) of an arm of ``links`` links: the paper's
    :data:`HORIZON` (5 s) for two, :data:`LINKS_HORIZON` (8 s) for three or more."""
    return HORIZON if check_links(links) == 2 else LINKS_HORIZON


@dataclasses.dataclass(frozen=True)
class ArmParameters:
    """Physical parameters of Table I (SI units)."""

    g: float = 9.81
    l1: float = 0.1
    l2: float = 0.1
    m1: float = 1.25
    m2: float = 1.0
    I1: float = 0.004
    I2: float = 0.003
    c1: float = 0.05
    c2: float = 0.05
    b1: float = 0.1
    b2: float = 0.02
    tau1_max: float = 0.2
    tau2_max: float = 0.1
    dtheta1_max: float = 2.0 * math.pi
    dtheta2_max: float = 2.0 * math.pi

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if not math.isfinite(value):
                raise ValueError(f"parameter {field.name} must be finite, got {value}")
            if field.name != "g" and value <= 0:
                raise ValueError(f"parameter {field.name} must be positive, got {value}")

    # Derived quantities of (10).
    @property
    def P1(self) -> float:
        return self.m1 * self.c1**2 + self.m2 * self.l1**2 + self.I1

    @property
    def P2(self) -> float:
        return self.m2 * self.c2**2 + self.I2

    @property
    def P3(self) -> float:
        return self.m2 * self.l1 * self.c2

    @property
    def g1(self) -> float:
        return (self.m1 * self.c1 + self.m2 * self.l1) * self.g

    @property
    def g2(self) -> float:
        return self.m2 * self.c2 * self.g

    @property
    def links(self) -> int:
        return 2

    @property
    def tau_max(self) -> np.ndarray:
        return np.array([self.tau1_max, self.tau2_max])

    @property
    def speed_max(self) -> np.ndarray:
        return np.array([self.dtheta1_max, self.dtheta2_max])

    def scaled(self, **factors: float) -> "ArmParameters":
        """A copy with named parameters multiplied by the given factors."""
        unknown = sorted(set(factors) - set(self.as_dict()))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}; known: {sorted(self.as_dict())}")
        return dataclasses.replace(
            self, **{k: getattr(self, k) * float(v) for k, v in factors.items()})

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "ArmParameters":
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown}")
        return cls(**{k: float(v) for k, v in data.items()})


#: The manipulator of Table I.
TABLE_I = ArmParameters()


_LINK_FIELDS = ("lengths", "masses", "coms", "inertias", "dampings", "torque_limits",
                "speed_limits")
#: The ArmParameters name of each per-link field (link k's is the name with k appended).
_ARM_NAMES = {"lengths": "l", "masses": "m", "coms": "c", "inertias": "I", "dampings": "b",
              "torque_limits": "tau{}_max", "speed_limits": "dtheta{}_max"}


@dataclasses.dataclass(frozen=True)
class LinksParameters:
    """A horizontal arm of N links, link k's numbers at index k - 1 of each tuple (SI
    units): length, mass, centre of mass (distance from the link's joint), inertia about
    the centre of mass, joint damping, torque limit and speed limit. Built by
    :func:`links_parameters`; for N = 2 :meth:`as_arm` gives the :class:`ArmParameters`."""

    lengths: tuple
    masses: tuple
    coms: tuple
    inertias: tuple
    dampings: tuple
    torque_limits: tuple
    speed_limits: tuple
    g: float = 9.81
    rule: str = "tapered"

    def __post_init__(self):
        n = len(self.lengths)
        check_links(n)
        if self.rule not in LINK_RULES:
            raise ValueError(f"unknown link rule {self.rule!r}; choose one of "
                             f"{', '.join(LINK_RULES)}")
        for name in _LINK_FIELDS:
            values = tuple(float(v) for v in getattr(self, name))
            if len(values) != n:
                raise ValueError(f"parameter {name} needs {n} values (one per link), "
                                 f"got {len(values)}")
            for k, v in enumerate(values, 1):
                if not math.isfinite(v) or v <= 0:
                    raise ValueError(f"{name} of link {k} must be positive and finite, "
                                     f"got {v}")
            object.__setattr__(self, name, values)
        if not math.isfinite(self.g):
            raise ValueError(f"parameter g must be finite, got {self.g}")
        object.__setattr__(self, "g", float(self.g))

    @property
    def links(self) -> int:
        return len(self.lengths)

    @property
    def tau_max(self) -> np.ndarray:
        """Torque limits, one per joint (as :attr:`ArmParameters.tau_max`)."""
        return np.array(self.torque_limits)

    @property
    def speed_max(self) -> np.ndarray:
        """Speed limits, one per joint (as :attr:`ArmParameters.speed_max`)."""
        return np.array(self.speed_limits)

    def as_arm(self) -> ArmParameters:
        """The :class:`ArmParameters` of an arm of two links (Table I for
        ``links_parameters(2)``)."""
        if self.links != 2:
            raise ValueError(f"a {self.links}-link arm has no two-link ArmParameters")
        values = {"g": self.g}
        for name, arm in _ARM_NAMES.items():
            for k, v in enumerate(getattr(self, name), 1):
                values[arm.format(k) if "{}" in arm else f"{arm}{k}"] = v
        return ArmParameters(**values)

    def as_dict(self) -> dict:
        out = {name: list(getattr(self, name)) for name in _LINK_FIELDS}
        out.update(g=self.g, rule=self.rule, links=self.links)
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "LinksParameters":
        known = set(_LINK_FIELDS) | {"g", "rule", "links"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown LinksParameters field(s) {unknown}")
        missing = sorted(set(_LINK_FIELDS) - set(data))
        if missing:
            raise ValueError(f"missing LinksParameters field(s) {missing}")
        out = cls(**{k: tuple(data[k]) for k in _LINK_FIELDS},
                  g=float(data.get("g", 9.81)), rule=str(data.get("rule", "tapered")))
        if "links" in data and data["links"] != out.links:
            raise ValueError(f"links says {data['links']} but the parameters describe "
                             f"{out.links} links")
        return out


def as_links(p: "ArmParameters | LinksParameters") -> LinksParameters:
    """``p`` as a :class:`LinksParameters` (its two links for an :class:`ArmParameters`)."""
    if isinstance(p, LinksParameters):
        return p
    return LinksParameters(
        **{name: tuple(getattr(p, (arm.format(k) if "{}" in arm else f"{arm}{k}"))
                       for k in (1, 2)) for name, arm in _ARM_NAMES.items()}, g=p.g)


def links_parameters(links: int = 2, rule: str = "tapered",
                     base: ArmParameters = TABLE_I) -> LinksParameters:
    """The N-link horizontal arm that extends Table I (``base``): links 1 and 2 are
    Table I's; with ``rule="tapered"`` each further link is the previous one with its mass,
    inertia and torque limit times :data:`TAPER` (real arms taper toward the tip: with
    copied links the inner motors turn the heavy outer links only slowly), with
    ``rule="copied"`` each further link is a copy of link 2. Length, centre of mass,
    damping and speed limit are link 2's in both rules. ``links_parameters(2)`` is Table I
    exactly."""
    n = check_links(links)
    if rule not in LINK_RULES:
        raise ValueError(f"unknown link rule {rule!r}; choose one of {', '.join(LINK_RULES)}")
    two = as_links(base)
    rows = [{name: getattr(two, name)[k] for name in _LINK_FIELDS} for k in (0, 1)]
    factor = TAPER if rule == "tapered" else 1.0
    for _ in range(2, n):
        prev = rows[-1]
        rows.append(dict(prev, masses=prev["masses"] * factor,
                         inertias=prev["inertias"] * factor,
                         torque_limits=prev["torque_limits"] * factor))
    return LinksParameters(**{name: tuple(r[name] for r in rows) for name in _LINK_FIELDS},
                           g=base.g, rule=rule)


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "ChainParameters": "LinksParameters", "chain": "links_parameters",
    "as_chain": "as_links", "CHAIN_HORIZON": "LINKS_HORIZON"
})
