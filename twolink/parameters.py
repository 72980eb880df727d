"""Table I of the paper: the one place where the arm's physical numbers live.

Everything else (the numpy models, the MJCF file, the fuzzy grids, the docs) is
derived from :data:`TABLE_I` and the constants below.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

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
#: Evaluation horizon of the metrics (SPEC.md): 5 s, success = settled 1 s before the end.
HORIZON = 5.0
SUCCESS_MARGIN = 1.0

#: Names of the state components, in the order used everywhere: x = [theta, dtheta].
STATE_NAMES = ("theta1", "theta2", "dtheta1", "dtheta2")


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
