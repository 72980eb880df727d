"""The arm as a Gymnasium environment: one arm, and many arms in one batched MuJoCo call.

``TwoLinkEnv`` is the ``centralized`` task of :mod:`twolink.tasks` under Gymnasium's
API: observation the state [theta1, theta2, dtheta1, dtheta2] (angles as given) or, with
``observation="cos_sin"``, [cos theta1, sin theta1, cos theta2, sin theta2, dtheta1,
dtheta2]; action the torques [tau1, tau2] in a Box of +-tau_max, or with
``actions="discrete"`` the index of one of the 9 joint actions of (16); reward (15) on
the state reached. Episodes never terminate; they are truncated at the time limit
(default 5 s = 100 steps of Ts = 0.05 s). Every step is one sample period of the
``mujoco`` plant (:class:`twolink.plants.MujocoPlant`), so a policy driven through the
environment retraces ``rollout(policy, MujocoPlant(), x0)`` and the dm_env environment
bit for bit.

``TwoLinkVectorEnv`` is a ``gymnasium.vector.VectorEnv`` over many such arms: one
``mujoco.rollout`` call per Ts for all of them, next-step autoreset (Gymnasium's
default), each arm with its own generator, so it equals as many single environments bit
for bit. Both share :class:`_Arms`, the batched episode logic.

Arms of N links (``links=3`` .. 6, ``rule`` ``'tapered'`` | ``'copied'``; issue 11):
observation [theta1 .. thetaN, dtheta1 .. dthetaN] or [cos theta1, sin theta1, ..,
cos thetaN, sin thetaN, dtheta1 .. dthetaN], action [tau1 .. tauN] (a Box) or the index
of one of the 3^N joint actions, reward (15) over all links; episodes last 8 s
(:func:`twolink.tasks.horizon`) and start from random angles at rest by default.
Perturbations, challenges and observation noise are two-link options; ``delay`` works
for any N.

Importing this module registers ``twolink/TwoLink-v0`` and ``twolink/TwoLinkDiscrete-v0``
(with the vector environment as their ``vector_entry_point``). Gymnasium 1.4 loads no
plugins by itself, so import it first, or name it in the id:
``gymnasium.make("twolink.gym_env:twolink/TwoLink-v0")``.
"""
from __future__ import annotations

import itertools
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from twolink.parameters import TS, ArmParameters, ChainParameters
from twolink.perturbations import ActuationDelay, Sensors
from twolink.plants import MAX_ANGLE, SPEED_BOUND, MujocoPlant, check_states
from twolink.reward import centralized_reward
from twolink.synthesis import _levels, centralized_actions
from twolink.tasks import (arm, check_action, check_challenge, check_policy_links,
                           check_reset_options, check_two_link_options, check_x0,
                           default_x0, horizon, initial_state, observe, perturbed_params)

ENV_ID = "twolink/TwoLink-v0"
#: Most arms one vector environment steps (a batch of this size is a few hundred MB of
#: states and observations at most; more would be a typing slip, not a learner's need).
MAX_ENVS = 100_000
DISCRETE_ID = "twolink/TwoLinkDiscrete-v0"
OBSERVATIONS = ("state", "cos_sin")
ACTIONS = ("box", "discrete")
#: Keys ``reset(options=...)`` accepts (the vector environment also ``reset_mask``).
RESET_OPTIONS = ("x0",)


def _check_choice(value, choices, what: str):
    if value not in choices:
        raise ValueError(f"{what} must be one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def _check_steps(time_limit) -> int:
    if isinstance(time_limit, bool) or not isinstance(time_limit, (int, float)) \
            or not np.isfinite(time_limit) or time_limit <= 0:
        raise ValueError(f"time_limit must be a positive number of seconds, got {time_limit!r}")
    return max(1, int(round(time_limit / TS)))



def _check_x0(x0, speed_max, links: int = 2):
    """``check_x0`` plus the plant's bounds, so a bad x0 fails at reset, not at a step."""
    x0 = check_x0(x0, links)
    if not isinstance(x0, str):
        check_states(x0, what="x0", speed_max=speed_max, links=links)
    return x0


def joint_actions(params) -> np.ndarray:
    """The discrete joint actions: every combination of the levels {-tau_max, 0, tau_max}
    of the links, the last link varying fastest, shape (3^N, N); for two links the 9 of
    (16) (:func:`twolink.synthesis.centralized_actions`)."""
    if params.links == 2:
        return centralized_actions(params)
    return np.array(list(itertools.product(*(_levels(t) for t in params.tau_max))))


def _real(action, what: str = "action") -> np.ndarray:
    a = np.asarray(action)
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{what} must hold real numbers, got dtype {a.dtype}")
    return a


def _hold(u):
    return np.array(u, dtype=np.float64)     # a copy: the delay keeps it


def features(x: np.ndarray, observation: str = "state") -> np.ndarray:
    """The observation of (measured) states x (..., 2N): ``'state'`` as given, or
    ``'cos_sin'`` = [cos theta1, sin theta1, .., cos thetaN, sin thetaN, dtheta1 ..
    dthetaN] (for two links [cos theta1, sin theta1, cos theta2, sin theta2, dtheta1,
    dtheta2])."""
    if observation == "state":
        return observe(x, "state")
    x = np.asarray(x)
    n = x.shape[-1] // 2
    trig = [f(x[..., k]) for k in range(n) for f in (np.cos, np.sin)]
    return np.stack(trig + [x[..., n + k] for k in range(n)], -1)


def policy_action(policy, observation, *, features: str = "state") -> np.ndarray:
    """Torques [tau1 .. tauN] of a :class:`twolink.policy.Policy` for an observation of
    the Box environments (one (d,) or a batch (B, d) from the vector environment); a
    ValueError for a policy of another number of links than the observation's."""
    obs = np.asarray(observation, dtype=float)
    if features not in OBSERVATIONS:
        raise ValueError(f"features must be 'state' or 'cos_sin', got {features!r}")
    per_link = 2 if features == "state" else 3
    d = obs.shape[-1] if obs.ndim else 0
    if d % per_link or not 2 <= d // per_link:
        raise ValueError(f"a {features!r} observation has {per_link} numbers per link, "
                         f"got shape {obs.shape}")
    n = d // per_link
    check_policy_links(policy, n)
    if features == "state":
        return policy(obs)
    th = [np.arctan2(obs[..., 2 * k + 1], obs[..., 2 * k]) for k in range(n)]
    return policy(np.stack(th + [obs[..., 2 * n + k] for k in range(n)], -1))


class _Arms:
    """N arms under one :class:`MujocoPlant` (one ``mujoco.rollout`` call per Ts): states,
    per-arm generators, step counts, and the challenges of :mod:`twolink.perturbations`.

    Each arm draws from its own generator, in the order: random plant (a perturbation
    size or a challenge's spread), x0 (``'random'``), then at every observation its noise
    and its reading faults (:class:`twolink.perturbations.Sensors`); so an arm's episode
    never depends on the arms beside it.
    """

    def __init__(self, rows: int, *, params, observation: str, actions: str,
                 x0, time_limit, perturbation, angle_noise, speed_noise, delay,
                 nthread, challenge=None, links=None, rule=None):
        if params is not None and not isinstance(params, (ArmParameters, ChainParameters)):
            raise ValueError(f"params must be an ArmParameters or a ChainParameters, got "
                             f"{type(params).__name__}")
        params = arm(params, links=links, rule=rule)
        self.rows = rows
        self.params = params
        self.links = n = params.links
        check_two_link_options(n, perturbation=perturbation, challenge=challenge,
                               angle_noise=angle_noise, speed_noise=speed_noise)
        self.observation = _check_choice(observation, OBSERVATIONS, "observation")
        self.actions = _check_choice(actions, ACTIONS, "actions")
        self.x0 = _check_x0(default_x0(n) if x0 is None else x0, params.speed_max, n)
        self.steps = _check_steps(horizon(n) if time_limit is None else time_limit)
        size = perturbation is not None and not isinstance(perturbation, dict)
        # Checks a dict or a size now (a size is drawn anew every episode).
        fixed = perturbed_params(params, perturbation, np.random.default_rng(0))
        for name, value in (("angle_noise", angle_noise), ("speed_noise", speed_noise),
                            ("delay", delay)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ValueError(f"{name} must be one number, got {value!r}")
        self.challenge = check_challenge(challenge, perturbation=perturbation,
                                          angle_noise=angle_noise, speed_noise=speed_noise,
                                          delay=delay)
        if self.challenge is not None:
            ch = self.challenge
            size = ch.perturbs_plant()          # a new plant every episode
            self._draw = lambda rng: ch.plant(rng, params)
            self.sensors = ch.sensors(rngs=[None] * rows)
            delay = ch.action_delay
        else:
            self._draw = lambda rng: perturbed_params(params, perturbation, rng)
            self.sensors = Sensors(float(angle_noise), float(speed_noise), rngs=[None] * rows)
        self._size = size
        self._noisy = self.sensors.noisy
        self._delay = ActuationDelay(_hold, delay)                     # checks the delay
        self.table = joint_actions(params)      # the controller's levels, not the plant's
        self.plant = MujocoPlant([params] * rows if size else fixed, nthread=nthread)
        self.rngs: list = [None] * rows
        self.x = np.zeros((rows, 2 * n))
        self.k = np.zeros(rows, dtype=int)

    # -------------------------------------------------------------- spaces
    def action_space(self) -> spaces.Space:
        if self.actions == "discrete":
            return spaces.Discrete(len(self.table))
        t = self.params.tau_max
        return spaces.Box(-t, t, (self.links,), np.float64)

    def observation_space(self) -> spaces.Space:
        """Bounds of the true state (x0's bounds; the plant keeps states inside them);
        unbounded where noise may leave them."""
        speed = SPEED_BOUND * self.params.speed_max
        n = self.links
        if self.observation == "state":
            high = np.array([MAX_ANGLE] * n + [*speed])
            if self._noisy:
                high[:] = np.inf
        else:
            high = np.array([1.0] * (2 * n) + [*speed])
            if self._noisy:
                high[2 * n:] = np.inf
        return spaces.Box(-high, high, (len(high),), np.float64)

    # -------------------------------------------------------------- checks
    def torques(self, action, *, single: bool = False) -> np.ndarray:
        """Checked torques (rows, N) for the actions of all arms (``single``: the one
        action of a one-arm environment); a ValueError otherwise."""
        a = _real(action)
        if self.actions == "box":
            if single:
                return check_action(a, self.params.tau_max)[None]
            return check_action(a, self.params.tau_max, rows=self.rows)
        want = () if single else (self.rows,)
        if a.shape != want or a.dtype.kind not in "iu":
            raise ValueError(f"a discrete action must be {'one whole number' if single else 'whole numbers'}"
                             f" of shape {want}, got dtype {a.dtype} and shape {a.shape}")
        if np.any((a < 0) | (a >= len(self.table))):
            raise ValueError(f"a discrete action must lie in [0, {len(self.table) - 1}], "
                             f"got {a.tolist()}")
        return self.table[np.reshape(a, (-1,))]

    def check_x0_option(self, x0):
        """One x0 for all arms, or one per arm (rows, 2N); a list of per-arm x0 options."""
        n = self.links
        if isinstance(x0, str) or np.ndim(x0) == 1:
            x0 = _check_x0(x0, self.params.speed_max, n)
            return [x0] * self.rows
        x0 = check_states(x0, what="x0", speed_max=self.params.speed_max, links=n)
        if x0.shape != (self.rows, 2 * n):
            raise ValueError(f"x0 must be one state ({2 * n},) or one per arm ({self.rows}, "
                             f"{2 * n}), got shape {x0.shape}")
        return list(x0.copy())

    # -------------------------------------------------------------- episodes
    def reset_rows(self, rows, rngs, x0s) -> None:
        """Start new episodes of ``rows`` with generators ``rngs`` and x0 options ``x0s``
        (all checked)."""
        for i, rng, x0 in zip(rows, rngs, x0s):
            self.rngs[i] = rng
            self.sensors.set_generator(i, rng)
            if self._size:
                self.plant.set_row_params(i, self._draw(rng))
            self.x[i] = initial_state(x0, rng, self.links)
            self.k[i] = 0
        self._delay.restart(rows)
        self.sensors.restart(rows)

    def observe(self, rows) -> np.ndarray:
        """Observations of ``rows`` (noise and faults drawn from each row's generator,
        once; then the observation delay)."""
        return features(self.sensors(self.x[rows], rows=rows), self.observation)

    def step(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One sample period of every arm under checked torques ``tau``: the next states
        (not yet stored), rewards (15) and truncation flags."""
        x = self.plant.step(self.x, self._delay(tau))
        return x, centralized_reward(x).astype(np.float64), self.k + 1 >= self.steps

    def close(self) -> None:
        self.plant.close()


class TwoLinkEnv(gymnasium.Env):
    """The arm, ``centralized`` task, under Gymnasium's API (see the module docstring).

    Options (keyword-only): ``links`` (2, the default, to 6) and ``rule`` (``'tapered'``
    | ``'copied'``, :func:`twolink.parameters.chain`) or ``params`` (the nominal arm,
    Table I by default, whose torque limits bound the actions; an
    :class:`~twolink.parameters.ArmParameters` or a
    :class:`~twolink.parameters.ChainParameters`); ``observation`` ``'state'`` |
    ``'cos_sin'``; ``actions`` ``'box'`` | ``'discrete'``; ``x0`` ``'paper'`` (two links; the
    default there) | ``'random'`` (the default for N >= 3) | a state (2N,), the default
    of every episode (``reset(options={'x0': ...})`` overrides it once); ``time_limit``
    (s; default :func:`twolink.tasks.horizon`, 5 s for two links, 8 s beyond);
    ``perturbation`` a dict of relative changes (``{'m2': 0.2}``) or a size s for a new
    random joint change of every Table I constant within +-s each episode;
    ``angle_noise``, ``speed_noise`` (std of Gaussian observation noise; rewards use the
    true state); ``delay`` (sample periods before a torque reaches the arm; zero torque
    until then); ``challenge`` a level of :data:`twolink.challenges.LEVELS` (``'easy'``,
    ``'medium'``, ``'hard'``) or a :class:`twolink.challenges.Challenge`: a new plant
    every episode, its delays, noise and dropped/stuck readings, instead of
    ``perturbation``, the noise and ``delay``; ``render_mode`` ``'rgb_array'`` (frames of :class:`twolink.render.Renderer`).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": round(1 / TS)}

    def __init__(self, *, task: str = "centralized", observation: str = "state",
                 actions: str = "box", x0=None, time_limit: float | None = None,
                 params=None, perturbation=None,
                 angle_noise: float = 0.0, speed_noise: float = 0.0, delay: int = 0,
                 challenge=None, render_mode: str | None = None, render_size=(320, 240),
                 links: int | None = None, rule: str | None = None):
        _check_task(task)
        if render_mode is not None:
            _check_choice(render_mode, self.metadata["render_modes"], "render_mode")
        self._render_size = _check_size(render_size)
        self._arms = _Arms(1, params=params, observation=observation, actions=actions, x0=x0,
                           time_limit=time_limit, perturbation=perturbation,
                           angle_noise=angle_noise, speed_noise=speed_noise, delay=delay,
                           nthread=1, challenge=challenge, links=links, rule=rule)
        self.links = self._arms.links
        self.render_mode = render_mode
        self.action_space = self._arms.action_space()
        self.observation_space = self._arms.observation_space()
        self._renderer = None
        self._started = False

    @property
    def state(self) -> np.ndarray:
        """The true state x (2N,) (a copy)."""
        return self._live().x[0].copy()

    @property
    def plant(self) -> MujocoPlant:
        return self._live().plant

    def _live(self) -> _Arms:
        if self._arms is None:
            raise RuntimeError("the environment is closed")
        return self._arms

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        arms = self._live()
        options = check_reset_options(options, RESET_OPTIONS)
        x0 = arms.check_x0_option(options["x0"])[0] if "x0" in options else arms.x0
        super().reset(seed=seed)
        arms.reset_rows([0], [self.np_random], [x0])
        self._started = True
        return arms.observe([0])[0], {}

    def step(self, action):
        arms = self._live()
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if arms.k[0] >= arms.steps:
            raise RuntimeError("the episode is over (truncated at the time limit): call reset()")
        tau = arms.torques(action, single=True)
        x, r, truncated = arms.step(tau)
        arms.x[:], arms.k[:] = x, arms.k + 1
        return arms.observe([0])[0], float(r[0]), False, bool(truncated[0]), {}

    def render(self):
        if self.render_mode is None:
            return None
        arms = self._live()
        from twolink.render import Renderer

        p = arms.plant.params[0] if arms.plant.per_row else arms.plant.params
        if self._renderer is None or self._renderer.params != p:
            self._close_renderer()
            w, h = self._render_size
            self._renderer = Renderer(width=w, height=h, overlay=False, params=p)
        return self._renderer.frame(arms.x[0])

    def _close_renderer(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def close(self):
        """Free the renderer and the plant; the environment cannot be used afterwards."""
        self._close_renderer()
        if self._arms is not None:
            self._arms.close()
            self._arms = None


class TwoLinkVectorEnv(VectorEnv):
    """``num_envs`` arms stepped together: one ``mujoco.rollout`` call per Ts for all.

    Same options as :class:`TwoLinkEnv` (no rendering), ``nthread`` for MuJoCo's thread
    pool (default: one per core). Next-step autoreset: the step after an arm's
    truncation resets it (reward 0, not truncated) and ignores its action.
    ``reset(seed=s)`` seeds arm i with s + i (as ``SyncVectorEnv`` does); ``seed`` may
    also be a list; ``options``: ``x0`` (one (2N,) or one per arm (num_envs, 2N)) and
    ``reset_mask`` (a bool array (num_envs,): reset only those arms).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, *, task: str = "centralized",
                 observation: str = "state", actions: str = "box", x0=None,
                 time_limit: float | None = None, params=None,
                 perturbation=None, angle_noise: float = 0.0, speed_noise: float = 0.0,
                 delay: int = 0, challenge=None, nthread: int | None = None,
                 render_mode: str | None = None, links: int | None = None,
                 rule: str | None = None):
        _check_task(task)
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) \
                or not 1 <= num_envs <= MAX_ENVS:
            raise ValueError(f"num_envs must be a whole number from 1 to {MAX_ENVS}, "
                             f"got {num_envs!r}")
        if render_mode is not None:
            raise ValueError("the vector environment does not render; render single "
                             "TwoLinkEnv environments")
        self.num_envs = int(num_envs)
        self._arms = _Arms(self.num_envs, params=params, observation=observation,
                           actions=actions, x0=x0, time_limit=time_limit,
                           perturbation=perturbation, angle_noise=angle_noise,
                           speed_noise=speed_noise, delay=delay, nthread=nthread,
                           challenge=challenge, links=links, rule=rule)
        self.links = self._arms.links
        self.single_action_space = self._arms.action_space()
        self.single_observation_space = self._arms.observation_space()
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.render_mode = None
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    @property
    def states(self) -> np.ndarray:
        """The true states (num_envs, 2N) (a copy)."""
        return self._live().x.copy()

    @property
    def plant(self) -> MujocoPlant:
        return self._live().plant

    def _live(self) -> _Arms:
        if self._arms is None:
            raise RuntimeError("the vector environment is closed")
        return self._arms

    def _seeds(self, seed) -> list:
        n = self.num_envs
        if seed is None:
            return [None] * n
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(n)]
        seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"seed must be an int, None or a list of {n} seeds, got {len(seeds)}")
        return seeds

    def reset(self, *, seed=None, options: dict[str, Any] | None = None):
        arms = self._live()
        options = check_reset_options(options, RESET_OPTIONS + ("reset_mask",))
        seeds = self._seeds(seed)
        mask = options.get("reset_mask")
        if mask is None:
            rows = np.arange(self.num_envs)
        else:
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_
                    and mask.shape == (self.num_envs,) and mask.any()):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape "
                                 f"({self.num_envs},) with at least one True, got {mask!r}")
            if not self._started and not mask.all():
                raise ValueError("the first reset must reset every arm (no reset_mask)")
            rows = np.flatnonzero(mask)
        x0s = arms.check_x0_option(options["x0"]) if "x0" in options \
            else [arms.x0] * self.num_envs
        rngs = [seeding.np_random(seeds[i])[0] if seeds[i] is not None or arms.rngs[i] is None
                else arms.rngs[i] for i in rows]
        super().reset(seed=seed if isinstance(seed, (int, np.integer)) else None)
        arms.reset_rows(rows, rngs, [x0s[i] for i in rows])
        self._autoreset[rows] = False
        self._started = True
        if mask is None:
            self._obs = arms.observe(rows)
        else:       # the other arms keep their last observation, as in SyncVectorEnv
            self._obs[rows] = arms.observe(rows)
        return self._obs.copy(), {}

    def step(self, actions):
        arms = self._live()
        if not self._started:
            raise RuntimeError("call reset() before step()")
        tau = arms.torques(actions)
        x, r, truncated = arms.step(tau)
        done = self._autoreset
        arms.x[:], arms.k[:] = x, arms.k + 1
        if done.any():
            rows = np.flatnonzero(done)
            arms.reset_rows(rows, [arms.rngs[i] for i in rows], [arms.x0] * len(rows))
            r[rows], truncated[rows] = 0.0, False
        self._autoreset = truncated.copy()
        self._obs = arms.observe(np.arange(self.num_envs))
        return self._obs.copy(), r, np.zeros(self.num_envs, dtype=bool), truncated, {}

    def close_extras(self, **kwargs):
        """Free the plant (MuJoCo's thread pool)."""
        if self._arms is not None:
            self._arms.close()
            self._arms = None


def _check_task(task) -> None:
    if task != "centralized":
        raise ValueError(f"the Gymnasium environment has the 'centralized' task only, got "
                         f"{task!r}; the two agents of (18) are in twolink.pettingzoo")


def _check_size(size) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ValueError(f"render_size must be (width, height), got {size!r}") from None
    if w < 1 or h < 1:
        raise ValueError(f"render_size must be positive, got {size!r}")
    return w, h


def register() -> None:
    """Register :data:`ENV_ID` and :data:`DISCRETE_ID` (done on import; idempotent)."""
    for env_id, kwargs in ((ENV_ID, {}), (DISCRETE_ID, {"actions": "discrete"})):
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=f"{__name__}:TwoLinkEnv",
                               vector_entry_point=f"{__name__}:TwoLinkVectorEnv",
                               kwargs=kwargs)


register()
