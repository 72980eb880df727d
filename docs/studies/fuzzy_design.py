"""The levers of the tuned fuzzy designs, each measured on tuning seeds only.

``python docs/studies/fuzzy_design.py [--only LABEL ...] [--json FILE] [--markdown FILE]``
synthesises every variant of :data:`VARIANTS` on the full model (6) and scores it on
MuJoCo with :func:`twolink.sim.evaluation.evaluate` on states and plants that no reported
figure uses (:data:`twolink.policy.registry.TUNING_SEEDS`):

* nominal: 48 random poses at rest, ``random_poses(2, 48, seed=9301)``;
* ``medium`` and ``hard``: the first 32 of those poses on 8 plants of the level drawn from
  seed 9302 (its noise and faults too), plain and compensated.

Each cell is k/n with the 95 % Wilson interval and the median settle time (failures
never settle). The settle / T* column runs every variant nominally from the 64 states of a
tuning grid (:func:`ratio_grid`, built as the evaluation set's grid at other angles): the
median and worst settle time over the time-optimal limit T* of each state. Every shipped
design marked ``tuned`` in the registry was chosen from this table; the leaderboard
(``twolink leaderboard``) reports them on the evaluation set and its own seed. Beside the levers the package offers (``levels``, ``bins``,
``refine``, ``readout``) others that it does not ship are measured here as study-only
controllers: the expectation over the reading noise inside the transition model
(:func:`noise_expectation`), agents that know their torque is one sample late
(:func:`delay_aware`), per-agent grids (:func:`per_agent`), agent 2 as the worst case
over link 1's motion (:func:`agent2_worst_over_link1`), a hold region that zeroes a
joint's torque near the goal (:class:`Hold`), the same with hysteresis
(:class:`Hysteresis`), a one-step look-ahead on the model far from the goal
(:class:`LookAhead`) and the read-out's near-goal gain (the gains
``docs/studies/near_gain.py`` chose). About 15 minutes on two cores; ``--merge --only LABEL ...``
measures some variants again and puts them into an existing ``--json`` table.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.arm.parameters import GAMMA, TABLE_I  # noqa: E402
from twolink.arm.task import action_levels, agent_reward, centralized_reward  # noqa: E402
from twolink.synthesis import problems as P  # noqa: E402
from twolink.synthesis.synthesize import synthesize  # noqa: E402
from twolink.fqi import fuzzy  # noqa: E402
from twolink.policy.fuzzy_policy import Policy  # noqa: E402
from twolink.policy.readout import Readout  # noqa: E402
from twolink.policy.registry import ROBUST_SEED, TUNING_SEEDS  # noqa: E402
from twolink.sim.evaluation import evaluate  # noqa: E402
from twolink.sim.metrics import random_poses, wilson_interval  # noqa: E402

POSE_SEED, PLANT_SEED = TUNING_SEEDS
POSES = random_poses(2, 48, seed=POSE_SEED)
CHALLENGE_POSES, CHALLENGE_PLANTS = 32, 8
#: Seed of the noise offsets of :func:`noise_expectation`.
NOISE_SEED = 9303
#: Angles (deg) of the tuning grid of the settle / T* column (:func:`ratio_grid`).
RATIO_ANGLES_DEG = (-160.0, -100.0, -55.0, -12.0, 12.0, 55.0, 100.0, 160.0)
#: T* of that grid: ``twolink limits --model full --degrees --x0 A B 0 0 ... --write``
#: over the 64 pairs, in the order of :func:`ratio_grid`.
RATIO_LIMITS = Path(__file__).resolve().parents[2] / "renders" / "fuzzy_design" \
    / "tuning_limits.json"


def _dz(width: float, argmax=None, near=None):
    gain, deg = near or (1.0, None)
    return Readout(speed_dead_zone=width, argmax_beyond_deg=argmax, near_gain=gain,
                   near_deg=deg) if width or argmax is not None or near else None


def _policy(kind, levels=3, bins="paper", context=None, dead_zone=0.0, argmax=None,
            robust=False, refine=1, link1="free", near=None):
    worst = {"robust": "worst", "draws": 8, "spread": 0.2, "seed": ROBUST_SEED} if robust \
        else {}
    return lambda: synthesize(kind, model="full", levels=levels, bins=bins, context=context,
                              refine=refine, readout=_dz(dead_zone, argmax, near),
                              agent2_link1=link1, **worst)


def ratio_grid() -> tuple:
    """The states of the settle / T* column and their T* (s): the 8 x 8 angle pairs of
    :data:`RATIO_ANGLES_DEG` at rest, as the evaluation set's grid is made but at other
    angles, with T* of the full model (6) from :data:`RATIO_LIMITS` (``upper`` x Ts;
    inf where the limit found none)."""
    from twolink.limits.table import tables_from_json

    table = tables_from_json(RATIO_LIMITS.read_text())["full"]
    a = np.deg2rad(RATIO_ANGLES_DEG)
    t1, t2 = np.meshgrid(a, a, indexing="ij")
    want = np.zeros((t1.size, 4))
    want[:, 0], want[:, 1] = t1.ravel(), t2.ravel()
    if not np.allclose(table.states, want):
        raise ValueError(f"{RATIO_LIMITS} does not hold the tuning grid of RATIO_ANGLES_DEG")
    seconds = np.array([np.inf if r.upper is None else r.seconds for r in table.rows])
    return want, seconds


def noise_expectation(levels=5, bins="goal", draws=8, angle_deg=1.0, speed=0.02,
                      dead_zone=0.0) -> Policy:
    """The centralized policy of the mean over ``draws`` transition models, model k
    starting from the bin centres shifted by a reading error (angles uniform in
    +-``angle_deg``, speeds in +-``speed``; model 0 unshifted): Q(m, u) = mean_k
    [rho(f(c_m + e_k, u)) + gamma V(f(c_m + e_k, u))]."""
    rng = np.random.default_rng(NOISE_SEED)
    shifts = [np.zeros(4)] + [np.r_[rng.uniform(-1, 1, 2) * np.deg2rad(angle_deg),
                                    rng.uniform(-1, 1, 2) * speed] for _ in range(draws - 1)]
    axes = (fuzzy.angle_axis("theta1", bins), fuzzy.angle_axis("theta2", bins),
            fuzzy.speed_axis("dtheta1", bins), fuzzy.speed_axis("dtheta2", bins))
    grid, actions = fuzzy.Grid(axes), P.centralized_actions(TABLE_I, levels)
    problems = []
    for shift in shifts:
        c = grid.centers() + shift
        nxt = P.model_step("full", TABLE_I, c[:, None, :], actions[None], compiled=True,
                           theta1_bins=grid.axes[0].size)
        problems.append(P.Problem("centralized", grid, actions, ("tau1", "tau2"), nxt,
                                  centralized_reward(nxt)))
    agent = P.solve_robust(problems, mode="mean", layout="factored")
    meta = {"model": "full", "parameters": TABLE_I.as_dict()}
    if dead_zone:
        meta["readout"] = _dz(dead_zone).as_dict()
    return Policy("centralized", [agent], meta)


def per_agent(angle2: int = 1, speed2: int = 1, refine1: int = 1, levels: int = 7) -> Policy:
    """decentralized_tuned's design (7 levels, propagated, 0.06 rad/s dead zone, argmax
    beyond 30 deg) with agent 2's angle and speed axes refined ``angle2`` and ``speed2``
    times and every axis of agent 1 ``refine1`` times (:meth:`fuzzy.Axis.refined`):
    which agent's bins a finer grid helps, and which it hurts."""
    axes = (fuzzy.angle_axis("theta2").refined(angle2),
            fuzzy.speed_axis("dtheta2").refined(speed2))
    a2 = P.solve(P.agent2_problem(TABLE_I, "full", axes=axes, levels=levels))
    a1 = P.solve(P.agent1_problem(a2, TABLE_I, "full", "propagated", refine=refine1,
                                  levels=levels), extra={"context": "propagated"})
    meta = {"model": "full", "parameters": TABLE_I.as_dict(), "context": "propagated",
            "readout": _dz(0.06, 30.0).as_dict()}
    return Policy("decentralized", [a2, a1], meta)


def agent2_worst_over_link1(tau1_fraction: float = 0.0, dtheta1: float = 0.0,
                            levels: int = 7) -> Policy:
    """decentralized_edge's design with agent 2 the worst case over link 1's motion: three
    transition models of agent 2 (link 1 starting at speed -``dtheta1``, 0, +``dtheta1``
    rad/s under tau1 = -, 0, + ``tau1_fraction`` tau1_max, each pair once; model 0 the
    paper's link 1 at rest without torque), solved by the robust Alg. 1
    (:func:`twolink.synthesis.problems.solve_robust`, ``mode="worst"``); agent 1 as in
    ``decentralized_edge``."""
    p, problems = TABLE_I, []
    grid = fuzzy.Grid((fuzzy.angle_axis("theta2", "edge"), fuzzy.speed_axis("dtheta2", "edge")))
    actions = action_levels(p.tau2_max, levels)[:, None]
    c = grid.centers()
    for sign in (0.0, -1.0, 1.0):
        x = np.zeros((len(c), 4))
        x[:, 1], x[:, 3], x[:, 2] = c[:, 0], c[:, 1], sign * dtheta1
        tau = np.zeros((len(actions), 2))
        tau[:, 1], tau[:, 0] = actions[:, 0], sign * tau1_fraction * p.tau1_max
        nxt = P.model_step("full", p, x[:, None, :], tau[None], compiled=False)
        problems.append(P.Problem("agent2", grid, actions, ("tau2",), nxt[..., [1, 3]],
                                  agent_reward(nxt, 2)))
    a2 = P.solve_robust(problems, mode="worst")
    a1 = P.solve(P.agent1_problem(a2, p, "full", "propagated", levels=levels, bins="edge"),
                 extra={"context": "propagated"})
    meta = {"model": "full", "parameters": p.as_dict(), "context": "propagated",
            "readout": _dz(0.06, 30.0).as_dict()}
    return Policy("decentralized", [a2, a1], meta)


class DelayAware:
    """Agents whose state holds the torque they sent one sample before (the torque acting
    now under a one-sample actuation delay): agent 2 over (theta2, dtheta2, tau2_prev),
    agent 1 over (theta1, dtheta1, theta2, tau2, tau1_prev) with link 2 frozen; the
    transition applies the previous torque and the action becomes the next previous one.
    A controller with state: ``reset(n)`` forgets the torques."""

    def __init__(self, levels: int):
        p = TABLE_I
        self.meta = {"model": "full", "parameters": p.as_dict()}
        self.name, self.prev = f"delay_aware_{levels}", None
        g2 = fuzzy.Grid((fuzzy.angle_axis("theta2"), fuzzy.speed_axis("dtheta2"),
                         fuzzy.torque_axis("tau2_prev", p.tau2_max, levels)))
        u2 = action_levels(p.tau2_max, levels)[:, None]
        c = g2.centers()
        x = np.zeros((len(c), 4))
        x[:, 1], x[:, 3] = c[:, 0], c[:, 1]
        tau = np.zeros((len(c), 1, 2))
        tau[:, 0, 1] = c[:, 2]
        nxt = np.broadcast_to(P.model_step("full", p, x[:, None], tau, compiled=True),
                              (len(c), len(u2), 4))
        pts = np.concatenate([nxt[..., [1, 3]], np.broadcast_to(u2[None], (len(c), len(u2), 1))], -1)
        a2 = P.solve(P.Problem("agent2", g2, u2, ("tau2",), np.ascontiguousarray(pts),
                               agent_reward(nxt, 2)))
        g1 = fuzzy.Grid((fuzzy.angle_axis("theta1"), fuzzy.speed_axis("dtheta1"),
                         fuzzy.angle_axis("theta2"), fuzzy.torque_axis("tau2", p.tau2_max, levels),
                         fuzzy.torque_axis("tau1_prev", p.tau1_max, levels)))
        u1 = action_levels(p.tau1_max, levels)[:, None]
        c = g1.centers()
        x = np.zeros((len(c), 4))
        x[:, 0], x[:, 1], x[:, 2] = c[:, 0], c[:, 2], c[:, 1]
        tau = np.zeros((len(c), 1, 2))
        tau[:, 0, 0], tau[:, 0, 1] = c[:, 4], c[:, 3]
        nxt = np.broadcast_to(P.model_step("full", p, x[:, None], tau, compiled=True,
                                           freeze_link2=True), (len(c), len(u1), 4))
        shape = nxt.shape[:-1]
        pts = np.stack([nxt[..., 0], nxt[..., 2], nxt[..., 1],
                        np.broadcast_to(c[:, None, 3], shape),
                        np.broadcast_to(u1[None, :, 0], shape)], -1)
        a1 = P.solve(P.Problem("agent1", g1, u1, ("tau1",), np.ascontiguousarray(pts),
                               agent_reward(nxt, 1)))
        self.agents = [a2, a1]

    def reset(self, n: int) -> None:
        self.prev = np.zeros((n, 2))

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        if self.prev is None or len(self.prev) != len(x):
            self.reset(len(x))
        theta = np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi
        signals = {"theta1": theta[:, 0], "theta2": theta[:, 1], "dtheta1": x[:, 2],
                   "dtheta2": x[:, 3], "tau1_prev": self.prev[:, 0],
                   "tau2_prev": self.prev[:, 1]}
        for agent in self.agents:
            out = agent.act(np.stack([signals[n] for n in agent.inputs], -1))
            for k, name in enumerate(agent.outputs):
                signals[name] = out[:, k]
        self.prev = np.stack([signals["tau1"], signals["tau2"]], -1)
        return self.prev.copy()


def delay_aware(levels: int = 3) -> DelayAware:
    return DelayAware(levels)


class LookAhead:
    """``policy`` (a centralized one) where every angle reads within ``beyond_deg``
    degrees; beyond that the action of a one-step look-ahead on the full model (6): the
    torque pair u of the policy's action set that maximises rho(f(x, u)) + gamma
    max_u' Q(f(x, u), u'), Q interpolated by (12) at the reached state."""

    def __init__(self, policy: Policy, beyond_deg: float):
        self.policy, self.agent = policy, policy.agents[0]
        self.beyond = np.deg2rad(beyond_deg)
        self.name, self.meta = f"{policy.meta.get('name', 'policy')}_lookahead", dict(policy.meta)

    def look(self, x):
        u = self.agent.actions
        nxt = P.model_step("full", TABLE_I, x[:, None, :], u[None], compiled=True)
        pts = nxt.copy()
        pts[..., :2] = np.mod(pts[..., :2] + np.pi, 2 * np.pi) - np.pi
        value = centralized_reward(nxt) + GAMMA * self.agent.q_values(pts).max(-1)
        return u[np.argmax(value, -1)]

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        out = self.policy(x)
        far = np.any(np.abs(np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi) > self.beyond, -1)
        if np.any(far):
            out[far] = self.look(x[far])
        return out


class Hold:
    """``policy`` with a hold region: joint i's torque is 0 while its link reads within
    ``angle_deg`` degrees and ``speed`` rad/s of the goal."""

    def __init__(self, policy: Policy, angle_deg: float, speed: float):
        self.policy, self.angle, self.speed = policy, np.deg2rad(angle_deg), speed
        self.name, self.meta = "hold", dict(policy.meta)

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        inside = (np.abs(np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi) < self.angle) \
            & (np.abs(x[:, 2:]) < self.speed)
        return np.where(inside, 0.0, self.policy(x))


class Hysteresis:
    """``policy`` with a hold region that has hysteresis: joint i holds (torque 0) from
    the sample its link reads within ``angle_in`` degrees and ``speed_in`` rad/s of the
    goal until it reads beyond ``angle_out`` degrees or ``speed_out`` rad/s. A controller
    with state: ``reset(n)`` releases every joint."""

    def __init__(self, policy: Policy, angle_in: float, speed_in: float, angle_out: float,
                 speed_out: float):
        self.policy, self.held = policy, None
        self.inner = (np.deg2rad(angle_in), speed_in)
        self.outer = (np.deg2rad(angle_out), speed_out)
        self.name, self.meta = "hysteresis", dict(policy.meta)

    def reset(self, n: int) -> None:
        self.held = np.zeros((n, 2), dtype=bool)

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        if self.held is None or len(self.held) != len(x):
            self.reset(len(x))
        theta, speed = np.abs(np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi), np.abs(x[:, 2:])
        inside = (theta <= self.inner[0]) & (speed <= self.inner[1])
        beyond = (theta > self.outer[0]) | (speed > self.outer[1])
        self.held = (self.held | inside) & ~beyond
        return np.where(self.held, 0.0, self.policy(x))


#: label -> a function building the controller.
VARIANTS = {
    "centralized_full (paper design on (6))": _policy("centralized"),
    "centralized 5 levels": _policy("centralized", levels=5),
    "centralized goal bins": _policy("centralized", bins="goal"),
    "centralized 5 levels, goal bins": _policy("centralized", levels=5, bins="goal"),
    "centralized 5 levels, goal bins, dead zone 0.05": _policy("centralized", 5, "goal",
                                                               dead_zone=0.05),
    "centralized 5 levels, goal bins, dead zone 0.08":
        _policy("centralized", 5, "goal", dead_zone=0.08),
    "centralized 5 levels, goal bins, dead zone 0.08, argmax beyond 30 deg (centralized_tuned)":
        _policy("centralized", 5, "goal", dead_zone=0.08, argmax=30.0),
    "centralized 7 levels, goal bins, dead zone 0.08": _policy("centralized", 7, "goal",
                                                               dead_zone=0.08),
    "centralized 7 levels, goal bins, dead zone 0.08, argmax beyond 30 deg":
        _policy("centralized", 7, "goal", dead_zone=0.08, argmax=30.0),
    "centralized 7 levels, goal bins, dead zone 0.04, argmax beyond 30 deg":
        _policy("centralized", 7, "goal", dead_zone=0.04, argmax=30.0),
    "centralized 9 levels, goal bins, dead zone 0.04, argmax beyond 30 deg":
        _policy("centralized", 9, "goal", dead_zone=0.04, argmax=30.0),
    "centralized 9 levels, goal bins, dead zone 0.04, argmax beyond 45 deg "
    "(centralized_9levels)":
        _policy("centralized", 9, "goal", dead_zone=0.04, argmax=45.0),
    "centralized 5 levels, goal bins, noise expectation": noise_expectation,
    "centralized_robust (worst of 8 models within +-20 %)": _policy("centralized", robust=True),
    "centralized_robust, argmax beyond 30 deg": _policy("centralized", argmax=30.0, robust=True),
    "centralized_robust, dead zone 0.04, argmax beyond 30 deg (centralized_robust_tuned)":
        _policy("centralized", dead_zone=0.04, argmax=30.0, robust=True),
    "centralized_robust, 5 levels, dead zone 0.05, argmax beyond 30 deg":
        _policy("centralized", 5, dead_zone=0.05, argmax=30.0, robust=True),
    "centralized_robust, edge bins, dead zone 0.04, argmax beyond 30 deg "
    "(centralized_robust_edge)":
        _policy("centralized", bins="edge", dead_zone=0.04, argmax=30.0, robust=True),
    "centralized_robust, 5 levels, edge bins, dead zone 0.04, argmax beyond 30 deg":
        _policy("centralized", 5, "edge", dead_zone=0.04, argmax=30.0, robust=True),
    "centralized 5 levels, edge bins, dead zone 0.08, argmax beyond 30 deg":
        _policy("centralized", 5, "edge", dead_zone=0.08, argmax=30.0),
    "decentralized_full (paper design on (6))": _policy("decentralized"),
    "decentralized 5 levels": _policy("decentralized", levels=5),
    "decentralized 5 levels, goal bins": _policy("decentralized", levels=5, bins="goal"),
    "decentralized 5 levels, propagated": _policy("decentralized", 5, context="propagated"),
    "decentralized 7 levels, propagated": _policy("decentralized", 7, context="propagated"),
    "decentralized 7 levels, propagated, dead zone 0.04":
        _policy("decentralized", 7, context="propagated", dead_zone=0.04),
    "decentralized 7 levels, propagated, dead zone 0.04, argmax beyond 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.04, argmax=30.0),
    "decentralized 7 levels, propagated, dead zone 0.06, argmax beyond 30 deg "
    "(decentralized_tuned)":
        _policy("decentralized", 7, context="propagated", dead_zone=0.06, argmax=30.0),
    "decentralized 7 levels, propagated, dead zone 0.08, argmax beyond 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.08, argmax=30.0),
    "decentralized 7 levels, propagated, dead zone 0.1, argmax beyond 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0),
    "decentralized 9 levels, propagated, dead zone 0.02":
        _policy("decentralized", 9, context="propagated", dead_zone=0.02),
    "decentralized 7 levels, propagated, worst of 8 models, dead zone 0.04, argmax 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.04, argmax=30.0,
                robust=True),
    "decentralized 7 levels, propagated, refine 2, no read-out":
        _policy("decentralized", 7, context="propagated", refine=2),
    "decentralized 7 levels, propagated, refine 2, dead zone 0.06, argmax beyond 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.06, argmax=30.0,
                refine=2),
    "decentralized 7 levels, propagated, refine 2, dead zone 0.1, argmax beyond 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
                refine=2),
    "decentralized 3 levels, propagated, refine 2, dead zone 0.06, argmax beyond 30 deg":
        _policy("decentralized", 3, context="propagated", dead_zone=0.06, argmax=30.0,
                refine=2),
    "decentralized_tuned, agent 1 refine 2": lambda: per_agent(refine1=2),
    "decentralized_tuned, agent 2's speed bins refined": lambda: per_agent(speed2=2),
    "decentralized_tuned, agent 2's angle bins refined": lambda: per_agent(angle2=2),
    "decentralized_tuned, agent 2's angle bins refined, agent 1 refine 2":
        lambda: per_agent(angle2=2, refine1=2),
    "decentralized 7 levels, propagated, edge bins, dead zone 0.06, argmax beyond 30 deg "
    "(decentralized_edge)":
        _policy("decentralized", 7, "edge", context="propagated", dead_zone=0.06, argmax=30.0),
    "decentralized 7 levels, propagated, edge bins, worst of 8 models, dead zone 0.06, "
    "argmax 30 deg":
        _policy("decentralized", 7, "edge", context="propagated", dead_zone=0.06, argmax=30.0,
                robust=True),
    "decentralized 7 levels, propagated, edge bins, agent 2 holds joint 1, dead zone 0.02, "
    "argmax 30 deg (decentralized_edge_locked)":
        _policy("decentralized", 7, "edge", context="propagated", dead_zone=0.02, argmax=30.0,
                link1="locked"),
    "decentralized 7 levels, propagated, edge bins, agent 2 holds joint 1, dead zone 0.06, "
    "argmax 30 deg":
        _policy("decentralized", 7, "edge", context="propagated", dead_zone=0.06, argmax=30.0,
                link1="locked"),
    "decentralized 7 levels, propagated, agent 2 holds joint 1, dead zone 0.1, argmax 30 deg "
    "(decentralized_locked)":
        _policy("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
                link1="locked"),
    "decentralized 7 levels, propagated, paper bins, agent 2 holds joint 1, dead zone 0.02, "
    "argmax 30 deg":
        _policy("decentralized", 7, context="propagated", dead_zone=0.02, argmax=30.0,
                link1="locked"),
    "decentralized_edge, agent 2 the worst case over tau1 in +-10 % of its limit":
        lambda: agent2_worst_over_link1(tau1_fraction=0.1),
    "decentralized_edge, agent 2 the worst case over dtheta1 in +-0.05 rad/s":
        lambda: agent2_worst_over_link1(dtheta1=0.05),
    "decentralized_robust, argmax beyond 30 deg": _policy("decentralized", argmax=30.0,
                                                          robust=True),
    "decentralized delay-aware, 3 levels": delay_aware,
    "decentralized delay-aware, 5 levels": lambda: delay_aware(5),
    "decentralized 7 levels, propagated, dead zone 0.06, angle dead zone 1 deg, argmax 30 deg":
        lambda: synthesize("decentralized", model="full", levels=7, context="propagated",
                           readout=Readout(speed_dead_zone=0.06, angle_dead_zone_deg=1.0,
                                           argmax_beyond_deg=30.0)),
    "decentralized_tuned with a hold region (3 deg, 0.06 rad/s)":
        lambda: Hold(_policy("decentralized", 7, context="propagated", dead_zone=0.06,
                             argmax=30.0)(), 3.0, 0.06),
    "decentralized_edge with a hysteresis hold (in 4 deg, 0.05 rad/s; out 7 deg, 0.15 rad/s)":
        lambda: Hysteresis(_policy("decentralized", 7, "edge", context="propagated",
                                   dead_zone=0.06, argmax=30.0)(), 4.0, 0.05, 7.0, 0.15),
    "decentralized_edge, near-goal gain 0.2 from 90 deg (decentralized_edge_gain)":
        _policy("decentralized", 7, "edge", context="propagated", dead_zone=0.06,
                argmax=30.0, near=(0.2, 90.0)),
    "decentralized_edge, near-goal gain 0.5 from 180 deg (decentralized_edge_gain_hard)":
        _policy("decentralized", 7, "edge", context="propagated", dead_zone=0.06,
                argmax=30.0, near=(0.5, 180.0)),
    "decentralized_locked, near-goal gain 0.3 from 60 deg (decentralized_locked_gain)":
        _policy("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
                link1="locked", near=(0.3, 60.0)),
    "decentralized_locked, near-goal gain 0.5 from 60 deg (decentralized_locked_gain_medium)":
        _policy("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
                link1="locked", near=(0.5, 60.0)),
    "centralized_robust_edge, near-goal gain 0.1 from 90 deg (centralized_robust_edge_gain)":
        _policy("centralized", bins="edge", dead_zone=0.04, argmax=30.0, robust=True,
                near=(0.1, 90.0)),
    "centralized_robust_edge, near-goal gain 0.2 from 60 deg "
    "(centralized_robust_edge_gain_medium)":
        _policy("centralized", bins="edge", dead_zone=0.04, argmax=30.0, robust=True,
                near=(0.2, 60.0)),
    "centralized_tuned with a one-step look-ahead on (6) beyond 15 deg":
        lambda: LookAhead(_policy("centralized", 5, "goal", dead_zone=0.08, argmax=30.0)(), 15.0),
}


def _cell(e) -> dict:
    s = e.score
    return {"successes": s.successes, "n": s.n, "wilson_95": list(s.wilson_95),
            "median_settle": s.median_settle if np.isfinite(s.median_settle) else None}


def measure(label: str) -> dict:
    t0 = time.perf_counter()
    controller = VARIANTS[label]()
    row = {"variant": label, "synthesis_seconds": time.perf_counter() - t0}
    row["none"] = _cell(evaluate(controller, x0=POSES))
    states, limit = ratio_grid()
    grid = evaluate(controller, x0=states)
    ratio = grid.settle.ravel() / limit
    row["ratio"] = {"successes": int(grid.success.sum()), "n": int(grid.success.size),
                    "median": float(np.median(ratio)) if np.isfinite(np.median(ratio))
                    else None,
                    "worst": float(np.max(ratio)) if np.isfinite(np.max(ratio)) else None}
    for level in ("medium", "hard"):
        for compensate in (False, True):
            e = evaluate(controller, x0=POSES[:CHALLENGE_POSES], challenge=level,
                         seed=PLANT_SEED, count=CHALLENGE_PLANTS, compensate=compensate)
            row[level + (" compensated" if compensate else "")] = _cell(e)
    return row


COLUMNS = ("none", "medium", "medium compensated", "hard", "hard compensated")


def ratio_text(cell) -> str:
    """The settle / T* cell: median and worst over the tuning grid, or '-' (a row measured
    before the column existed)."""
    if cell is None:
        return "-"
    med = "never" if cell["median"] is None else f"{cell['median']:.2f}"
    worst = "never" if cell["worst"] is None else f"{cell['worst']:.2f}"
    return f"{med}, {worst} ({cell['successes']}/{cell['n']})"


def markdown(rows: list) -> str:
    def fmt(c):
        lo, hi = wilson_interval(c["successes"], c["n"])
        settle = "never" if c["median_settle"] is None else f"{c['median_settle']:.2f} s"
        return f"{c['successes']}/{c['n']} [{100 * lo:.0f}, {100 * hi:.0f}] {settle}"
    lines = ["| variant | " + " | ".join(COLUMNS) + " | settle / T* |",
             "|---" * (len(COLUMNS) + 2) + "|"]
    lines += [f"| {r['variant']} | " + " | ".join(fmt(r[c]) for c in COLUMNS)
              + f" | {ratio_text(r.get('ratio'))} |" for r in rows]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", default=None, choices=list(VARIANTS),
                        metavar="LABEL")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--merge", action="store_true",
                        help="measure the --only variants and put their rows into the --json "
                             "file's table (kept in the order of VARIANTS)")
    parser.add_argument("--markdown", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.merge and (args.json is None or not args.json.is_file() or not args.only):
        parser.error("--merge needs --only and an existing --json file")
    kept = json.loads(args.json.read_text())["rows"] if args.merge else []
    rows = []
    for k, label in enumerate(args.only or VARIANTS, 1):
        rows.append(measure(label))
        print(f"[{k}/{len(args.only or VARIANTS)}] {label}: nominal "
              f"{rows[-1]['none']['successes']}/{rows[-1]['none']['n']}", file=sys.stderr,
              flush=True)
    if args.merge:
        new = {r["variant"]: r for r in rows}
        old = {r["variant"]: r for r in kept if r["variant"] in VARIANTS}
        rows = [new.get(label) or old[label] for label in VARIANTS if label in new or label in old]
    table = markdown(rows)
    print(table)
    if args.json:
        args.json.write_text(json.dumps({"poses": len(POSES), "seeds": list(TUNING_SEEDS),
                                         "rows": rows}, indent=2))
    if args.markdown:
        args.markdown.write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
