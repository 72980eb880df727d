"""The environments seen through run-time compensation (:mod:`twolink.sim.estimation`).

Wrappers whose observation is the compensated state estimate x^_{k+d} instead of the
reading: the observer's estimate of the measured state rolled over the commands already
in the pipeline, the state the action chosen now will act on. A policy that acts on this
observation is compensated as ``estimation.Compensator`` compensates it in a rollout.

* :class:`CompensatedObservation` wraps a Gymnasium :class:`twolink.envs.gym.TwoLinkEnv`
  (``observation='state'``, box or discrete actions);
* :class:`CompensatedVectorObservation` wraps :class:`twolink.envs.gym.TwoLinkVectorEnv`
  (next-step autoreset: an arm restarts its estimator with its new episode);
* :class:`CompensatedEnvironment` wraps the dm_env ``centralized`` task
  (:func:`twolink.envs.dm.load`), whose readings may be noisy but never late.

The estimator is not told the environment's settings: give it the environment's
``delay`` (and ``observation_delay``); ``observer`` for noisy readings. ``model`` and
``params`` are the prediction model (default the full model (6) with Table I, the
nominal arm the environments simulate).
"""
from __future__ import annotations

import collections

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorWrapper

from twolink.arm.parameters import TABLE_I, ArmParameters
from twolink.synthesis.problems import centralized_actions
from twolink.sim.estimation import StateEstimator

_STATE_SPACE = spaces.Box(-np.inf, np.inf, (4,), np.float64)


def _estimator(delay, observation_delay, observer, model, params, design) -> StateEstimator:
    return StateEstimator(model=model, params=TABLE_I if params is None else params,
                          delay=delay, observation_delay=observation_delay,
                          observer=observer, **design)


def _check_two_links(links) -> None:
    """The estimator predicts the two-link arm (6)/(11): a ValueError for another N."""
    if links != 2:
        raise ValueError(f"compensation (twolink.sim.estimation) predicts the two-link arm; the "
                         f"wrapped environment's arm has {links} links")


def _check_state_space(space, shape, what: str) -> None:
    if not isinstance(space, spaces.Box) or space.shape != shape:
        raise ValueError(f"{what} must observe the state (observation='state', a Box of "
                         f"shape {shape}), got {space}")


class _Torques:
    """Torques of an environment's actions: box actions as given, discrete ones through
    the 9 joint actions of (16) at the controller's torque limits."""

    def __init__(self, action_space, params: ArmParameters):
        self.table = centralized_actions(params) \
            if isinstance(action_space, (spaces.Discrete, spaces.MultiDiscrete)) else None

    def __call__(self, action) -> np.ndarray:
        a = np.asarray(action)
        return self.table[a] if self.table is not None else a.astype(float)


class CompensatedObservation(gymnasium.Wrapper):
    """A :class:`twolink.envs.gym.TwoLinkEnv` whose observation is the compensated state
    estimate x^_{k+d} (4,) (see the module docstring); actions and rewards unchanged."""

    def __init__(self, env: gymnasium.Env, *, delay: int = 0, observation_delay: int = 0,
                 observer: bool = True, model: str = "full",
                 params: ArmParameters | None = None, **design):
        super().__init__(env)
        _check_two_links(getattr(env.unwrapped, "links", 2))
        _check_state_space(env.observation_space, (4,), "the wrapped environment")
        self.estimator = _estimator(delay, observation_delay, observer, model, params, design)
        self._torques = _Torques(env.action_space, self.estimator.params)
        self.observation_space = _STATE_SPACE

    def reset(self, *, seed=None, options=None):
        y, info = self.env.reset(seed=seed, options=options)
        self.estimator.restart()
        return self.estimator.update(y), info

    def step(self, action):
        y, reward, terminated, truncated, info = self.env.step(action)
        self.estimator.record(self._torques(action))
        return self.estimator.update(y), reward, terminated, truncated, info


class CompensatedVectorObservation(VectorWrapper):
    """A :class:`twolink.envs.gym.TwoLinkVectorEnv` whose observations are the compensated
    estimates (num_envs, 4); an arm's estimator restarts with each of its episodes."""

    def __init__(self, env, *, delay: int = 0, observation_delay: int = 0,
                 observer: bool = True, model: str = "full",
                 params: ArmParameters | None = None, **design):
        super().__init__(env)
        _check_two_links(getattr(env.unwrapped, "links", 2))
        _check_state_space(env.single_observation_space, (4,), "the wrapped environment")
        self.estimator = _estimator(delay, observation_delay, observer, model, params, design)
        self._torques = _Torques(env.single_action_space, self.estimator.params)
        self.single_observation_space = _STATE_SPACE
        self.observation_space = gymnasium.vector.utils.batch_space(_STATE_SPACE, env.num_envs)
        self._autoreset = np.zeros(env.num_envs, dtype=bool)
        self._obs = None

    def reset(self, *, seed=None, options=None):
        y, info = self.env.reset(seed=seed, options=options)
        mask = (options or {}).get("reset_mask")
        rows = np.arange(self.num_envs) if mask is None else np.flatnonzero(mask)
        if self._obs is None or mask is None:
            self.estimator.restart()
            self._obs = self.estimator.update(y)
        else:                      # the other arms keep their estimates and pending readings
            self.estimator.restart(rows)
            self._obs[rows] = self.estimator.update(y[rows], rows)
        self._autoreset[rows] = False
        return self._obs.copy(), info

    def step(self, actions):
        y, reward, terminated, truncated, info = self.env.step(actions)
        self.estimator.record(self._torques(actions))
        self.estimator.restart(np.flatnonzero(self._autoreset))   # these arms were reset
        self._autoreset = np.asarray(terminated | truncated, dtype=bool).copy()
        self._obs = self.estimator.update(y)
        return self._obs.copy(), reward, terminated, truncated, info


class CompensatedEnvironment:
    """A dm_env environment of the ``centralized`` task whose ``'state'`` observation is
    the compensated estimate; everything else is the wrapped environment's."""

    def __init__(self, env, *, delay: int = 0, observer: bool = True, model: str = "full",
                 params: ArmParameters | None = None, **design):
        _check_two_links(getattr(getattr(env, "task", None), "links", 2))
        spec = env.observation_spec()
        if "state" not in spec or spec["state"].shape != (4,):
            raise ValueError("CompensatedEnvironment wraps the centralized task (an observation "
                             f"'state' of shape (4,)), got observations {list(spec)}")
        self.env = env
        self.estimator = _estimator(delay, 0, observer, model, params, design)

    def _seen(self, timestep):
        obs = collections.OrderedDict(timestep.observation)
        obs["state"] = self.estimator.update(obs["state"])
        return timestep._replace(observation=obs)

    def reset(self):
        self.estimator.restart()
        return self._seen(self.env.reset())

    def step(self, action):
        a = np.asarray(action)
        timestep = self.env.step(action)
        if timestep.first():                     # the episode ended: dm_env reset
            self.estimator.restart()
        else:
            self.estimator.record(np.clip(a.astype(float), -self.estimator.params.tau_max,
                                          self.estimator.params.tau_max))
        return self._seen(timestep)

    def __getattr__(self, name):                 # specs, physics, task, close
        return getattr(self.env, name)
