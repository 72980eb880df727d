"""The batched episode core of the Gymnasium environments of :mod:`twolink.envs.gym`.

:class:`Arms` keeps N arms under one :class:`twolink.sim.plants.MujocoPlant` (one
``mujoco.rollout`` call per Ts): their options and spaces, the checks of actions and
x0, resets, observations and steps; :func:`joint_actions` are the discrete joint actions
they use, and :func:`features` (re-exported from :mod:`twolink.arm.observations`) their
observations.
"""
from __future__ import annotations

import itertools

import numpy as np
from gymnasium import spaces

from twolink.arm.observations import OBSERVATIONS, features
from twolink.arm.parameters import SUCCESS_MARGIN, TS, ArmParameters, LinksParameters
from twolink.arm.task import action_levels, in_goal_band
from twolink.synthesis.problems import centralized_actions
from twolink.envs.core import (
    BAD_TIME_LIMIT,
    REWARD_FLOOR,
    arm,
    check_action,
    check_challenge,
    check_reward,
    check_two_link_options,
    check_x0,
    check_x0_speeds,
    default_x0,
    horizon,
    initial_state,
    perturbed_params,
    reward_of,
    state_bounds,
    wrap_angles,
)
from twolink.envs.starts import check_slow_starts
from twolink.sim.challenges import is_mix, mix
from twolink.sim.perturbations import ActuationDelay, Sensors
from twolink.sim.plants import ModelPlant, MujocoPlant, check_states
from twolink.validate import choice, is_real, is_whole, numbers, real, real_array

#: The plants the arms may step on: MuJoCo (one ``mujoco.rollout`` call per Ts) or the
#: full model (6)-(9) (N links: the rigid-body model of all N) integrated by numpy, batched.
ENV_PLANTS = ("mujoco", "full")
#: ``'box'``: torques in +-tau_max (float64); ``'discrete'``: the 3^N joint actions;
#: ``'normalized'``: a float32 Box [-1, 1]^N scaled to +-tau_max (what deep RL libraries
#: expect; Stable-Baselines3's checker warns about any other Box).
ACTIONS = ("box", "discrete", "normalized")


def _check_steps(time_limit) -> int:
    seconds = real(time_limit, "time_limit", 0, open_low=True, numpy=False,
                   message=BAD_TIME_LIMIT)
    return max(1, int(round(seconds / TS)))



def _check_x0(x0, speed_max, links: int = 2):
    """``check_x0`` (angles wrapped to [-pi, pi)) plus the arm's speed limit, so a bad x0
    fails at construction or reset, and a first observation lies in the declared space."""
    x0 = check_x0(x0, links)
    if not isinstance(x0, str):
        check_x0_speeds(x0, speed_max)
    return x0


def joint_actions(params) -> np.ndarray:
    """The discrete joint actions: every combination of the levels {-tau_max, 0, tau_max}
    of the links, the last link varying fastest, shape (3^N, N); for two links the 9 of
    (16) (:func:`twolink.synthesis.problems.centralized_actions`)."""
    if params.links == 2:
        return centralized_actions(params)
    return np.array(list(itertools.product(*(action_levels(t) for t in params.tau_max))))


def _hold(u):
    return np.array(u, dtype=np.float64)     # a copy: the delay keeps it


class Arms:
    """N arms under one :class:`MujocoPlant` (one ``mujoco.rollout`` call per Ts; or, with
    ``plant='full'``, the numpy :class:`ModelPlant` of the full model, a fixed plant only):
    states, per-arm generators, step counts, and the challenges of
    :mod:`twolink.sim.perturbations`.

    Each arm draws from its own generator, in the order: random plant (a perturbation
    size or a challenge's spread), x0 (``'random'``), then at every observation its noise
    and its reading faults (:class:`twolink.sim.perturbations.Sensors`); so an arm's episode
    never depends on the arms beside it.
    """

    def __init__(self, rows: int, *, params, observation: str, actions: str,
                 x0, time_limit, perturbation, angle_noise, speed_noise, delay,
                 nthread, challenge=None, links=None, rule=None, reward="paper",
                 plant="mujoco"):
        if params is not None and not isinstance(params, (ArmParameters, LinksParameters)):
            raise ValueError(f"params must be an ArmParameters or a LinksParameters, got "
                             f"{type(params).__name__}")
        params = arm(params, links=links, rule=rule)
        self.rows = rows
        self.params = params
        self.links = n = params.links
        check_two_link_options(n, perturbation=perturbation, challenge=challenge,
                               angle_noise=angle_noise, speed_noise=speed_noise)
        self.observation = choice(observation, "observation", OBSERVATIONS)
        self.actions = choice(actions, "actions", ACTIONS)
        self.reward = check_reward(reward)
        self.steps = _check_steps(horizon(n) if time_limit is None else time_limit)
        size = perturbation is not None and not isinstance(perturbation, dict)
        # Checks a dict or a size now (a size is drawn anew every episode).
        fixed = perturbed_params(params, perturbation, np.random.default_rng(0))
        # Where the plant saturates speeds: Table I's limits (a size or a challenge never
        # changes them; a dict of changes may).
        self.speed_max = np.maximum(params.speed_max, fixed.speed_max)
        self.x0 = _check_x0(default_x0(n) if x0 is None else x0, self.speed_max, n)
        check_slow_starts(self.x0, params)
        for name, value in (("angle_noise", angle_noise), ("speed_noise", speed_noise),
                            ("delay", delay)):
            if not is_real(value):
                raise ValueError(f"{name} must be one number, got {value!r}")
        mixed = mix(challenge) if is_mix(challenge) else None
        self.challenge = mixed or check_challenge(challenge, perturbation=perturbation,
                                                  angle_noise=angle_noise,
                                                  speed_noise=speed_noise, delay=delay)
        if mixed is not None:
            check_challenge(mixed.levels[0].name, perturbation=perturbation,
                            angle_noise=angle_noise, speed_noise=speed_noise, delay=delay)
            if rows < len(mixed.levels):
                raise ValueError(f"a mix of {len(mixed.levels)} levels ({mixed.name}) needs "
                                 f"at least as many arms, got {rows}")
            size = mixed.perturbs_plant()
            self._draw = lambda rng, i: mixed.level(i).plant(rng, params)
            self.sensors = mixed.sensors(rngs=[None] * rows)
            delay = mixed.action_delays(rows)
        elif self.challenge is not None:
            ch = self.challenge
            size = ch.perturbs_plant()          # a new plant every episode
            self._draw = lambda rng, i: ch.plant(rng, params)
            self.sensors = ch.sensors(rngs=[None] * rows)
            delay = ch.action_delay
        else:
            self._draw = lambda rng, i: perturbed_params(params, perturbation, rng)
            self.sensors = Sensors(float(angle_noise), float(speed_noise), rngs=[None] * rows)
        self._size = size
        self._noisy = self.sensors.noisy
        self._delay = ActuationDelay(_hold, delay)                     # checks the delay
        self.table = joint_actions(params)      # the controller's levels, not the plant's
        self.plant_name = choice(plant, "plant", ENV_PLANTS)
        if self.plant_name == "full":
            if size:
                raise ValueError("plant='full' steps one fixed plant; a perturbation size or a "
                                 "challenge draws a new plant per episode (use plant='mujoco')")
            self.plant = ModelPlant("full", fixed)
        else:
            self.plant = MujocoPlant([params] * rows if size else fixed, nthread=nthread)
        self.rngs: list = [None] * rows
        self.x = np.zeros((rows, 2 * n))
        self.k = np.zeros(rows, dtype=int)
        # The last sample k at which each arm was outside the goal band (-1: never).
        self.last_out = np.full(rows, -1)

    # -------------------------------------------------------------- spaces
    def action_space(self) -> spaces.Space:
        if self.actions == "discrete":
            return spaces.Discrete(len(self.table))
        if self.actions == "normalized":
            return spaces.Box(-1.0, 1.0, (self.links,), np.float32)
        t = self.params.tau_max
        return spaces.Box(-t, t, (self.links,), np.float64)

    def observation_space(self) -> spaces.Space:
        """The true state's bounds (:func:`twolink.envs.core.state_bounds`): angles in
        [-pi, pi] and speeds in +-speed_max (the plant wraps and saturates them at the end
        of every sample period; x0 is wrapped and held to the limit), cos/sin in [-1, 1];
        the angles and speeds unbounded where observation noise may leave those bounds."""
        n = self.links
        bound = state_bounds(self.speed_max)
        if self._noisy:
            bound[:] = np.inf
        high = bound if self.observation == "state" else np.concatenate(
            [np.ones(2 * n), bound[n:]])
        return spaces.Box(-high, high, (len(high),), np.float64)

    # -------------------------------------------------------------- checks
    def torques(self, action, *, single: bool = False) -> np.ndarray:
        """Checked torques (rows, N) for the actions of all arms (``single``: the one
        action of a one-arm environment); a ValueError otherwise (for a discrete action
        of the wrong type, a TypeError)."""
        if self.actions == "discrete":
            return self.table[self._discrete(action, single)]
        a = real_array(action, "action", dtype=None, finite=False)
        t = self.params.tau_max
        unit = self.actions == "normalized"
        bound = np.ones_like(t) if unit else t
        a = check_action(a, bound)[None] if single else check_action(a, bound, rows=self.rows)
        return a * t if unit else a

    def _discrete(self, action, single: bool) -> np.ndarray:
        """The indices (rows,) of discrete actions into :attr:`table`: a TypeError naming
        the action unless whole numbers, a ValueError for another shape or an index out
        of [0, len(table) - 1] (an int beyond int64 included)."""
        top = len(self.table) - 1
        a = np.asarray(action)
        if a.dtype.kind == "O" and all(is_whole(v) for v in a.ravel().tolist()):
            bad = [v for v in a.ravel().tolist() if not 0 <= v <= top]   # beyond int64
            raise ValueError(f"action must be a discrete action index in [0, {top}], got "
                             f"{bad[0]}")
        if a.dtype.kind not in "iu":
            raise TypeError(f"action must be {'a whole number' if single else 'whole numbers'}"
                            f" (a discrete action index in [0, {top}]), got {action!r}")
        want = () if single else (self.rows,)
        if a.shape != want:
            raise ValueError(f"action must be {'one index' if single else 'one index per arm'}"
                             f" of shape {want}, got shape {a.shape}")
        if np.any((a < 0) | (a > top)):
            raise ValueError(f"action must be a discrete action index in [0, {top}], got "
                             f"{a.tolist()}")
        return np.reshape(a, (-1,))

    def check_x0_option(self, x0):
        """One x0 for all arms, or one per arm (rows, 2N); a list of per-arm x0 options."""
        n = self.links
        if isinstance(x0, str) or (not isinstance(x0, dict) and np.ndim(x0) == 1):
            x0 = _check_x0(x0, self.speed_max, n)
            check_slow_starts(x0, self.params)
            return [x0] * self.rows
        numbers(x0, "x0")                # a TypeError naming x0 for a dict, None, ...
        x0 = check_states(x0, what="x0", links=n)
        if x0.shape != (self.rows, 2 * n):
            raise ValueError(f"x0 must be one state ({2 * n},) or one per arm ({self.rows}, "
                             f"{2 * n}), got shape {x0.shape}")
        return list(wrap_angles(check_x0_speeds(x0, self.speed_max)))

    # -------------------------------------------------------------- episodes
    def reset_rows(self, rows, rngs, x0s) -> None:
        """Start new episodes of ``rows`` with generators ``rngs`` and x0 options ``x0s``
        (all checked)."""
        for i, rng, x0 in zip(rows, rngs, x0s):
            self.rngs[i] = rng
            self.sensors.set_generator(i, rng)
            if self._size:
                self.plant.set_row_params(i, self._draw(rng, i))
            self.x[i] = initial_state(x0, rng, self.links, self.params)
            self.k[i] = 0
            self.last_out[i] = -1 if in_goal_band(self.x[i]) else 0
        self._delay.restart(rows)
        self.sensors.restart(rows)

    def observe(self, rows) -> np.ndarray:
        """Observations of ``rows`` (noise and faults drawn from each row's generator,
        once; then the observation delay)."""
        return features(self.sensors(self.x[rows], rows=rows), self.observation)

    def step(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One sample period of every arm under checked torques ``tau``: the next states
        (not yet stored: :meth:`commit`), rewards (15) or shaped, and truncation flags."""
        x = self.plant.step(self.x, self._delay(tau))
        return x, reward_of(x, self.reward), self.k + 1 >= self.steps

    def commit(self, x: np.ndarray) -> None:
        """Store the states a :meth:`step` reached: one more sample for every arm."""
        self.x[:], self.k[:] = x, self.k + 1
        out = ~in_goal_band(x)
        self.last_out[out] = self.k[out]

    def settled(self, rows) -> np.ndarray:
        """Whether the episodes of ``rows`` (at their time limit) succeeded by
        :func:`twolink.sim.metrics.success`: settled in the goal band no later than
        SUCCESS_MARGIN (1 s) before the end, i.e. inside it at every sample from then on."""
        settle = (self.last_out[rows] + 1).astype(float) * TS
        return settle <= self.steps * TS - SUCCESS_MARGIN + 1e-9

    def floor(self) -> float:
        """The reward of an autoreset step: the reward's lowest value, never a goal."""
        return REWARD_FLOOR[self.reward]

    def close(self) -> None:
        self.plant.close()
