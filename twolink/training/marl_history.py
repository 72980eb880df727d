"""Each agent's own observation history on the batched multi-agent env.

An IPPO/MAPPO run of ``history`` K (:class:`twolink.training.marl.MarlConfig`) hands
agent ``linkI`` of every arm, instead of its present observation, the last K of its own
observations and its own K - 1 last actions, in the layout of
:mod:`twolink.control.history` (one :class:`~twolink.control.history.ObservationHistory`
per agent over the arms, actions of one number)::

    [o_{t-K+1}, ..., o_t,  a_{t-K+1}, ..., a_{t-1}]        (K d_I + K - 1 numbers)

oldest first, zeros before an episode's first observation. The env
(:class:`twolink.envs.pettingzoo_batched.BatchedParallelArms`) resets an arm whose
episode ended in the same step: that arm's history of the reached observation (its
``final_observation``, to bootstrap from) ends the old episode, and its history starts
from zeros again with the first observation of the next, as
:class:`twolink.envs.history.HistoryVecEnv` does for Stable-Baselines3. The actions
recorded are the agent's own, clipped to [-1, 1] (before any base controller adds to
them), which :class:`twolink.control.marl_agent.MarlController` records too when it runs
the saved agents, so they see in evaluation what they saw in training. K = 1 is the
observation alone.
"""
from __future__ import annotations

import numpy as np

from twolink.control.history import ObservationHistory, check_history, history_layout


class AgentHistories:
    """The histories of length ``k`` of the ``agents`` (observations of ``sizes[agent]``
    numbers) over ``rows`` arms (see the module docstring)."""

    def __init__(self, agents, rows: int, sizes: dict, k: int):
        self.k = check_history(k)
        self.agents = list(agents)
        self.buffers = {a: ObservationHistory(rows, sizes[a], 1, self.k) for a in self.agents}

    def size(self, agent) -> int:
        """Numbers in one history observation of ``agent``."""
        return self.buffers[agent].size

    def layout(self, agent) -> dict:
        """``agent``'s :func:`twolink.control.history.history_layout` (for the agent file)."""
        b = self.buffers[agent]
        return history_layout(self.k, b.obs_size, 1)

    def start(self, obs: dict) -> dict:
        """Every arm starts an episode on the observations ``obs`` (agent -> (rows, d)):
        the history observations."""
        out = {}
        for a in self.agents:
            self.buffers[a].reset()
            out[a] = self.buffers[a].observe(obs[a])
        return out

    def act(self, actions: dict) -> None:
        """Add every agent's clipped actions (rows, 1) given on its newest observations."""
        for a in self.agents:
            self.buffers[a].act(np.clip(np.asarray(actions[a], dtype=float), -1.0, 1.0))

    def step(self, obs: dict, final: dict, ended) -> tuple[dict, dict]:
        """(history observations, final history observations) after an env step:
        ``final`` are the observations of the states reached, ``obs`` those the next step
        acts on (the ``ended`` arms' first of a new episode)."""
        ended = np.flatnonzero(ended)
        out, last = {}, {}
        for a in self.agents:
            b = self.buffers[a]
            last[a] = b.observe(final[a])
            out[a] = last[a].copy()
            if len(ended):
                b.reset(ended)
                out[a][ended] = b.observe(np.asarray(obs[a])[ended], ended)
        return out, last

    def state(self) -> dict:
        """agent -> the buffers (copies), for a checkpoint."""
        return {a: b.state() for a, b in self.buffers.items()}

    def set_state(self, state: dict) -> None:
        """Put the buffers of :meth:`state` back (shapes checked)."""
        for a, b in self.buffers.items():
            b.set_state(state[a])
