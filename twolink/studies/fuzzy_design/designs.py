"""The study-only controllers the tuning table measures and the package does not ship,
each synthesised here from the package's pieces (:mod:`twolink.synthesis.problems`,
:mod:`twolink.fqi.fuzzy`): the expectation over the reading noise inside the transition
model (:func:`noise_expectation`), per-agent grids (:func:`per_agent`), agent 2 as the
worst case over link 1's motion (:func:`agent2_worst_over_link1`) and agents that know
their torque is one sample late (:class:`DelayAware`); and :func:`readout_of`, the
read-out every variant of :mod:`.variants` is built with.
"""
from __future__ import annotations

import numpy as np

from twolink.arm.parameters import TABLE_I
from twolink.arm.task import action_levels, agent_reward, centralized_reward
from twolink.fqi import fuzzy
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.readout import Readout
from twolink.synthesis import problems as P

#: Seed of the noise offsets of :func:`noise_expectation`.
NOISE_SEED = 9303


def readout_of(width: float, argmax=None, near=None):
    """The read-out of a design: a speed dead zone of ``width`` rad/s, the argmax of Q
    beyond ``argmax`` degrees and the near-goal gain ``near`` = (gain, angle_deg); None
    when it asks for none of them (the plain read-out)."""
    gain, deg = near or (1.0, None)
    return Readout(speed_dead_zone=width, argmax_beyond_deg=argmax, near_gain=gain,
                   near_deg=deg) if width or argmax is not None or near else None



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
        meta["readout"] = readout_of(dead_zone).as_dict()
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
            "readout": readout_of(0.06, 30.0).as_dict()}
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
            "readout": readout_of(0.06, 30.0).as_dict()}
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
    """:class:`DelayAware` with ``levels`` torque levels per joint."""
    return DelayAware(levels)
