"""The arm as a dm_control environment (dm_env API): ``centralized`` and ``decentralized``.

``load(task_name, links=N)`` returns a :class:`dm_env.Environment` built on
``dm_control.rl.control.Environment`` whose every step is one sample period Ts = 0.05 s
of the MJCF arm, with the conventions of the ``mujoco`` plant: the same compiled model
(:func:`twolink.arm.mjcf.build_model`), the torques clipped to +-tau_max and held over Ts,
and the angles wrapped and speeds saturated at the end of the period
(:func:`twolink.sim.plants.finish_data`). A shipped policy driven through the environment
therefore retraces ``rollout(policy, MujocoPlant(), x0)`` bit for bit.

Tasks (two links; for N links see below)
-----------------------------------------
``centralized``: action [tau1, tau2]; observation ``{'state': [theta1, theta2, dtheta1,
dtheta2]}``; reward (15), a float.

``decentralized``: the two agents of (18). The action is still the joint [tau1, tau2]
(one physics step per joint action). Observations per agent: ``'agent2'`` =
(theta2, dtheta2), ``'agent1'`` = (theta1, dtheta1, theta2). Agent 1 also reads agent 2's
*current* tau2, which no environment can observe before it is chosen: as in (18) agent 2
acts first and hands its tau2 to agent 1 directly (see :func:`decentralized_action`).
The reward is the array [r1, r2] of (17) (``reward_spec()`` has shape (2,)).

N links (``links=3`` .. 6): the arm of :func:`twolink.arm.parameters.links_parameters`
(``rule`` ``'tapered'`` or ``'copied'``). ``centralized``: action [tau1 .. tauN],
observation ``{'state': [theta1 .. thetaN, dtheta1 .. dthetaN]}``, reward (15) over all
links. ``decentralized``: observations ``'agent1'`` .. ``'agentN'`` as
:func:`twolink.envs.core.observation_names` lists them (agent i: theta_i, dtheta_i,
theta_{i+1}, dtheta_{i+1}; agent N: theta_N, dtheta_N), the reward the array
[r1 .. rN] of (17). Episodes last 8 s by default (:func:`twolink.envs.core.horizon`) and
start from random angles at rest (the paper's x0 is a two-link state). Perturbations,
challenges and observation noise are two-link options (refused for N >= 3).

Both rewards lie in [-0.5, 0] and are evaluated on the state reached (r_{k+1}); the
discount is always 1 and episodes end only at the time limit (default 5 s = 100 steps
for two links).
Actions outside the spec are clipped to +-tau_max (as the plants and MuJoCo's ctrlrange
do); actions of the wrong shape, NaN or infinite actions are refused with a ValueError.
Observation noise corrupts the observations only; rewards read the true state.

Observation specs are ``BoundedArray``s of the true bounds: every sample period ends with
the angles wrapped to [-pi, pi) and the speeds saturated at +-speed_max, so angles lie in
[-pi, pi] and speeds in +-speed_max (the plant's, ``speed_max`` included); an x0 given
is wrapped the same way and refused (ValueError) with a speed beyond speed_max, so the
first observation is inside too. With observation noise (``angle_noise``,
``speed_noise`` or a noisy ``challenge``) the specs are unbounded ``Array``s: Gaussian
noise can carry a reading past any bound. The same bounds as the Gymnasium and
PettingZoo environments declare.
"""
from __future__ import annotations

import collections
import dataclasses

import numpy as np

try:
    from dm_control import mujoco
    from dm_control.mujoco import wrapper
    from dm_control.rl import control
    from dm_control.suite import base
    from dm_env import specs
except ImportError as _exc:           # Python 3.13: dm-control is installed without deps
    raise ImportError(f"twolink.envs.dm needs dm-control ({_exc}); on Python 3.13, where its "
                      "labmaze dependency has no wheel: pip install --no-deps "
                      "dm-control==1.0.50") from None

from twolink.arm import mjcf
from twolink.arm.parameters import REWARD_GOAL, REWARD_OTHER, TS, state_names
from twolink.arm.task import agent_reward, centralized_reward
from twolink.envs.core import (  # noqa: F401
    OBSERVATION_NAMES,
    BAD_TIME_LIMIT,
    TASKS,
    arm,
    check_action,
    check_challenge,
    check_policy_links,
    check_task,
    check_two_link_options,
    check_x0,
    check_x0_speeds,
    default_x0,
    horizon,
    initial_state,
    observation_names,
    perturbed_params,
    state_bounds,
)
from twolink.sim.perturbations import ActuationDelay, Sensors
from twolink.sim.plants import finish_data, set_data
from twolink.validate import count_of, real
from twolink.validate import seed as check_seed


def _hold(u):
    return np.array(u, dtype=np.float64)     # a copy: the delay keeps it


class Physics(mujoco.Physics):
    """The arm's physics with named read-outs (N links: N hinge joints)."""

    @property
    def links(self) -> int:
        return int(self.model.nq)

    def angles(self) -> np.ndarray:
        """[theta1 .. thetaN] (rad)."""
        return self.named.data.qpos[list(mjcf.joint_names(self.links))].copy()

    def speeds(self) -> np.ndarray:
        """[dtheta1 .. dthetaN] (rad/s)."""
        return self.named.data.qvel[list(mjcf.joint_names(self.links))].copy()

    def state(self) -> np.ndarray:
        """x = [theta1 .. thetaN, dtheta1 .. dthetaN]."""
        return np.concatenate([self.angles(), self.speeds()])

    def tip_position(self) -> np.ndarray:
        """(x, y) of the end of the outermost link in the plane of the arm (m)."""
        return self.named.data.site_xpos[f"link{self.links}_tip", :2].copy()


class ArmTask(base.Task):
    """Drive the arm to the origin of the state space; subclasses choose observations and reward."""

    def __init__(self, params, *, x0="paper", angle_noise: float = 0.0,
                 speed_noise: float = 0.0, random=None, challenge=None, nominal=None):
        super().__init__(random=random)
        self.params = params
        self.links = params.links
        # The controller's torque bounds (the action spec): the nominal arm's under a
        # challenge, whose changed limits only the plant (MuJoCo's ctrlrange) applies.
        self._tau_max = (params if nominal is None else nominal).tau_max
        self._x0 = check_x0(x0, self.links)
        if not isinstance(self._x0, str):
            check_x0_speeds(self._x0, params.speed_max)
        from twolink.envs.starts import check_slow_starts

        check_slow_starts(self._x0, params)
        # The true state's bounds (its angles and speeds), or unbounded under noise.
        self._bound = state_bounds(params.speed_max)
        # One row of the perturbations of twolink.sim.perturbations, drawing from the task's
        # random state: a challenge's noise, faults and delays, or the noise given.
        if challenge is not None:
            self._sensors = challenge.sensors(rngs=[self.random])
            self._delay = ActuationDelay(_hold, challenge.action_delay)
        else:
            self._sensors = Sensors(angle_noise, speed_noise, rngs=[self.random])
            self._delay = ActuationDelay(_hold, 0)
        if self._sensors.noisy:
            self._bound = None

    def _spec(self, components, name: str):
        """The spec of an observation of the state's ``components`` (indices)."""
        shape = (len(components),)
        if self._bound is None:
            return specs.Array(shape, np.float64, name=name)
        high = self._bound[list(components)]
        return specs.BoundedArray(shape, np.float64, -high, high, name=name)

    def initialize_episode(self, physics):
        """Set x0: the paper's, random angles at rest, or the given one; the delays and
        reading faults start afresh."""
        set_data(physics.data, initial_state(self._x0, self.random, self.links, self.params))
        physics.data.ctrl[:] = 0.0
        self._sensors.restart([0])
        self._delay.restart([0])
        # base.Task.initialize_episode only recolours the suite's materials: not delegated.

    def action_spec(self, physics):
        tmax = self._tau_max
        return specs.BoundedArray((self.links,), np.float64, -tmax, tmax, name="tau")

    def before_step(self, action, physics):
        """Hold the clipped torques [tau1 .. tauN] over the sample period (those of
        ``action_delay`` samples ago under a challenge; zero until they arrive)."""
        physics.set_control(self._delay(check_action(action, self._tau_max)[None])[0])

    def after_step(self, physics):
        """End the sample period as every plant does: wrap angles, saturate speeds."""
        finish_data(self.params, physics.data)
        physics.forward()

    def get_termination(self, physics):
        return None

    def _measured(self, physics) -> np.ndarray:
        return self._sensors(physics.state())


class Centralized(ArmTask):
    """One controller, the full state, reward (15)."""

    def get_observation(self, physics):
        return collections.OrderedDict(state=self._measured(physics))

    def observation_spec(self, physics):
        return collections.OrderedDict(state=self._spec(range(2 * self.links), "state"))

    def get_reward(self, physics):
        return float(centralized_reward(physics.state()))

    def reward_spec(self):
        return specs.BoundedArray((), np.float64, REWARD_OTHER, REWARD_GOAL, name="reward")


class Decentralized(ArmTask):
    """One agent per joint ((18) for two links): per-agent observations
    (:func:`twolink.envs.core.observation_names`), rewards [r1 .. rN] of (17)."""

    def __init__(self, params, **kwargs):
        super().__init__(params, **kwargs)
        names = observation_names(self.links)
        self._agents = {f"agent{i}": names[f"agent{i}"] for i in range(1, self.links + 1)}
        self._state_names = state_names(self.links)

    def get_observation(self, physics):
        x = dict(zip(self._state_names, self._measured(physics)))
        return collections.OrderedDict(
            (key, np.array([x[n] for n in names])) for key, names in self._agents.items())

    def observation_spec(self, physics):
        return collections.OrderedDict(
            (key, self._spec([self._state_names.index(n) for n in names], key))
            for key, names in self._agents.items())

    def get_reward(self, physics):
        x = physics.state()
        return np.array([agent_reward(x, i) for i in range(1, self.links + 1)],
                        dtype=np.float64)

    def reward_spec(self):
        return specs.BoundedArray((self.links,), np.float64, REWARD_OTHER, REWARD_GOAL,
                                  name="reward")


class Environment(control.Environment):
    """``control.Environment`` that takes its reward spec from the task."""

    def reward_spec(self):
        return self.task.reward_spec()


def load(task_name: str, *, seed=None, time_limit: float | None = None, params=None,
         x0=None, speed_max=None, angle_noise: float = 0.0, speed_noise: float = 0.0,
         perturbation=None, challenge=None, links: int | None = None,
         rule: str | None = None) -> Environment:
    """The ``task_name`` environment (one of :data:`TASKS`).

    ``links``: the number of links N, 2 (default; Table I) to 6; ``rule``: how the links
    beyond the second are made, ``'tapered'`` (default) or ``'copied'``
    (:func:`twolink.arm.parameters.links_parameters`); ``params``: the arm itself instead
    (:class:`~twolink.arm.parameters.ArmParameters` or
    :class:`~twolink.arm.parameters.LinksParameters`; ``links`` then defaults to its own).
    ``time_limit``: seconds per episode (default :func:`twolink.envs.core.horizon`: 5 s for
    two links, 8 s for more).
    ``x0``: ``'paper'`` ([-1, -3, 0, 0], the default for two links), ``'random'`` (angles
    uniform in [-pi, pi), at rest, as ``twolink rollout --x0 random``; drawn from ``seed``
    every episode; the default for N >= 3) or a state (2N,) used as given.
    ``speed_max``: the speed limit in rad/s (one value or one per link; default the arm's).
    ``angle_noise``, ``speed_noise``: std of Gaussian noise on the observations.
    ``perturbation``: relative parameter changes, a dict such as ``{'m2': 0.2}``
    (:func:`twolink.sim.perturbations.perturbed`), or a size s in [0, 1) for one random joint
    perturbation drawn from ``seed`` (:func:`twolink.sim.perturbations.random_perturbation`).
    ``challenge``: a level of :data:`twolink.sim.challenges.LEVELS` (``'easy'``, ``'medium'``,
    ``'hard'``) or a :class:`twolink.sim.challenges.Challenge`, instead of ``perturbation`` and
    the noise: one plant drawn from ``seed`` (every PHYSICAL parameter within +-spread,
    the torque limits changed), the torque reaching the arm ``action_delay`` samples late,
    and the observations noisy, dropped, stuck and ``observation_delay`` samples late.
    Noise, ``perturbation`` and ``challenge`` are two-link options.
    """
    check_task(task_name)
    params = arm(params, links=links, rule=rule)
    n = params.links
    check_two_link_options(n, perturbation=perturbation, challenge=challenge,
                           angle_noise=angle_noise, speed_noise=speed_noise)
    challenge = check_challenge(challenge, perturbation=perturbation,
                                angle_noise=angle_noise, speed_noise=speed_noise)
    time_limit = horizon(n) if time_limit is None else time_limit
    real(time_limit, "time_limit", 0, open_low=True, numpy=False, message=BAD_TIME_LIMIT)
    x0 = check_x0(default_x0(n) if x0 is None else x0, n)
    random = np.random.RandomState(check_seed(seed, high=2**32 - 1))
    p = (challenge.plant(random, params) if challenge is not None
         else perturbed_params(params, perturbation, random))
    if speed_max is not None:
        v = count_of(speed_max, "speed_max", n)
        if np.any(v <= 0):
            raise ValueError(f"speed_max must be positive (rad/s), got {v.tolist()}")
        p = (dataclasses.replace(p, dtheta1_max=float(v[0]), dtheta2_max=float(v[1]))
             if n == 2 else dataclasses.replace(p, speed_limits=tuple(float(s) for s in v)))
    physics = Physics.from_model(wrapper.MjModel(mjcf.build_model(p)))
    cls = Centralized if task_name == "centralized" else Decentralized
    task = cls(p, x0=x0, angle_noise=angle_noise, speed_noise=speed_noise, random=random,
               challenge=challenge, nominal=params if challenge is not None else None)
    return Environment(physics, task, time_limit=time_limit, control_timestep=TS)


def decentralized_action(agent2, agent1, observation) -> np.ndarray:
    """Joint action [tau1, tau2] of (18) on the two-link arm: agent 2 acts on its
    observation, then agent 1 on its observation and agent 2's tau2.
    ``agent2(o2) -> tau2``, ``agent1(o1, tau2) -> tau1``."""
    if set(observation) != {"agent1", "agent2"}:
        raise ValueError(f"decentralized_action is the two-link (18); these observations "
                         f"are {', '.join(observation)} (use policy_action)")
    tau2 = float(np.asarray(agent2(observation["agent2"])).reshape(()))
    tau1 = float(np.asarray(agent1(observation["agent1"], tau2)).reshape(()))
    return np.array([tau1, tau2])


def observed_links(observation) -> int:
    """The number of links N of the arm an observation of either task comes from."""
    if "state" in observation:
        return np.shape(observation["state"])[-1] // 2
    return sum(1 for key in observation if key.startswith("agent"))


def policy_action(policy, observation) -> np.ndarray:
    """Action [tau1 .. tauN] of a :class:`twolink.policy.fuzzy_policy.Policy` for an observation of
    either task; a ValueError for a policy of another number of links.

    On ``decentralized`` observations every agent of the policy reads only its own
    observation (the key named like the agent) and the actions of the agents before it
    (agent N first, as (18) orders agent 2 before agent 1).
    """
    n = observed_links(observation)
    check_policy_links(policy, n)
    if "state" in observation:
        return policy(observation["state"])
    names = observation_names(n)
    signals = {}
    for agent in policy.agents:
        if agent.name not in observation:
            raise ValueError(f"policy agent {agent.name!r} has no observation of its own here "
                             f"(observation keys: {', '.join(observation)})")
        seen = dict(zip(names[agent.name], observation[agent.name]), **signals)
        missing = [c for c in agent.inputs if c not in seen]
        if missing:
            raise ValueError(f"agent {agent.name} reads {missing}, which it does not observe")
        out = agent.act(np.stack([seen[c] for c in agent.inputs], -1))
        signals.update(zip(agent.outputs, out))
    return np.array([signals[f"tau{i}"] for i in range(1, n + 1)])
