"""Many arms of the multi-agent task in one MuJoCo call per Ts, for multi-agent learners.

``batched_parallel_env(num_arms, **options)`` returns a :class:`BatchedParallelArms`: the
task of :class:`twolink.envs.pettingzoo.ParallelArm` (same options, same agents
``link1`` .. ``linkN``, same spaces per agent) on ``num_arms`` arms at once, with every
per-agent value an array over the arms. It is **not** a PettingZoo env (its values are
batches, and PettingZoo's ``parallel_api_test`` does not apply to it): it is the
multi-agent counterpart of :class:`twolink.envs.gym.TwoLinkVectorEnv`, for learners that
step many environments as one (IPPO/MAPPO in skrl, MARLlib-style vectorised
collectors). The arms run under one :class:`twolink.envs.gym_arms.Arms` (one
``mujoco.rollout`` call per Ts for all of them, each arm with its own generator), the
batched episode core the Gymnasium vector env and the Stable-Baselines3 ``VecEnv`` use;
what the agents observe and earn comes from :mod:`twolink.envs.multi_agent`, as for
``ParallelArm``. So arm i's episodes equal those of a ``ParallelArm`` with the same options
reset with seed s + i (and then reset without a seed after each episode) bit for bit, for
the same actions.

The interface, for a reader writing a learner (arrays are numpy, float64 unless said)::

    env = batched_parallel_env(64, links=3, reward="shaped", actions="normalized")
    obs, infos = env.reset(seed=0)          # obs[agent]: (num_arms, obs_dim[agent])
    obs, rewards, terminations, truncations, infos = env.step(
        {agent: actions_of_agent for agent in env.agents})   # each (num_arms, 1) or (num_arms,)

- ``env.agents`` / ``env.possible_agents``: ``['link1', .., 'linkN']`` (always all: an
  arm whose episode ended restarts in the same step).
- ``env.observation_space(agent)`` / ``env.action_space(agent)``: one arm's space of that
  agent (a Box; ``actions="normalized"``: float32 [-1, 1]); ``env.state_space`` one arm's
  true state; ``env.state()`` the true states (num_arms, 2N), for a centralized critic.
- ``rewards[agent]``: (num_arms,); ``terminations[agent]``: (num_arms,) bool, always False
  (the task never terminates); ``truncations[agent]``: (num_arms,) bool, True for the arms
  whose episode reached the time limit at this step (the same for every agent).
- **Same-step autoreset**: an arm truncated at this step is reset inside the same call, so
  ``obs`` already holds the first observation of its next episode. What the ended
  episode reached is in the infos: ``infos[agent]['final_observation']`` (num_arms,
  obs_dim) holds every arm's observation of the state reached at this step (before any
  reset: for the truncated arms their episode's last observation, to bootstrap from; for
  the others equal to ``obs[agent]``), ``infos[agent]['final_state']`` (num_arms, 2N) the
  true states reached, and ``infos[agent]['is_success']`` (num_arms,) bool whether each
  truncated arm settled by :func:`twolink.sim.metrics.success` (False for the others).
  ``reset`` returns ``infos[agent] = {}``.
- ``reset(seed=s)``: arm i draws from ``np.random.default_rng(s + i)``; ``seed=None``
  keeps each arm's generator (fresh ones at the first reset). ``options={'x0': ...}``
  one state (2N,) for every arm or one per arm (num_arms, 2N), for this episode.
- Bad actions (a missing or unknown agent, a wrong shape, NaN) are one ValueError naming
  the agent, before any arm moves.
- ``plant="full"`` steps the arms on the full model (6) (N links: the rigid-body chain)
  integrated by numpy in one batch instead of MuJoCo (:class:`twolink.envs.gym_arms.Arms`;
  a fixed plant only: no perturbation size or challenge).
"""
from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding

from twolink.envs.core import check_reset_options
from twolink.envs.gym import MAX_ENVS
from twolink.envs.gym_arms import Arms
from twolink.sim.challenges import is_mix, mix
from twolink.envs.multi_agent import agent_observations, agent_rewards
from twolink.envs.pettingzoo import ParallelArm
from twolink.validate import MAX_SEED, is_whole, whole
from twolink.validate import seed as check_seed

#: Keys ``reset(options=...)`` accepts.
RESET_OPTIONS = ("x0",)


class BatchedParallelArms:
    """``num_arms`` arms of :class:`twolink.envs.pettingzoo.ParallelArm`'s task stepped as
    one (see the module docstring for the interface and its autoreset). Options: those of
    ``ParallelArm`` except ``render_mode``, plus ``nthread`` (MuJoCo's threads, default
    all cores) and ``plant`` (``'mujoco'`` or ``'full'``, the numpy full model; module
    docstring)."""

    metadata = {"name": "twolink_decentralized_batched_v0"}

    def __init__(self, num_arms: int, *, x0=None, params=None, perturbation=None,
                 angle_noise: float = 0.0, speed_noise: float = 0.0, delay: int = 0,
                 reward: str = "paper", link1_tau2: str = "none",
                 time_limit: float | None = None, challenge=None, links: int | None = None,
                 rule: str | None = None, actions: str = "box", observation: str = "state",
                 observe: str = "neighbours", nthread: int | None = None,
                 plant: str = "mujoco"):
        self.num_arms = whole(num_arms, "num_arms", 1, MAX_ENVS)
        options = dict(x0=x0, params=params, perturbation=perturbation,
                       angle_noise=angle_noise, speed_noise=speed_noise, delay=delay,
                       time_limit=time_limit, challenge=challenge, links=links, rule=rule)
        # One arm's env checks every option and defines the spaces; it never steps. Under a
        # mix of levels (training only: arm i under level i mod L) the spaces are those of
        # its last level, the noisiest (levels are in the table's order, mildest first).
        spec_options = dict(options, challenge=mix(challenge).levels[-1]) \
            if is_mix(challenge) else options
        spec = ParallelArm(**spec_options, reward=reward, link1_tau2=link1_tau2,
                           actions=actions, observation=observation, observe=observe)
        self.links = spec.links
        self.possible_agents = list(spec.possible_agents)
        self.agents = list(spec.possible_agents)
        self.observation_spaces = dict(spec.observation_spaces)
        self.action_spaces = dict(spec.action_spaces)
        self.state_space = spec.state_space
        self._reward, self._actions = reward, actions
        self._observation, self._observe = observation, observe
        self._previous = link1_tau2 == "previous"
        # Box torques are clipped by the plant at each arm's own limits, as ParallelArm
        # clips them at its episode's plant; "normalized" is scaled by the nominal limits.
        self._arms = Arms(self.num_arms, **options, observation="state",
                          actions="normalized" if actions == "normalized" else "box",
                          nthread=nthread, plant=plant)
        self._last = np.zeros((self.num_arms, self.links))
        self._started = False

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def state(self) -> np.ndarray:
        """The true states (num_arms, 2N) (a copy)."""
        self._check_started()
        return self._live().x.copy()

    # ------------------------------------------------------------------ episodes
    def reset(self, seed=None, options=None):
        """Start an episode on every arm: ``(obs, infos)`` (see the module docstring)."""
        arms = self._live()
        options = check_reset_options(options, RESET_OPTIONS)
        n = self.num_arms
        if seed is not None and not is_whole(seed):
            raise TypeError(f"seed must be a whole number or None, got {seed!r}")
        seed = None if seed is None else check_seed(seed, high=MAX_SEED - n)
        x0s = arms.check_x0_option(options["x0"]) if "x0" in options else [arms.x0] * n
        rngs = [seeding.np_random(seed + i)[0] if seed is not None
                else arms.rngs[i] if arms.rngs[i] is not None
                else seeding.np_random(None)[0] for i in range(n)]
        rows = np.arange(n)
        arms.reset_rows(rows, rngs, x0s)
        self._last[:] = 0.0
        self._started = True
        return self._observe_rows(rows), {a: {} for a in self.agents}

    def step(self, actions):
        """One sample period of every arm: ``(obs, rewards, terminations, truncations,
        infos)``, dicts of arrays over the arms, with same-step autoreset."""
        arms = self._live()
        self._check_started()
        commanded = self._check_actions(actions)
        tau = arms.torques(commanded) if self._actions == "normalized" else commanded
        x, _, truncated = arms.step(tau)
        arms.commit(x)
        self._last = commanded
        rows = np.arange(self.num_arms)
        final = self._observe_rows(rows)
        obs = {a: o.copy() for a, o in final.items()}
        r = agent_rewards(x, self._reward)
        success = np.zeros(self.num_arms, dtype=bool)
        if truncated.any():
            ended = np.flatnonzero(truncated)
            success[ended] = arms.settled(ended)
            arms.reset_rows(ended, [arms.rngs[i] for i in ended], [arms.x0] * len(ended))
            self._last[ended] = 0.0
            for a, o in self._observe_rows(ended).items():
                obs[a][ended] = o
        rewards = {a: r[:, i].copy() for i, a in enumerate(self.agents)}
        terminations = {a: np.zeros(self.num_arms, dtype=bool) for a in self.agents}
        truncations = {a: truncated.copy() for a in self.agents}
        infos = {a: {"final_observation": final[a], "final_state": x.copy(),
                     "is_success": success.copy()} for a in self.agents}
        return obs, rewards, terminations, truncations, infos

    def _observe_rows(self, rows) -> dict:
        """Every agent's observation of ``rows`` (noise drawn once per row)."""
        arms = self._arms
        seen = agent_observations(arms.observe(rows), self.links, self._observe,
                                  self._observation)
        obs = dict(zip(self.agents, seen))
        if self._previous:                          # agent i sees a_{i+1}, i < N
            for i, a in enumerate(self.agents[:-1]):
                obs[a] = np.concatenate([obs[a], self._last[rows, i + 1, None]], -1)
        return obs

    def _check_actions(self, actions) -> np.ndarray:
        """The agents' actions as (num_arms, N) float64, each checked; a ValueError naming
        the agent otherwise."""
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict {{agent: array (num_arms, 1)}}, got "
                             f"{type(actions).__name__}")
        unknown = [a for a in actions if a not in self.agents]
        missing = [a for a in self.agents if a not in actions]
        if unknown or missing:
            raise ValueError(f"actions must name every agent exactly ({', '.join(self.agents)})"
                             "; " + "; ".join(f"{what}: {', '.join(map(repr, names))}" for
                                              what, names in (("unknown", unknown),
                                                              ("missing", missing)) if names))
        out = np.empty((self.num_arms, self.links))
        for i, agent in enumerate(self.agents):
            a = np.asarray(actions[agent])
            if a.dtype.kind not in "fiu":
                raise ValueError(f"actions of {agent} must be real numbers, got dtype "
                                 f"{a.dtype}")
            if a.shape not in ((self.num_arms,), (self.num_arms, 1)):
                raise ValueError(f"actions of {agent} must have shape ({self.num_arms}, 1) "
                                 f"or ({self.num_arms},) [one torque per arm], got shape "
                                 f"{a.shape}")
            a = a.reshape(-1).astype(np.float64)
            if not np.all(np.isfinite(a)):
                raise ValueError(f"actions of {agent} contain NaN or infinite values")
            out[:, i] = a
        return out

    def _check_started(self):
        if not self._started:
            raise RuntimeError("call reset() before step() or state()")

    def _live(self) -> Arms:
        if self._arms is None:
            raise RuntimeError("the batched environment is closed")
        return self._arms

    def close(self) -> None:
        """Free the plant (MuJoCo's thread pool); idempotent."""
        if self._arms is not None:
            self._arms.close()
            self._arms = None


def batched_parallel_env(num_arms: int, **options) -> BatchedParallelArms:
    """``num_arms`` arms of :func:`twolink.envs.pettingzoo.parallel_env`'s task in one
    MuJoCo call per Ts (options: see :class:`twolink.envs.pettingzoo.ParallelArm`; returns
    dicts of arrays, agent -> (num_arms, obs_dim); not a PettingZoo env, see the module
    docstring)."""
    return BatchedParallelArms(num_arms, **options)
