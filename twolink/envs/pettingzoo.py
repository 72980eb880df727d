"""The decentralized task as a PettingZoo environment: one agent per joint, (17)-(18).

``parallel_env(...)`` returns a :class:`pettingzoo.ParallelEnv` whose every step is one
sample period Ts = 0.05 s of the MuJoCo arm, stepped by :class:`twolink.sim.plants.MujocoPlant`
(the same code path as ``rollout(policy, MujocoPlant(), x0)``, so the same x0 and the
same torques give the same trajectory bit for bit). ``env(...)`` is its AEC form through
PettingZoo's own converter (:func:`pettingzoo.utils.conversions.parallel_to_aec`), and
``raw_env(...)`` the same without the order-enforcing wrapper, as PettingZoo's modules do.

Agents ``link1``, ``link2`` (one per joint of :data:`twolink.arm.mjcf.JOINTS`). Each sends
its torque tau_i as an array of shape (1,), clipped to +-tau_i_max, and observes (18):
``link1`` (theta1, dtheta1, theta2), ``link2`` (theta2, dtheta2). Rewards are (17) per
link on the state reached (``reward="paper"``, the default; ``"individual"`` is its older
name), or the same number to every agent: (15) (``"centralized"``) or r1 + r2
(``"sum"``). Episodes are truncated at the time limit (default 5 s = 100 steps), never
terminated.

Options for learners (:mod:`twolink.envs.core` names them once, :mod:`twolink.envs.multi_agent`
defines them for this env and the batched one):

- ``reward="shaped"``: each agent the dense shaped reward of its own link
  (:func:`twolink.envs.multi_agent.shaped_link_rewards`: 0 in its goal band, in [-1, 0)
  outside); ``"shaped_team"``: the Gymnasium env's :func:`twolink.envs.core.shaped_reward`
  of the whole arm, the same number to every agent.
- ``actions="normalized"``: each agent's action a float32 Box [-1, 1] of shape (1,),
  clipped to it and scaled to the nominal +-tau_i_max (``"box"``, the default: the torque).
- ``observation="cos_sin"``: every angle an agent observes replaced in place by its
  (cos, sin), as the Gymnasium env's ``observation="cos_sin"`` (``"state"``, the default).
- ``observe``: what each agent sees of the arm, ``"neighbours"`` (the default: the
  one-hop observations above), ``"local"`` (its own joint only, (theta_I, dtheta_I), the
  information of the paper's agent 2) or ``"global"`` (the whole state).

Many arms in one MuJoCo call per Ts, for multi-agent learners:
:func:`twolink.envs.pettingzoo_batched.batched_parallel_env` (dicts of arrays, same-step
autoreset; not a PettingZoo env).

N links (``links=3`` .. 6, ``rule`` ``'tapered'`` | ``'copied'``): agents
``link1`` .. ``linkN``, one per joint; ``linkI`` (I < N) observes the one-hop
(theta_I, dtheta_I, theta_{I+1}, dtheta_{I+1}) and ``linkN`` (theta_N, dtheta_N)
(:func:`twolink.envs.core.observation_names`) with ``observe="neighbours"``; rewards (17)
per link (or any reward option above); episodes of 8 s from random angles at rest by default
(:func:`twolink.envs.core.horizon`). ``link1_tau2`` then applies to every inner agent: link I
sees its outer neighbour's torque tau_{I+1} (``"previous"``; in the AEC form
``"current"``, with the turns running linkN first down to link1). Perturbations,
challenges and observation noise are two-link options.

How link1 can see tau2 (``link1_tau2``). In (18) agent 2 chooses tau2 first and agent 1
reads it in the same sample.
- ``"previous"`` (parallel and AEC-through-the-converter): in a parallel step both agents
  act at once, so no observation can hold the tau2 of that step; the only causal reading
  is link2's *previous* torque, appended to link1's observation (as link2 commanded it,
  before the plant clips it to +-tau2_max, as a policy's agent 1 reads it; in [-1, 1]
  units with ``actions="normalized"``; 0 after reset). The converter refreshes observations once per cycle, so its AEC form
  shows link1 that same previous tau2, whatever the turn order.
- ``"current"`` (AEC only, ``env(link1_tau2="current")``): :class:`SequentialArm` lets
  link2 act first and then shows link1 the tau2 just chosen: the paper's ordering (18).
- ``"none"`` (default): observations exactly as (18) lists the states.
For a policy file, :func:`policy_actions` keeps the paper's ordering on any of these: its
agent 2 acts first and hands tau2 to agent 1 directly, as
:func:`twolink.envs.dm.decentralized_action` does for the dm_env task.

Options (keyword-only), as in :func:`twolink.envs.dm.load`: ``x0`` (``'paper'``, ``'random'``
or a state (4,); also ``reset(options={'x0': ...})`` for one episode), ``params``,
``perturbation`` (a dict of relative changes, or a size s: one random joint change of every
Table I constant within +-s, drawn anew each episode), ``angle_noise``/``speed_noise``
(observation noise; rewards read the true state) and ``delay`` (actuation delay in sample
periods), or instead of these ``challenge`` (a level of :data:`twolink.sim.challenges.LEVELS`,
``'easy'``, ``'medium'``, ``'hard'``, or a :class:`twolink.sim.challenges.Challenge`): a new
plant every episode, its delays, noise and dropped/stuck readings. All randomness comes
from ``reset(seed=...)``: per episode the plant, then x0, then at every observation the
noise and the reading faults.
"""
from __future__ import annotations

import numpy as np
import pettingzoo
from gymnasium import logger, spaces
from pettingzoo.utils import conversions
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from twolink.arm import mjcf
from twolink.arm.parameters import TS, ArmParameters, LinksParameters
from twolink.arm.observations import OBSERVATIONS
from twolink.envs.core import (
    AGENT_ACTION_OPTIONS,
    AGENT_REWARD_OPTIONS,
    BAD_TIME_LIMIT,
    OBSERVE_OPTIONS,
    arm,
    check_action,
    check_agent_reward,
    check_challenge,
    check_reset_options,
    check_two_link_options,
    check_x0,
    check_x0_speeds,
    default_x0,
    horizon,
    initial_state,
    perturbed_params,
    state_bounds,
)
from twolink.envs.multi_agent import (  # noqa: F401 (policy_actions: public here too)
    agent_bounds,
    agent_observations,
    agent_rewards,
    agents,
    check_agent_action,
    float_box,
    policy_actions,
)
from twolink.sim.perturbations import ActuationDelay, Sensors
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import steps_for
from twolink.validate import choice, is_real, real
from twolink.validate import seed as check_seed


#: The agents of the two-link arm, one per joint; agent ``linkI`` is agent I of (17)-(18).
AGENTS = agents(len(mjcf.JOINTS))
#: Reward options (:data:`twolink.envs.core.AGENT_REWARD_OPTIONS`, where each is defined).
REWARDS = AGENT_REWARD_OPTIONS
#: What link1 may see of link2's torque in a parallel step (see the module docstring);
#: ``"current"`` exists in the AEC form only (:class:`SequentialArm`).
LINK1_TAU2 = ("none", "previous")
RESET_OPTIONS = ("x0",)


class ParallelArm(pettingzoo.ParallelEnv):
    """The decentralized task (17)-(18) as a :class:`pettingzoo.ParallelEnv`.

    Observation spaces declare the true bounds, as the Gymnasium and dm_env environments
    do: angles in [-pi, pi] and speeds in +-speed_max (the plant wraps and saturates them
    at the end of every sample period; an x0 given is wrapped and refused with a speed
    beyond speed_max), and so does ``state_space``. Declared unbounded: the angles and
    speeds an agent observes under observation noise (``angle_noise``, ``speed_noise``, a
    noisy ``challenge``: Gaussian noise can carry a reading past any bound; ``state()``
    is the true state and stays bounded), and the neighbour's torque of ``link1_tau2``
    (the torque as commanded, before the plant clips it: any finite number). A cos or
    sin (``observation="cos_sin"``) is declared in [-1, 1], noisy or not.
    """

    metadata = {"name": "twolink_decentralized_v0", "render_modes": ["rgb_array"],
                "render_fps": round(1 / TS), "is_parallelizable": True}

    def __init__(self, *, x0=None, params=None, perturbation=None,
                 angle_noise: float = 0.0, speed_noise: float = 0.0, delay: int = 0,
                 reward: str = "paper", link1_tau2: str = "none",
                 time_limit: float | None = None, render_mode: str | None = None,
                 challenge=None, links: int | None = None, rule: str | None = None,
                 actions: str = "box", observation: str = "state",
                 observe: str = "neighbours"):
        if params is not None and not isinstance(params, (ArmParameters, LinksParameters)):
            raise ValueError(f"params must be ArmParameters or LinksParameters, got {params!r}")
        params = arm(params, links=links, rule=rule)
        n = self.links = params.links
        check_two_link_options(n, perturbation=perturbation, challenge=challenge,
                               angle_noise=angle_noise, speed_noise=speed_noise)
        x0 = default_x0(n) if x0 is None else x0
        time_limit = horizon(n) if time_limit is None else time_limit
        if link1_tau2 == "current":
            raise ValueError("link1_tau2='current' is impossible in a parallel step: both "
                             "agents act at once, so link2's torque of this step does not "
                             "exist when link1 observes; use 'previous', or the AEC form "
                             "env(link1_tau2='current') for the paper's ordering (18)")
        self._link1_tau2 = choice(link1_tau2, "link1_tau2", LINK1_TAU2)
        self._reward = check_agent_reward(reward)
        self._actions = choice(actions, "actions", AGENT_ACTION_OPTIONS)
        self._observation = choice(observation, "observation", OBSERVATIONS)
        self._observe = choice(observe, "observe", OBSERVE_OPTIONS)
        if render_mode is not None:
            choice(render_mode, "render_mode", self.metadata["render_modes"])
        self._steps = steps_for(real(time_limit, "time_limit", 0, open_low=True,
                                     message=BAD_TIME_LIMIT))
        for name, value, what in (("angle_noise", angle_noise, "one standard deviation (rad)"),
                                  ("speed_noise", speed_noise, "one standard deviation (rad/s)"),
                                  ("delay", delay, "a whole number of sample periods")):
            if not is_real(value):      # one real number (not a bool, not an array)
                raise ValueError(f"{name} must be {what}, got {value!r}")
        # Check the remaining options now (with a throw-away generator), not at reset.
        fixed = perturbed_params(params, perturbation, np.random.default_rng(0))
        # Where the plant saturates speeds: Table I's limits (a size or a challenge never
        # changes them; a dict of changes may).
        self._speed_max = np.maximum(params.speed_max, fixed.speed_max)
        self._base, self._perturbation = params, perturbation
        self._x0 = self._check_x0(x0)
        sensors = Sensors(angle_noise, speed_noise, rngs=[None])
        ActuationDelay(None, delay)
        self._challenge = check_challenge(challenge, perturbation=perturbation,
                                          angle_noise=angle_noise, speed_noise=speed_noise,
                                          delay=delay)
        if self._challenge is not None:
            sensors = self._challenge.sensors(rngs=[None])
        self._noise_std = (float(angle_noise), float(speed_noise))
        self._delay = delay if self._challenge is None else self._challenge.action_delay
        self.render_mode = render_mode

        self._agents = agents(n)
        self.possible_agents = list(self._agents)
        self.agents: list = []
        # With link1_tau2="previous" every inner agent also sees its outer neighbour's action.
        extra = 1 if link1_tau2 == "previous" else 0
        bound = state_bounds(self._speed_max)
        self.state_space = spaces.Box(-bound, bound, (2 * n,), np.float64)
        seen = np.full(2 * n, np.inf) if sensors.noisy else bound
        highs = agent_bounds(n, observe, observation, seen)
        self.observation_spaces = {
            a: float_box([*highs[i - 1]] + [np.inf] * (extra if i < n else 0))
            for i, a in enumerate(self._agents, 1)}
        tau_max = params.tau_max
        self.action_spaces = {
            a: (spaces.Box(-1.0, 1.0, (1,), np.float32) if actions == "normalized"
                else spaces.Box(-tau_max[i], tau_max[i], (1,), np.float64))
            for i, a in enumerate(self._agents)}

        self._rng = None
        self._plant = None
        self._renderer = None
        self.params = None
        self._x = None
        self._k = 0

    # ------------------------------------------------------------------ spaces
    def _check_x0(self, x0):
        """A checked ``x0`` option; a given state wrapped and within the speed limit."""
        from twolink.envs.starts import check_slow_starts

        x0 = check_x0(x0, self.links)
        if not isinstance(x0, str):
            check_x0_speeds(x0, self._speed_max)
        check_slow_starts(x0, self._base)
        return x0

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    # ------------------------------------------------------------------ episodes
    def reset(self, seed=None, options=None):
        """Start an episode; ``options={'x0': ...}`` sets this episode's initial state."""
        options = check_reset_options(options, RESET_OPTIONS)
        x0 = self._check_x0(options["x0"]) if "x0" in options else self._x0
        seed = check_seed(seed)
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        ch = self._challenge
        params = (ch.plant(self._rng, self._base) if ch is not None
                  else perturbed_params(self._base, self._perturbation, self._rng))
        x = initial_state(x0, self._rng, self.links, self._base)
        if self._plant is None or params != self.params:
            self._close_plant()
            self._plant = MujocoPlant(params, nthread=1)
        self.params, self._x, self._k = params, x, 0
        self._noise = (ch.sensors(rngs=[self._rng]) if ch is not None
                       else Sensors(*self._noise_std, rngs=[self._rng]))
        self._delay_line = ActuationDelay(lambda u: u, self._delay)
        self._last = np.zeros(self.links)
        self._applied = np.zeros(self.links)
        self._rewards = dict.fromkeys(self._agents, 0.0)
        self.agents = list(self._agents)
        return self._observations(), {a: {} for a in self.agents}

    def step(self, actions):
        """One sample period under the agents' torques: (observations, rewards,
        terminations, truncations, infos)."""
        if self._x is None:
            raise RuntimeError("call reset() before step()")
        if not self.agents:
            raise RuntimeError("the episode is over (truncated at the time limit); call reset()")
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict {{agent: action}}, "
                             f"got {type(actions).__name__}")
        unknown = [a for a in actions if a not in self.agents]
        missing = [a for a in self.agents if a not in actions]
        if unknown or missing:
            raise ValueError(f"actions must name every agent exactly ({', '.join(self.agents)}); "
                             + "; ".join(f"{what}: {', '.join(map(repr, names))}" for what, names
                                         in (("unknown", unknown), ("missing", missing)) if names))
        commanded = np.concatenate([check_agent_action(a, actions[a]) for a in self._agents])
        if self._actions == "normalized":   # [-1, 1] scaled to the nominal +-tau_max
            tau = check_action(commanded, np.ones(self.links)) * self._base.tau_max
        else:
            tau = check_action(commanded, self.params.tau_max)
        applied = np.asarray(self._delay_line(tau), dtype=np.float64)
        x = self._plant.step(self._x, applied)
        self._x, self._k, self._last, self._applied = x, self._k + 1, commanded, applied
        self._rewards = self._reward_of(x)
        done = self._k >= self._steps
        obs = self._observations()
        rewards = dict(self._rewards)
        terminations = dict.fromkeys(self._agents, False)
        truncations = dict.fromkeys(self._agents, done)
        infos = {a: {} for a in self._agents}
        if done:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    def _observations(self) -> dict:
        """Per-agent observations (:mod:`twolink.envs.multi_agent`), fresh arrays; noise on
        the measured state only (drawn once per observation)."""
        seen = agent_observations(self._noise(self._x), self.links, self._observe,
                                  self._observation)
        obs = dict(zip(self._agents, seen))
        if self._link1_tau2 == "previous":          # agent i sees a_{i+1}, i < N
            for i, a in enumerate(self._agents[:-1]):
                obs[a] = np.append(obs[a], self._last[i + 1])
        return {a: obs[a] for a in self.agents}

    def _reward_of(self, x) -> dict:
        """Every agent's reward on the state reached (:func:`~twolink.envs.multi_agent.agent_rewards`)."""
        r = agent_rewards(x, self._reward)
        return {a: float(r[i]) for i, a in enumerate(self._agents)}

    def state(self) -> np.ndarray:
        """The true state x = [theta1 .. thetaN, dtheta1 .. dthetaN] (a copy)."""
        if self._x is None:
            raise RuntimeError("call reset() before state()")
        return self._x.copy()

    # ------------------------------------------------------------------ rendering
    def render(self):
        """An RGB frame (H, W, 3) of the arm when ``render_mode='rgb_array'``, else None."""
        if self.render_mode is None:
            logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        if self._x is None:
            raise RuntimeError("call reset() before render()")
        from twolink.viz.render import (
            Renderer,  # GL is set up only when a frame is wanted
        )
        if self._renderer is None or self._renderer.params != self.params:
            self._close_renderer()
            self._renderer = Renderer(width=320, height=240, params=self.params)
        lines = (f"t = {self._k * TS:4.2f} s",
                 "tau = " + ", ".join(f"{t:+.3f}" for t in self._applied),
                 "r = " + ", ".join(f"{r:+.1f}" for r in self._rewards.values()))
        return self._renderer.frame(self._x, lines=lines)

    # ------------------------------------------------------------------ resources
    def _close_plant(self):
        if self._plant is not None:
            self._plant.close()
            self._plant = None

    def _close_renderer(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def close(self):
        """Free the renderer's GL context and the MuJoCo plant (its models and data)."""
        self._close_renderer()
        self._close_plant()
        self._x, self.agents = None, []


class SequentialArm(pettingzoo.AECEnv):
    """The decentralized task as an AEC env in the ordering of (18): in every sample
    link2 acts first, then link1 observes (theta1, dtheta1, theta2, tau2) with the tau2
    link2 has just commanded (before clipping) and acts, then the arm moves one sample period.
    For N links the turns run linkN, .., link1, and every inner link I observes its own
    observation followed by the tau_{I+1} its outer neighbour has just commanded.

    ``arm`` (a :class:`ParallelArm` without ``link1_tau2``) holds the physics, the options,
    the perturbations and the rewards; this class only orders the turns. Outside link1's
    turn its observation holds link2's latest torque (0 after reset).
    """

    def __init__(self, arm: ParallelArm):
        if not isinstance(arm, ParallelArm) or arm._link1_tau2 != "none":
            raise ValueError("SequentialArm needs a ParallelArm made without link1_tau2")
        super().__init__()
        self.arm = arm
        # The converter to a parallel env would have link1 choose before link2: not (18).
        self.metadata = {**arm.metadata, "name": "twolink_decentralized_sequential_v0",
                         "is_parallelizable": False}
        self.render_mode = arm.render_mode
        self._agents = tuple(arm.possible_agents)
        self.possible_agents = list(reversed(self._agents))  # the turn order: outermost first
        self.agents: list = []
        self.observation_spaces = {a: arm.observation_space(a) for a in self._agents}
        for a in self._agents[:-1]:                # inner agents: + tau_{i+1}, unbounded
            own = arm.observation_space(a).high
            self.observation_spaces[a] = float_box([*own, np.inf])
        self.action_spaces = {a: arm.action_space(a) for a in self._agents}
        self.state_space = arm.state_space

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def reset(self, seed=None, options=None):
        self._obs, infos = self.arm.reset(seed=seed, options=options)
        self._tau = np.zeros(len(self._agents))   # the latest torque each agent commanded
        self._chosen: dict = {}
        self.agents = list(self.possible_agents)
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self.infos = {a: infos[a] for a in self.agents}
        self.agent_selection = self.agents[0]

    def observe(self, agent):
        """The agent's observation (18); link1's ends with link2's latest torque (link I's,
        I < N, with tau_{I+1})."""
        i = self._agents.index(agent)
        if i < len(self._agents) - 1:
            return np.append(self._obs[agent], self._tau[i + 1])
        return self._obs[agent].copy()

    def step(self, action):
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        i = self._agents.index(agent)
        a = check_agent_action(agent, action)
        if agent == self.agents[0]:
            self._clear_rewards()
        self._cumulative_rewards[agent] = 0.0
        self._chosen[agent] = a
        self._tau[i] = a[0]
        if agent != self.agents[-1]:
            self.agent_selection = self.agents[self.agents.index(agent) + 1]
            return
        chosen, self._chosen = self._chosen, {}
        self._obs, self.rewards, self.terminations, self.truncations, self.infos = \
            self.arm.step(chosen)
        self._accumulate_rewards()
        self.agent_selection = self.agents[0]

    def state(self) -> np.ndarray:
        return self.arm.state()

    def render(self):
        return self.arm.render()

    def close(self):
        """Free the renderer and the MuJoCo plant (see :meth:`ParallelArm.close`)."""
        self.arm.close()
        self.agents = []


def parallel_env(**kwargs) -> ParallelArm:
    """The decentralized task as a ParallelEnv (options: see :class:`ParallelArm`)."""
    return ParallelArm(**kwargs)


def raw_env(**kwargs):
    """The AEC form without PettingZoo's order-enforcing wrapper: with
    ``link1_tau2='current'`` the :class:`SequentialArm` of (18), else the parallel env
    through PettingZoo's converter."""
    if kwargs.get("link1_tau2") == "current":
        return SequentialArm(ParallelArm(**{**kwargs, "link1_tau2": "none"}))
    return conversions.parallel_to_aec_wrapper(parallel_env(**kwargs))


def env(**kwargs):
    """The AEC form: with ``link1_tau2='current'`` the :class:`SequentialArm` of (18)
    (link2 first, link1 sees its torque), else the parallel env through PettingZoo's
    converter (:func:`parallel_to_aec`); both order-enforced."""
    if kwargs.get("link1_tau2") == "current":
        return OrderEnforcingWrapper(raw_env(**kwargs))
    return conversions.parallel_to_aec(parallel_env(**kwargs))
