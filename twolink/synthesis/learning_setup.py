"""The definition of an online fuzzy Q-learning run (:mod:`twolink.synthesis.learning`).

:class:`LearnConfig` holds a run's settings and checks them against the limits below;
:func:`make_agents` builds the agents a learner learns (their grids, discrete actions and
rewards, theta = 0) and :func:`warm_start` copies a given policy's Q-tables into them.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Optional

import numpy as np

from twolink.arm.parameters import GAMMA, TABLE_I
from twolink.arm.task import agent_reward, centralized_reward
from twolink.synthesis.problems import centralized_actions
from twolink.fqi import fuzzy
from twolink.policy.fuzzy_policy import Policy
from twolink.validate import real, whole

#: The message of a bad whole-number setting (a :func:`twolink.validate.whole` template).
_RANGE = "{what} must be a whole number in [{low}, {high:,}], got {value!r}"

LEARNERS = ("centralized", "decentralized", "independent")
UPDATES = ("fuzzy", "discrete", "rule", "fql")
#: Most arms a run may drive (the checkpoint stores every arm's state in its header, which
#: a policy file caps at 1 MiB: 4096 arms did not fit; 1024 do, with theta, its average,
#: the kept actions and the longest curve; tested).
MAX_ARMS = 1024
#: Most control steps (summed over arms) a run may take: some hours on one core.
MAX_STEPS = 10**8
#: Most evaluations a run may hold (each is a 65-state rollout on MuJoCo).
MAX_EVALUATIONS = 200


#: The recommended read-out against a noisy theta: the policy reads theta averaged over
#: this many control steps (the decentralized learners; the centralized one has none).
RECOMMENDED_AVERAGE = 200_000.0
#: The settings a checkpoint written before they existed ran with (no average, no
#: hysteresis, a warm start at the given Q), so that it resumes as it ran.
LEGACY = {"average": 0.0, "init_scale": 1.0, "hysteresis": 0.0}


@dataclasses.dataclass(frozen=True)
class LearnConfig:
    """Everything that defines a learning run (stored in every checkpoint)."""

    learner: str = "decentralized"
    steps: int = 1_000_000            # control steps, summed over arms
    arms: int = 256
    seed: int = 0
    update: str = "discrete"          # measured better on MuJoCo (README, benchmarks/learning.py)
    alpha: float = 0.2
    alpha_halflife: float = 0.0       # control steps; 0: constant alpha
    epsilon: float = 0.1
    epsilon_final: float = 0.1
    episode: int = 100                # sample periods per episode
    eval_every: int = 0               # control steps; 0: steps / 20
    gamma: float = GAMMA
    average: float | None = None      # control steps of the policy's theta average; 0:
    #                                   none; None: RECOMMENDED_AVERAGE (0 for centralized)
    init_scale: float = 0.5           # a warm start begins at init_scale * the given Q
    hysteresis: float = 0.1           # margin a new greedy action must win by; 0: none

    def __post_init__(self):
        if self.average is None:
            object.__setattr__(self, "average", 0.0 if self.learner == "centralized"
                               else RECOMMENDED_AVERAGE)

    def check(self) -> "LearnConfig":
        """This configuration, or a ValueError naming the first bad field."""
        if self.learner not in LEARNERS:
            raise ValueError(f"unknown learner {self.learner!r}; choose one of "
                             f"{', '.join(LEARNERS)}")
        if self.update not in UPDATES:
            raise ValueError(f"unknown update {self.update!r}; choose one of {', '.join(UPDATES)}")
        whole(self.arms, "arms", 1, MAX_ARMS, message=_RANGE)
        whole(self.steps, "steps", 1, MAX_STEPS, message=_RANGE)
        if self.steps < self.arms:
            raise ValueError(f"steps ({self.steps}) must be at least the number of arms "
                             f"({self.arms}): every arm takes one step per iteration")
        whole(self.seed, "seed", 0, 2**63 - 1, message=_RANGE)
        whole(self.episode, "episode", 1, 100_000, message=_RANGE)
        whole(self.eval_every, "eval every", 0, MAX_STEPS, message=_RANGE)
        if self.eval_every and math.ceil(self.steps / self.eval_every) > MAX_EVALUATIONS:
            raise ValueError(f"{self.steps} steps evaluated every {self.eval_every} would "
                             f"take more than {MAX_EVALUATIONS} evaluations")
        real(self.alpha, "learning rate alpha", 0.0, 1.0, open_low=True, numpy=False)
        real(self.alpha_halflife, "alpha half-life", 0.0, float(MAX_STEPS) * 100, numpy=False)
        real(self.epsilon, "epsilon", 0.0, 1.0, numpy=False)
        real(self.epsilon_final, "final epsilon", 0.0, 1.0, numpy=False)
        real(self.gamma, "gamma", 0.0, 1.0, open_high=True, numpy=False)
        real(self.average, "theta average (control steps)", 0.0, float(MAX_STEPS), numpy=False)
        if self.average and self.learner == "centralized":
            raise ValueError("a theta average is not available to the centralized learner: "
                             "its checkpoint would carry a second 63 504-entry theta, more "
                             "than a policy file's header holds")
        real(self.init_scale, "warm-start scale", 0.0, 1.0, open_low=True, numpy=False)
        real(self.hysteresis, "hysteresis margin", 0.0, 100.0, numpy=False)
        return self

    @property
    def iterations(self) -> int:
        """Batched steps of all arms: ceil(steps / arms)."""
        return -(-self.steps // self.arms)

    @property
    def eval_iterations(self) -> int:
        """Batched steps between evaluations (at least one)."""
        every = self.eval_every or max(1, self.steps // 20)
        return max(1, round(every / self.arms))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "LearnConfig":
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"unknown learning setting(s) {unknown}")
        return cls(**{**LEGACY, **data}).check()


@dataclasses.dataclass
class LearningAgent:
    """One fuzzy Q-table being learned: its grid (inputs named like policy signals), its
    discrete actions (N_U, len(outputs)), theta (N_X, N_U) and its reward: (15) when
    ``link`` is None, else link ``link``'s reward (17)."""

    name: str
    grid: fuzzy.Grid
    actions: np.ndarray
    outputs: tuple
    link: Optional[int]
    theta: np.ndarray

    def reward(self, x: np.ndarray) -> np.ndarray:
        return centralized_reward(x) if self.link is None else agent_reward(x, self.link)


def make_agents(learner: str, p=TABLE_I) -> list:
    """The agents of ``learner`` (:data:`LEARNERS`) in acting order, theta = 0, on the
    paper's grids (the same grids and actions as :mod:`twolink.synthesis.synthesize`)."""
    ang, spd = fuzzy.angle_axis, fuzzy.speed_axis
    lv1 = np.array([[-p.tau1_max], [0.0], [p.tau1_max]])
    lv2 = np.array([[-p.tau2_max], [0.0], [p.tau2_max]])
    if learner == "centralized":
        grid = fuzzy.Grid((ang("theta1"), ang("theta2"), spd("dtheta1"), spd("dtheta2")))
        acts = centralized_actions(p)
        return [LearningAgent("centralized", grid, acts, ("tau1", "tau2"), None,
                              np.zeros((grid.size, len(acts))))]
    if learner not in ("decentralized", "independent"):
        raise ValueError(f"unknown learner {learner!r}; choose one of {', '.join(LEARNERS)}")
    g2 = fuzzy.Grid((ang("theta2"), spd("dtheta2")))
    axes1 = (ang("theta1"), spd("dtheta1"), ang("theta2"))
    if learner == "decentralized":
        axes1 += (fuzzy.torque_axis("tau2", p.tau2_max),)
    g1 = fuzzy.Grid(axes1)
    return [LearningAgent("agent2", g2, lv2, ("tau2",), 2, np.zeros((g2.size, 3))),
            LearningAgent("agent1", g1, lv1, ("tau1",), 1, np.zeros((g1.size, 3)))]


def policy_kind(learner: str) -> str:
    """The policy kind a learner produces: ``centralized`` or ``decentralized``."""
    return "centralized" if learner == "centralized" else "decentralized"


def warm_start(agents: list, init: Policy, learner: str) -> None:
    """Copy the Q-tables of ``init`` into ``agents``, or a ValueError saying what differs."""
    kind = policy_kind(learner)
    if init.kind != kind:
        raise ValueError(f"--init policy is a {init.kind} policy; the {learner} learner "
                         f"needs a {kind} one")
    theirs = {a.name: a for a in init.agents}
    if sorted(theirs) != sorted(a.name for a in agents):
        raise ValueError(f"--init policy has agents {sorted(theirs)}; the {learner} learner "
                         f"has {sorted(a.name for a in agents)}")
    for a in agents:
        b = theirs[a.name]
        if b.grid != a.grid:
            raise ValueError(f"--init policy: agent {a.name} reads a grid over {b.grid.names} "
                             f"of shape {b.grid.shape}; the {learner} learner's is over "
                             f"{a.grid.names} of shape {a.grid.shape} (same bins needed)")
        if b.actions.shape != a.actions.shape or not np.allclose(b.actions, a.actions):
            raise ValueError(f"--init policy: agent {a.name} has actions "
                             f"{b.actions.ravel().tolist()}, the learner "
                             f"{a.actions.ravel().tolist()}")
    for a in agents:
        a.theta = np.array(theirs[a.name].q, dtype=float)
