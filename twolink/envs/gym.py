"""The arm as a Gymnasium environment: one arm, and many arms in one batched MuJoCo call.

``TwoLinkEnv`` is the ``centralized`` task of :mod:`twolink.envs.core` under Gymnasium's
API: observation the state [theta1, theta2, dtheta1, dtheta2] or, with
``observation="cos_sin"``, [cos theta1, sin theta1, cos theta2, sin theta2, dtheta1,
dtheta2]; action the torques [tau1, tau2] in a Box of +-tau_max, with
``actions="normalized"`` a float32 Box [-1, 1]^2 scaled to +-tau_max (for deep RL), or
with ``actions="discrete"`` the index of one of the 9 joint actions of (16); reward (15)
on the state reached, or with ``reward="shaped"`` the dense
:func:`twolink.envs.core.shaped_reward` (0 in the goal band, in [-1, 0) outside; (15)
stays the evaluation metric). Episodes never terminate; they are truncated at the time
limit (default 5 s = 100 steps of Ts = 0.05 s), and the truncation step's info holds
``is_success``: whether the arm settled by :func:`twolink.sim.metrics.success` (inside
the goal band at every sample from 1 s before the end on). Every step is one sample
period of the ``mujoco`` plant (:class:`twolink.sim.plants.MujocoPlant`), so a policy
driven through the environment retraces ``rollout(policy, MujocoPlant(), x0)`` and the
dm_env environment bit for bit.

Observation bounds are true: the plant wraps angles to [-pi, pi) and saturates speeds at
+-speed_max at the end of every sample period, so the Box declares angles [-pi, pi],
speeds +-speed_max and cos/sin [-1, 1]; an x0 given is wrapped the same way and refused
(ValueError) with a speed beyond speed_max, so the first observation lies inside too.
With observation noise (``angle_noise``, ``speed_noise`` or a noisy ``challenge``) the
noisy components are declared unbounded: Gaussian noise can carry a reading past any
bound.

``TwoLinkVectorEnv`` is a ``gymnasium.vector.VectorEnv`` over many such arms: one
``mujoco.rollout`` call per Ts for all of them, next-step autoreset (Gymnasium's
default), each arm with its own generator, so it equals as many single environments bit
for bit. Both share :class:`twolink.envs.gym_arms.Arms`, the batched episode logic. For
Stable-Baselines3, :mod:`twolink.envs.sb3` has a ``VecEnv`` over the same batched core
with SB3's same-step autoreset.

Arms of N links (``links=3`` .. 6, ``rule`` ``'tapered'`` | ``'copied'``):
observation [theta1 .. thetaN, dtheta1 .. dthetaN] or [cos theta1, sin theta1, ..,
cos thetaN, sin thetaN, dtheta1 .. dthetaN], action [tau1 .. tauN] (a Box) or the index
of one of the 3^N joint actions, reward (15) over all links; episodes last 8 s
(:func:`twolink.envs.core.horizon`) and start from random angles at rest by default.
Perturbations, challenges and observation noise are two-link options; ``delay`` works
for any N.

``import twolink`` registers ``twolink/TwoLink-v0`` and ``twolink/TwoLinkDiscrete-v0``
(:mod:`twolink.envs.registration`, with the vector environment as their
``vector_entry_point``); Gymnasium 1.4 loads no plugins by itself, so import twolink
first, or name the package in the id: ``gymnasium.make("twolink:twolink/TwoLink-v0")``.
"""
from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from twolink.arm.parameters import TS
from twolink.envs.core import check_policy_links, check_reset_options
from twolink.envs.gym_arms import OBSERVATIONS, Arms
from twolink.envs.registration import DISCRETE_ID, ENV_ID, register  # noqa: F401 (the ids)
from twolink.sim.plants import MujocoPlant
from twolink.validate import MAX_SEED, choice, is_whole, pixels, whole
from twolink.validate import seed as check_seed

#: Most arms one vector environment steps (a batch of this size is a few hundred MB of
#: states and observations at most; more would be a typing slip, not a learner's need).
MAX_ENVS = 100_000
#: Keys ``reset(options=...)`` accepts (the vector environment also ``reset_mask``).
RESET_OPTIONS = ("x0",)


def policy_action(policy, observation, *, features: str = "state") -> np.ndarray:
    """Torques [tau1 .. tauN] of a :class:`twolink.policy.fuzzy_policy.Policy` for an observation of
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


class TwoLinkEnv(gymnasium.Env):
    """The arm, ``centralized`` task, under Gymnasium's API (see the module docstring).

    Options (keyword-only): ``links`` (2, the default, to 6) and ``rule`` (``'tapered'``
    | ``'copied'``, :func:`twolink.arm.parameters.links_parameters`) or ``params`` (the nominal arm,
    Table I by default, whose torque limits bound the actions; an
    :class:`~twolink.arm.parameters.ArmParameters` or a
    :class:`~twolink.arm.parameters.LinksParameters`); ``observation`` ``'state'`` |
    ``'cos_sin'``; ``actions`` ``'box'`` | ``'normalized'`` | ``'discrete'``; ``reward``
    ``'paper'`` ((15), the default) | ``'shaped'``; ``x0`` ``'paper'`` (two links; the
    default there) | ``'random'`` (the default for N >= 3) | a state (2N,), the default
    of every episode (``reset(options={'x0': ...})`` overrides it once; angles wrapped to
    [-pi, pi), speeds at most the arm's limit); ``time_limit``
    (s; default :func:`twolink.envs.core.horizon`, 5 s for two links, 8 s beyond);
    ``perturbation`` a dict of relative changes (``{'m2': 0.2}``) or a size s for a new
    random joint change of every Table I constant within +-s each episode;
    ``angle_noise``, ``speed_noise`` (std of Gaussian observation noise; rewards use the
    true state); ``delay`` (sample periods before a torque reaches the arm; zero torque
    until then); ``challenge`` a level of :data:`twolink.sim.challenges.LEVELS` (``'easy'``,
    ``'medium'``, ``'hard'``) or a :class:`twolink.sim.challenges.Challenge`: a new plant
    every episode, its delays, noise and dropped/stuck readings, instead of
    ``perturbation``, the noise and ``delay``; ``render_mode`` ``'rgb_array'`` (frames of
    :class:`twolink.viz.render.Renderer`, whose GL context is released after every frame
    and freed at ``close`` or at the latest at interpreter exit).

    The truncation step's info is ``{'is_success': bool}`` (settled by the success rule);
    other steps' infos are empty. Observation bounds: see the module docstring (unbounded
    angles and speeds with observation noise).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": round(1 / TS)}

    def __init__(self, *, task: str = "centralized", observation: str = "state",
                 actions: str = "box", x0=None, time_limit: float | None = None,
                 params=None, perturbation=None,
                 angle_noise: float = 0.0, speed_noise: float = 0.0, delay: int = 0,
                 challenge=None, render_mode: str | None = None, render_size=(320, 240),
                 links: int | None = None, rule: str | None = None,
                 reward: str = "paper"):
        _check_task(task)
        if render_mode is not None:
            choice(render_mode, "render_mode", self.metadata["render_modes"])
        self._render_size = _check_size(render_size)
        self._options = dict(params=params, observation=observation, actions=actions, x0=x0,
                             time_limit=time_limit, perturbation=perturbation,
                             angle_noise=angle_noise, speed_noise=speed_noise, delay=delay,
                             nthread=1, challenge=challenge, links=links, rule=rule,
                             reward=reward)
        self._arms = Arms(1, **self._options)
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

    def _live(self) -> Arms:
        if self._arms is None:
            raise RuntimeError("the environment is closed")
        return self._arms

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        options = check_reset_options(options, RESET_OPTIONS)
        if self._arms is None:                 # closed: reset opens it again, as Gymnasium allows
            self._arms = Arms(1, **self._options)
        arms = self._arms
        x0 = arms.check_x0_option(options["x0"])[0] if "x0" in options else arms.x0
        super().reset(seed=check_seed(seed))
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
        arms.commit(x)
        info = {"is_success": bool(arms.settled([0])[0])} if truncated[0] else {}
        return arms.observe([0])[0], float(r[0]), False, bool(truncated[0]), info

    def render(self):
        if self.render_mode is None:
            return None
        arms = self._live()
        from twolink.viz.render import Renderer

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
        """Free the renderer and the plant; ``step`` and ``render`` refuse until the next
        ``reset``, which opens them again (Gymnasium allows an environment to be reset after
        ``close``; Stable-Baselines3's ``check_env`` does so)."""
        self._started = False
        self._close_renderer()
        if self._arms is not None:
            self._arms.close()
            self._arms = None


class TwoLinkVectorEnv(VectorEnv):
    """``num_envs`` arms stepped together: one ``mujoco.rollout`` call per Ts for all.

    Same options as :class:`TwoLinkEnv` (no rendering), ``nthread`` for MuJoCo's thread
    pool (default: one per core).

    Next-step autoreset (Gymnasium's default): the step after an arm's truncation resets
    it and ignores its action. That autoreset step returns the new episode's first
    observation, terminated and truncated False, and the reward's lowest value
    (:data:`twolink.envs.core.REWARD_FLOOR`: -0.5 under (15), -1 shaped), never the goal
    reward 0, which a sum or a count of goal rewards could otherwise take it for; its infos
    mark it, ``infos['autoreset']`` True where ``infos['_autoreset']``. Learners mask
    those steps out (the transition from a final observation to a first one is no step of
    the arm); Stable-Baselines3's same-step autoreset never shows them
    (:mod:`twolink.envs.sb3`). The truncation step's infos hold ``is_success`` (with its
    mask ``_is_success``, True for the arms truncated), as :class:`TwoLinkEnv`'s.
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
                 rule: str | None = None, reward: str = "paper"):
        _check_task(task)
        whole(num_envs, "num_envs", 1, MAX_ENVS)
        if render_mode is not None:
            raise ValueError("the vector environment does not render; render single "
                             "TwoLinkEnv environments")
        self.num_envs = int(num_envs)
        self._arms = Arms(self.num_envs, params=params, observation=observation,
                          actions=actions, x0=x0, time_limit=time_limit,
                          perturbation=perturbation, angle_noise=angle_noise,
                          speed_noise=speed_noise, delay=delay, nthread=nthread,
                          challenge=challenge, links=links, rule=rule, reward=reward)
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

    def _live(self) -> Arms:
        if self._arms is None:
            raise RuntimeError("the vector environment is closed")
        return self._arms

    def _seeds(self, seed) -> list:
        n = self.num_envs
        if seed is None:
            return [None] * n
        if is_whole(seed):
            return [check_seed(seed, high=MAX_SEED - n) + i for i in range(n)]
        if not isinstance(seed, (list, tuple, np.ndarray)):
            raise TypeError(f"seed must be an int, None or a list of {n} seeds, got {seed!r}")
        seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"seed must be an int, None or a list of {n} seeds, got {len(seeds)}")
        return [check_seed(s, f"seed[{i}]") for i, s in enumerate(seeds)]

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
        arms.commit(x)
        infos = {}
        if done.any():
            rows = np.flatnonzero(done)
            arms.reset_rows(rows, [arms.rngs[i] for i in rows], [arms.x0] * len(rows))
            r[rows], truncated[rows] = arms.floor(), False
            infos["autoreset"] = done.copy()
            infos["_autoreset"] = done.copy()
        if truncated.any():
            infos["is_success"] = truncated & arms.settled(np.arange(self.num_envs))
            infos["_is_success"] = truncated.copy()
        self._autoreset = truncated.copy()
        self._obs = arms.observe(np.arange(self.num_envs))
        return self._obs.copy(), r, np.zeros(self.num_envs, dtype=bool), truncated, infos

    def close_extras(self, **kwargs):
        """Free the plant (MuJoCo's thread pool)."""
        if self._arms is not None:
            self._arms.close()
            self._arms = None


def _check_task(task) -> None:
    if task != "centralized":
        raise ValueError(f"the Gymnasium environment has the 'centralized' task only, got "
                         f"{task!r}; the two agents of (18) are in twolink.envs.pettingzoo")


def _check_size(size) -> tuple[int, int]:
    """``render_size`` (width, height) as two ints, each from 1 to
    :data:`twolink.viz.video.MAX_SIZE` pixels: a TypeError for something else than two
    whole numbers, a ValueError for a size out of range, both naming render_size."""
    from twolink.viz.video import MAX_SIZE

    if isinstance(size, (str, bytes)) or not hasattr(size, "__len__") or len(size) != 2:
        raise TypeError(f"render_size must be (width, height), got {size!r}")
    return tuple(pixels(v, f"render_size {name}", MAX_SIZE)
                 for v, name in zip(size, ("width", "height")))


register()
