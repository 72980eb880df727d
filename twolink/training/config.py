"""What one deep-RL training run is: :class:`TrainConfig`, checked whole before any work.

The agent sees and does what :data:`ENV` says (the options of
:class:`twolink.envs.sb3.TwoLinkSB3VecEnv`): the cos/sin observation (3N numbers),
normalized actions (a float32 Box [-1, 1]^N scaled to +-tau_max), the shaped reward
(:func:`twolink.envs.core.shaped_reward`), random initial angles at rest, episodes of
:func:`twolink.arm.parameters.horizon` seconds (5 s for two links, 8 s beyond). One
hyperparameter set per algorithm (:data:`HYPERPARAMETERS`), stated once, never tuned
per seed; ``--envs`` and ``--n-steps`` change the batch only.

Under a challenge level (``challenge``, :data:`twolink.sim.challenges.LEVELS`) every
episode of every arm runs on a plant drawn anew from the level's distribution, with its
noise, delays and faults (the env's ``challenge`` option, the implementation the
leaderboard evaluates with). Arm i draws plants, initial poses and noise from
``np_random(train_stream(seed) + i)``, :func:`train_stream` being a 32-bit word of
``SeedSequence([seed, TRAIN_STREAM])``: one-word entropy, never the two-word
``SeedSequence([seed, PLANT_STREAM], spawn_key=...)`` of the evaluation's plants, so no
training seed draws an evaluation plant. The evaluation seeds themselves
(:data:`EVALUATION_SEEDS`: the leaderboard's and ``twolink evaluate``'s 2026 and the
curve's :data:`EVAL_SEED`) are refused as training seeds under a challenge, so no run is
ever named after the plants it is scored on. ``history`` K > 1 hands the agent the last
K observations and K - 1 actions (:mod:`twolink.envs.history`). ``base`` ``'pd'`` makes
the agent's action a residual over the tuned per-joint PD (3 to 6 links, no challenge):
torque = clip(PD(x) + tau_max a, +-tau_max) (:mod:`twolink.control.residual`,
:class:`twolink.envs.residual.ResidualVecEnv`), so an agent of zero action is the PD.
``action_gain`` G > 1 drives the arms with clip(G a, -1, 1) for the normalized action a
(:mod:`twolink.control.action_gain`): full torque within reach of SAC's squashed actions.
``std_floor`` S (PPO only): the policy's noise starts at standard deviation S and is
raised back to S before every rollout (:mod:`twolink.training.std_floor`).

Training stops, evaluates and checkpoints at update boundaries only: every
:meth:`TrainConfig.unit` environment steps (PPO: one rollout of ``n_steps`` per arm;
SAC: one vector step of all arms), so ``steps`` and ``eval_every`` are rounded up to
whole units.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink.arm.parameters import LINK_RULES, check_links
from twolink.control.action_gain import check_action_gain
from twolink.control.history import check_history
from twolink.control.residual import BASES, check_base
from twolink.training.action_rate import check_action_rate
from twolink.training.std_floor import check_std_floor
from twolink.sim.challenges import LEVELS, is_mix, levels_of, mix
from twolink.validate import choice, whole

#: The algorithms ``twolink train`` runs (Stable-Baselines3).
ALGOS = ("ppo", "sac")
#: The multi-agent algorithms (skrl), run by :mod:`twolink.training.marl`
#: (:class:`~twolink.training.marl.MarlConfig`), not by :class:`TrainConfig`.
MARL_ALGOS = ("ippo", "mappo")
#: The old name of :data:`MARL_ALGOS`.
LATER_ALGOS = MARL_ALGOS
#: ``--plant``: what the arms are stepped on while training -> the env's ``plant`` option.
#: ``mujoco``: MuJoCo, one ``mujoco.rollout`` call per Ts; ``model``: the full model (6)
#: (N links: the rigid-body chain) integrated by numpy, batched. Evaluation is on MuJoCo.
PLANTS = {"mujoco": "mujoco", "model": "full"}
#: ``--device``: where torch runs the networks.
DEVICES = ("cpu", "cuda")
#: What the agent sees and does (the options of TwoLinkSB3VecEnv).
ENV = dict(observation="cos_sin", actions="normalized", reward="shaped", x0="random")
#: ``--reward``: the env reward PPO and SAC learn from, ``shaped`` (the default,
#: :func:`twolink.envs.core.shaped_reward`), ``shaped_time`` (the shaped reward minus one
#: per sample outside the goal band, :func:`twolink.envs.core.shaped_time_reward`) or
#: ``paper`` (the paper's (15), :func:`twolink.arm.task.centralized_reward`: -0.5 per
#: sample outside the goal band, nothing else).
TRAIN_REWARDS = ("shaped", "shaped_time", "paper")
#: What each reward adds to a run's name (``run_name``).
REWARD_SUFFIX = {"shaped": "", "shaped_time": "_rt", "paper": "_rp"}
#: One hyperparameter set per algorithm (those of the committed agents of
#: ``renders/deep_rl/``). SAC: one gradient step per vector step of 8 arms; on a CPU the
#: gradient steps, not the arms, bound the wall time, so more arms buy data at no cost.
HYPERPARAMETERS = {
    "sac": dict(n_envs=8, learning_rate=3e-4, buffer_size=1_000_000, batch_size=256,
                learning_starts=5_000, gamma=0.98, tau=0.005, train_freq=1,
                gradient_steps=1, ent_coef="auto", net_arch=[256, 256]),
    "ppo": dict(n_envs=16, learning_rate=3e-4, n_steps=128, batch_size=256, n_epochs=10,
                gamma=0.98, gae_lambda=0.95, clip_range=0.2, ent_coef=0.0, vf_coef=0.5,
                max_grad_norm=0.5, net_arch=[256, 256]),
}
#: The discount factors a run may take instead of its algorithm's (``--gamma``).
GAMMA_RANGE = (0.5, 1.0)
#: ``--start``: the training episodes' initial poses (the env's ``x0``): uniform angles at
#: rest, or more of the poses beyond the own motors' reach (:mod:`twolink.envs.starts`).
#: The curve's evaluation stays on uniform poses.
START_OPTIONS = ("random", "mixed", "slow")
#: Environment steps between evaluations by default, per algorithm.
EVAL_EVERY = {"sac": 10_000, "ppo": 50_000}
#: Most environment steps a run may ask for, arms per batch, torch threads.
MAX_STEPS = 10**10
MAX_ENVS = 4096
MAX_THREADS = 256
#: ``--batch-size``: the minibatch of an update (PPO, IPPO, MAPPO; held to at most one
#: rollout) or SAC's replay batch, from this many samples to this many.
BATCH_RANGE = (8, 65_536)
#: ``--net``: hidden layers of the policy and value networks, this many at most, each of
#: this many units at least and at most.
NET_LAYERS = 4
NET_WIDTHS = (4, 1024)
#: ``--epochs``: passes over each rollout per update (PPO, IPPO, MAPPO), at most this many.
MAX_EPOCHS = 100
#: Seed of the N-link evaluation poses (N links draw from EVAL_SEED + N): the scaling
#: table's (:data:`twolink.studies.scaling.measure.EVAL_SEED`), so the two compare.
EVAL_SEED = 20061122
#: Random poses at rest an N-link evaluation runs (the scaling table's default).
EVAL_POSES = 64
#: Second word of the seed of a challenge run's training stream (:func:`train_stream`).
TRAIN_STREAM = 611_953
#: The leaderboard's and ``twolink evaluate``'s seed
#: (:data:`twolink.studies.leaderboard.measure.SEED`; a lower layer cannot import it).
LEADERBOARD_SEED = 2026
#: Seeds a challenge run may not train with: those its agent is evaluated on.
EVALUATION_SEEDS = (LEADERBOARD_SEED, EVAL_SEED)
#: Plants of the curve's evaluation under a challenge: ``challenge.plants(EVAL_PLANTS,
#: EVAL_SEED)`` (the leaderboard row runs 32 of seed 2026).
EVAL_PLANTS = 8


def check_challenge_run(challenge, links: int, seed: int) -> None:
    """One-line ValueErrors for a run under ``challenge`` (None: no check): an unknown
    level, an arm of other than two links, or a training seed among
    :data:`EVALUATION_SEEDS`."""
    if challenge is None:
        return
    if is_mix(challenge):
        mix(challenge)
    else:
        choice(challenge, "challenge level", tuple(LEVELS))
    if links != 2:
        raise ValueError(f"challenge levels perturb the two-link arm of Table I; "
                         f"this run has {links} links")
    if seed in EVALUATION_SEEDS:
        raise ValueError(f"seed {seed} is an evaluation seed (the leaderboard's and "
                         f"evaluate's {LEADERBOARD_SEED}, the curve's {EVAL_SEED}): "
                         f"training seeds must differ from the evaluation seeds")


def check_mix_arms(challenge, arms: int) -> None:
    """A one-line ValueError when ``challenge`` is a mix of more levels than the run has
    arms, or of a number of levels that does not divide them (arm i trains under level
    i mod L, so every level gets as many arms)."""
    if not is_mix(challenge):
        return
    levels = len(mix(challenge).levels)
    if arms % levels:
        raise ValueError(f"a mix of {levels} levels ({challenge}) needs a multiple of {levels} "
                         f"arms (--envs), so each level trains on as many; got {arms}")


def evaluate_under(agent, challenge, label: str, plants: int = EVAL_PLANTS):
    """The :class:`twolink.sim.metrics.Score` of the controller ``agent`` on the 65-state
    evaluation set under ``challenge`` (a level, or a :class:`twolink.sim.challenges.Mix`'s
    name: each of its levels, the runs of all together): a level on ``plants`` plants of
    :data:`EVAL_SEED` (the curve's :data:`EVAL_PLANTS`), the nominal arm of a mix's
    ``none`` once."""
    from twolink.sim.evaluation import evaluate
    from twolink.sim.metrics import score

    if not is_mix(challenge):
        return evaluate(agent, label=label, nthread=1, challenge=challenge, seed=EVAL_SEED,
                        count=plants).score
    runs = [evaluate(agent, label=label, nthread=1, challenge=c, seed=EVAL_SEED,
                     count=plants if c != LEVELS["none"] else 1)
            for c in levels_of(challenge)]
    first = np.cumsum([0] + [r.success.shape[0] for r in runs])
    return score(np.concatenate([r.success.ravel() for r in runs]),
                 np.concatenate([r.settle.ravel() for r in runs]),
                 np.concatenate([np.repeat(np.arange(r.success.shape[0]) + f,
                                           r.success.shape[1]) for r, f in zip(runs, first)]))


def mix_protocol(challenge) -> dict:
    """What a curve's protocol adds under a mix (nothing under one level)."""
    if not is_mix(challenge):
        return {}
    return {"mix": "each level's runs scored together; none on the nominal plant once "
                   "(65 runs), every other level on the plants"}


def check_gamma(gamma) -> float:
    """``gamma`` as a float if it is a discount factor a run may take, from
    :data:`GAMMA_RANGE`'s low end up to 1; else one line. The default of every algorithm is
    its :data:`HYPERPARAMETERS` entry (0.98: an effective horizon of 50 samples, 2.5 s)."""
    low, high = GAMMA_RANGE
    try:
        value = float(gamma)
    except (TypeError, ValueError):
        raise ValueError(f"gamma must be a number from {low:g} to {high:g}, "
                         f"got {gamma!r}") from None
    if isinstance(gamma, bool) or not low <= value <= high:
        raise ValueError(f"gamma must be a number from {low:g} to {high:g}, got {gamma!r}")
    return value


def check_recipe(config, *, epochs: bool = True) -> None:
    """Check a run's ``batch_size`` (:data:`BATCH_RANGE`), ``epochs`` (1 to
    :data:`MAX_EPOCHS`; refused where the algorithm has none, ``epochs=False``) and
    ``net`` (:func:`check_net`, stored back as a tuple) of a frozen config
    (:class:`TrainConfig` or :class:`twolink.training.marl.MarlConfig`); one line each."""
    if config.batch_size is not None:
        whole(config.batch_size, "batch_size", *BATCH_RANGE)
    if config.epochs is not None:
        if not epochs:
            raise ValueError("epochs (passes over each rollout) is PPO's; SAC takes one "
                             "gradient step per vector step")
        whole(config.epochs, "epochs", 1, MAX_EPOCHS)
    if config.net is not None:
        object.__setattr__(config, "net", check_net(config.net))


def check_net(net) -> tuple[int, ...]:
    """``net`` (hidden-layer widths, e.g. ``(64, 64)``) as a tuple of ints if it has 1 to
    :data:`NET_LAYERS` layers of :data:`NET_WIDTHS` units; else one line."""
    low, high = NET_WIDTHS
    message = (f"net must be 1 to {NET_LAYERS} hidden-layer widths of {low} to {high} "
               f"units, e.g. 64,64; got {net!r}")
    if isinstance(net, (str, bytes)) or not hasattr(net, "__len__") or \
            not 1 <= len(net) <= NET_LAYERS:
        raise ValueError(message)
    if not all(isinstance(w, (int, np.integer)) and not isinstance(w, bool)
               and low <= w <= high for w in net):
        raise ValueError(message)
    return tuple(int(w) for w in net)


def recipe_suffix(config) -> str:
    """``[_b<B>][_e<E>][_net<W>x<W>]``: the batch, epochs and network a run was given
    (:class:`TrainConfig` or :class:`twolink.training.marl.MarlConfig`), for its name."""
    batch = f"_b{config.batch_size}" if config.batch_size is not None else ""
    epochs = f"_e{config.epochs}" if config.epochs is not None else ""
    net = f"_net{'x'.join(map(str, config.net))}" if config.net is not None else ""
    return batch + epochs + net


def train_stream(seed: int) -> int:
    """The seed of a challenge run's arms (arm i: this + i): a 32-bit word of
    ``SeedSequence([seed, TRAIN_STREAM])``."""
    return int(np.random.SeedSequence([int(seed), TRAIN_STREAM]).generate_state(1)[0])


def check_algo(algo, *, marl: bool = False) -> str:
    """``algo`` if ``twolink train`` runs it (``marl``: the multi-agent ones too); else
    one line."""
    if algo in MARL_ALGOS and not marl:
        raise ValueError(f"--algo {algo} (multi-agent, from skrl) is run by "
                         f"twolink.training.marl.MarlConfig, not TrainConfig")
    return choice(algo, "algo", ALGOS + (MARL_ALGOS if marl else ()))


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """One training run. ``steps``: environment steps (all arms together); ``envs``:
    arms per batch (default the algorithm's ``n_envs``); ``n_steps``: PPO's rollout
    length per arm (default 128); ``eval_every``: environment steps between evaluations
    and checkpoints (default :data:`EVAL_EVERY`); ``threads``: torch's CPU threads."""

    algo: str = "ppo"
    links: int = 2
    rule: str = "tapered"
    steps: int = 1_000_000
    seed: int = 0
    plant: str = "mujoco"
    envs: int | None = None
    n_steps: int | None = None
    eval_every: int | None = None
    device: str = "cpu"
    threads: int = 1
    challenge: str | None = None
    history: int = 1
    base: str = "none"
    action_rate: float = 0.0
    gamma: float | None = None
    start: str = "random"
    init: str | None = None
    batch_size: int | None = None
    epochs: int | None = None
    net: tuple[int, ...] | None = None
    reward: str = "shaped"
    action_gain: float = 1.0
    std_floor: float | None = None

    def __post_init__(self):
        check_algo(self.algo)
        choice(self.reward, "reward", TRAIN_REWARDS)
        check_links(self.links)
        choice(self.rule, "rule", LINK_RULES)
        choice(self.plant, "plant", tuple(PLANTS))
        choice(self.device, "device", DEVICES)
        whole(self.steps, "steps", 1, MAX_STEPS)
        whole(self.seed, "seed", 0, 2**32 - 1)          # SB3 seeds numpy with it
        whole(self.threads, "threads", 1, MAX_THREADS)
        if self.envs is not None:
            whole(self.envs, "envs", 1, MAX_ENVS)
        if self.n_steps is not None:
            if self.algo != "ppo":
                raise ValueError("n_steps (the rollout length per arm) is PPO's; SAC "
                                 "updates after every vector step")
            whole(self.n_steps, "n_steps", 2, 100_000)
        if self.eval_every is not None:
            whole(self.eval_every, "eval_every", 1, MAX_STEPS)
        check_recipe(self, epochs=self.algo == "ppo")
        check_history(self.history)
        choice(self.base, "base", BASES)
        check_base(self.base, self.links)
        object.__setattr__(self, "action_rate", check_action_rate(self.action_rate))
        object.__setattr__(self, "action_gain", check_action_gain(self.action_gain))
        if self.std_floor is not None:
            if self.algo != "ppo":
                raise ValueError("std_floor is for ppo, ippo and mappo: SAC's noise is an "
                                 "output of its network")
            object.__setattr__(self, "std_floor", check_std_floor(self.std_floor))
        if self.gamma is not None:
            object.__setattr__(self, "gamma", check_gamma(self.gamma))
        choice(self.start, "start", START_OPTIONS)
        if self.start != "random":
            from twolink.arm.parameters import links_parameters
            from twolink.envs.starts import check_slow_starts

            check_slow_starts(self.start, links_parameters(self.links, self.rule), "start")
        if self.init is not None:
            if not isinstance(self.init, str) or not self.init.endswith(".zip"):
                raise ValueError(f"init must be the path of a saved agent .zip, got "
                                 f"{self.init!r}")
        check_challenge_run(self.challenge, self.links, self.seed)
        check_mix_arms(self.challenge, self.hyperparameters()["n_envs"])
        if self.challenge is not None and self.plant != "mujoco":
            raise ValueError("a challenge draws a new plant every episode: train it on "
                             "--plant mujoco")

    def hyperparameters(self) -> dict:
        """The algorithm's :data:`HYPERPARAMETERS` with this run's arms, rollout length,
        discount, batch, epochs and network (PPO's minibatch held to at most one rollout)."""
        hp = dict(HYPERPARAMETERS[self.algo])
        if self.envs is not None:
            hp["n_envs"] = self.envs
        if self.gamma is not None:
            hp["gamma"] = self.gamma
        if self.batch_size is not None:
            hp["batch_size"] = self.batch_size
        if self.epochs is not None:
            hp["n_epochs"] = self.epochs
        if self.net is not None:
            hp["net_arch"] = list(self.net)
        if self.algo == "ppo":
            if self.n_steps is not None:
                hp["n_steps"] = self.n_steps
            hp["batch_size"] = min(hp["batch_size"], hp["n_steps"] * hp["n_envs"])
        return hp

    def unit(self) -> int:
        """Environment steps between update boundaries (PPO: a rollout of all arms; SAC:
        one vector step)."""
        hp = self.hyperparameters()
        return hp["n_envs"] * (hp["n_steps"] if self.algo == "ppo" else hp["train_freq"])

    def _whole_units(self, steps: int) -> int:
        return self.unit() * math.ceil(steps / self.unit())

    def total_steps(self) -> int:
        """``steps`` rounded up to whole units."""
        return self._whole_units(self.steps)

    def every(self) -> int:
        """``eval_every`` (or the default) rounded up to whole units."""
        return self._whole_units(self.eval_every or EVAL_EVERY[self.algo])

    def env_options(self) -> dict:
        """The options of :class:`twolink.envs.sb3.TwoLinkSB3VecEnv` for this run."""
        return dict(ENV, reward=self.reward, links=self.links,
                    rule=None if self.links == 2 else self.rule,
                    plant=PLANTS[self.plant], nthread=1, challenge=self.challenge,
                    x0=self.start)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    #: The fields that make a run what it is: a checkpoint resumes only a run of the same.
    IDENTITY = ("algo", "links", "rule", "seed", "plant", "envs", "n_steps", "eval_every",
                "device", "threads", "challenge", "history", "base", "action_rate", "gamma",
                "start", "init", "batch_size", "epochs", "net", "reward", "action_gain",
                "std_floor")

    @classmethod
    def from_dict(cls, d: dict) -> "TrainConfig":
        """The config of ``d`` (:meth:`as_dict`); a ValueError naming a field it lacks or
        one that is not a field."""
        if not isinstance(d, dict):
            raise ValueError("a training config is a dict of its fields")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ValueError(f"unknown training option {unknown[0]!r}")
        return cls(**d)
