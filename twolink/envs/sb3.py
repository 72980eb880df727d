"""The arm as a Stable-Baselines3 ``VecEnv``: many arms, one ``mujoco.rollout`` call per Ts.

``TwoLinkSB3VecEnv(num_envs, **options)`` (or :func:`vec_env`) is a subclass of
``stable_baselines3.common.vec_env.VecEnv`` over :class:`twolink.envs.gym_arms.Arms`, the
batched episode core of the Gymnasium environments: the same options as
:class:`twolink.envs.gym.TwoLinkVectorEnv` (``observation``, ``actions`` ``'box'`` |
``'normalized'`` | ``'discrete'``, ``reward`` ``'paper'`` | ``'shaped'``, ``x0``,
``time_limit``, ``params``, ``perturbation``, the noise, ``delay``, ``challenge``,
``nthread``, ``links``, ``rule``), the same spaces, and arm i's episodes equal those of a
``TwoLinkEnv`` reset with seed s + i, bit for bit. ``plant='full'`` steps the arms on the
full model (6)-(9) (N links: the rigid-body model of all N) integrated by numpy instead of MuJoCo
(a fixed plant: no perturbation size or challenge).

SB3's conventions, not Gymnasium's vector ones:

* same-step autoreset: the step that reaches an arm's time limit returns ``done`` True
  and already the first observation of the arm's next episode; the last observation of
  the episode is ``infos[i]['terminal_observation']``, with
  ``infos[i]['TimeLimit.truncated']`` True (episodes are only ever truncated, so SB3
  bootstraps from it) and ``infos[i]['is_success']`` (settled by
  :func:`twolink.sim.metrics.success`: inside the goal band at every sample from 1 s
  before the end on; SB3 logs its rate as ``rollout/success_rate``). No step ever
  shows a reset transition, so no reset can pass for a goal reward.
* seeding: ``seed(s)`` (what SB3's ``seed=`` calls) seeds arm i with s + i at the next
  ``reset()``; ``set_options({'x0': ...})`` sets the next reset's initial states. Later
  episodes of an arm draw from its own generator.
* rewards float32, ``dones`` bool, observations float64 in the declared Box.

``get_attr``/``set_attr``/``env_method`` act on this one batched environment (there are
no sub-environments), the same value for every index. It does not render (render single
:class:`twolink.envs.gym.TwoLinkEnv` environments).

Stable-Baselines3 is an optional dependency: ``pip install 'twolink[rl]'``.
"""
from __future__ import annotations

try:
    from stable_baselines3.common.vec_env import VecEnv
except ImportError:
    raise ImportError("twolink.envs.sb3 needs Stable-Baselines3: "
                      "pip install 'twolink[rl]'") from None

import numpy as np
from gymnasium.utils import seeding

from twolink.envs.core import check_reset_options
from twolink.envs.gym import MAX_ENVS, RESET_OPTIONS
from twolink.envs.gym_arms import Arms
from twolink.validate import whole


class TwoLinkSB3VecEnv(VecEnv):
    """``num_envs`` arms as one Stable-Baselines3 ``VecEnv`` (see the module docstring)."""

    def __init__(self, num_envs: int = 1, *, observation: str = "state",
                 actions: str = "box", reward: str = "paper", x0=None,
                 time_limit: float | None = None, params=None, perturbation=None,
                 angle_noise: float = 0.0, speed_noise: float = 0.0, delay: int = 0,
                 challenge=None, nthread: int | None = None, links: int | None = None,
                 rule: str | None = None, plant: str = "mujoco"):
        whole(num_envs, "num_envs", 1, MAX_ENVS)
        self._arms = Arms(int(num_envs), params=params, observation=observation,
                          actions=actions, x0=x0, time_limit=time_limit,
                          perturbation=perturbation, angle_noise=angle_noise,
                          speed_noise=speed_noise, delay=delay, nthread=nthread,
                          challenge=challenge, links=links, rule=rule, reward=reward,
                          plant=plant)
        self.links = self._arms.links
        self.render_mode = None          # VecEnv.__init__ reads it through get_attr
        self._actions = None
        self._started = False
        super().__init__(int(num_envs), self._arms.observation_space(),
                         self._arms.action_space())

    # ------------------------------------------------------------------ state
    def _live(self) -> Arms:
        if self._arms is None:
            raise RuntimeError("the vector environment is closed")
        return self._arms

    @property
    def states(self) -> np.ndarray:
        """The true states (num_envs, 2N) (a copy)."""
        return self._live().x.copy()

    @property
    def plant(self):
        """The plant stepping every arm (:class:`twolink.sim.plants.MujocoPlant`, or the
        full model's :class:`twolink.sim.plants.ModelPlant` with ``plant='full'``)."""
        return self._live().plant

    # ------------------------------------------------------------------ the VecEnv API
    def reset(self) -> np.ndarray:
        """Start an episode on every arm: arm i seeded with ``seed(s)``'s s + i when a seed
        was set since the last reset (else it keeps drawing from its generator), from the
        ``x0`` of ``set_options`` when given (else the environment's)."""
        arms = self._live()
        x0s = []
        for i, options in enumerate(self._options):
            options = check_reset_options(options, RESET_OPTIONS)
            x0s.append(arms.check_x0_option(options["x0"])[0] if "x0" in options
                       else arms.x0)
        rngs = [seeding.np_random(s)[0] if s is not None or arms.rngs[i] is None
                else arms.rngs[i] for i, s in enumerate(self._seeds)]
        rows = np.arange(self.num_envs)
        arms.reset_rows(rows, rngs, x0s)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in rows]
        self._actions, self._started = None, True
        return arms.observe(rows)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        arms = self._live()
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if self._actions is None:
            raise RuntimeError("call step_async(actions) before step_wait()")
        actions, self._actions = self._actions, None
        x, reward, done = arms.step(arms.torques(actions))
        arms.commit(x)
        rows = np.arange(self.num_envs)
        obs = arms.observe(rows)
        infos = [{} for _ in rows]
        if done.any():
            ended = np.flatnonzero(done)
            settled = arms.settled(ended)
            for i, ok in zip(ended, settled):
                infos[i] = {"terminal_observation": obs[i].copy(),
                            "TimeLimit.truncated": True, "is_success": bool(ok)}
            arms.reset_rows(ended, [arms.rngs[i] for i in ended], [arms.x0] * len(ended))
            obs[ended] = arms.observe(ended)
        return obs, reward.astype(np.float32), done.copy(), infos

    def close(self) -> None:
        """Free the plant (MuJoCo's thread pool); idempotent."""
        if self._arms is not None:
            self._arms.close()
            self._arms = None

    def _count(self, indices) -> int:
        return len(list(self._get_indices(indices)))

    def get_attr(self, attr_name: str, indices=None) -> list:
        """This environment's ``attr_name``, once per index."""
        return [getattr(self, attr_name)] * self._count(indices)

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        """Set ``attr_name`` on this environment (all arms share it)."""
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        """Call this environment's method once; its result once per index."""
        out = getattr(self, method_name)(*method_args, **method_kwargs)
        return [out] * self._count(indices)

    def env_is_wrapped(self, wrapper_class, indices=None) -> list:
        """No arm is a wrapped Gymnasium environment."""
        return [False] * self._count(indices)


def vec_env(num_envs: int = 1, **options) -> TwoLinkSB3VecEnv:
    """``num_envs`` arms as a Stable-Baselines3 ``VecEnv`` (options: see
    :class:`TwoLinkSB3VecEnv`)."""
    return TwoLinkSB3VecEnv(num_envs, **options)
