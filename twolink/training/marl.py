"""Multi-agent deep RL on the arm: IPPO and MAPPO (skrl) on many arms stepped together.

``twolink train --algo ippo|mappo`` runs :func:`train` with a :class:`MarlConfig`. One
agent per joint (``link1`` .. ``linkN``) on
:func:`twolink.envs.pettingzoo_batched.batched_parallel_env` (all arms in one MuJoCo call
per Ts, or with ``plant='model'`` one numpy step of the full model (6), as PPO's
``--plant model``; same-step autoreset; evaluation on MuJoCo either way): cos/sin angles
(``observation='cos_sin'``), normalized actions (a float32 [-1, 1] per agent, scaled to
+-tau_max), initial poses at rest (``start``), episodes of :func:`twolink.arm.parameters.horizon` seconds; ``observe`` (``local``,
``neighbours``, ``global``: :data:`twolink.envs.core.OBSERVE_OPTIONS`) is what each
policy sees.

* **IPPO** (skrl's ``IPPO``, de Witt et al. 2020): each agent has its own policy and its
  own critic on its own observation, and earns the per-link shaped reward
  (``reward='shaped'``, :func:`twolink.envs.multi_agent.shaped_link_rewards`).
* **MAPPO** (skrl's ``MAPPO``, Yu et al. 2021): each agent has its own policy on its own
  observation and its own centralized critic on the global state (the arm's whole
  cos/sin observation, 3N numbers, :func:`twolink.arm.observations.features`), and every
  agent earns the team's shaped reward (``reward='shaped_team'``: the arm's
  :func:`twolink.envs.core.shaped_reward`, the reward PPO trains with), the cooperative
  setting MAPPO's critic is made for.

``reward='shaped_time'`` (``twolink train --reward shaped_time``) adds the minimum-time
term of PPO's ``shaped_time`` (:func:`twolink.envs.core.shaped_time_reward`): IPPO's agent
earns ``'shaped_time'`` (its link's shaped reward less one per sample outside its link's
band), MAPPO's team ``'shaped_team_time'`` (the arm's shaped reward less one per sample
outside the goal band). ``reward='paper'`` is the paper's own: IPPO's agent earns (17) of
its link, MAPPO's team (15) (-0.5 per sample outside the band, nothing else).

One hyperparameter set (:data:`HYPERPARAMETERS`, PPO's of
:data:`twolink.training.config.HYPERPARAMETERS` where they have a counterpart: 16 arms,
rollouts of 128 steps, 10 epochs of minibatches of 256, lr 3e-4, gamma 0.98, GAE 0.95,
clip 0.2, gradient norm 0.5; networks 64x64 tanh). Truncated episodes bootstrap from the
value of their last observation (``time_limit_bootstrap``, the env's
``final_observation``). The Gaussian actions are clipped to [-1, 1] for the env only (the
memory keeps the sampled ones, as SB3's PPO does).

The run's folder holds ``curve.json`` (the PPO curve's schema,
:data:`twolink.training.run.CURVE_SCHEMA`), ``checkpoint.pt`` (:mod:`.marl_state`,
rewritten at every evaluation, at the end of an update cycle, from which ``resume``
continues bit for bit) and the agent ``<algo>_<N>links_<observe>_seed<S>.marl.pt``
(:mod:`twolink.control.marl_agent`, a controller for evaluate/leaderboard/rollout). The
evaluation (before the first step, every ``eval_every`` steps and after the last) scores
the decentralized controller of the agents' deterministic policies (each joint's torque
from its own agent's mean action on its own observation) with the protocol of PPO's runs:
two links, the 65-state set for 5 s; N links, 64 random poses at rest (seed 20061122 + N)
for 8 s.

Two-link runs may train under a challenge level (``challenge``, as PPO's
:class:`twolink.training.config.TrainConfig`): every episode of every arm on a plant drawn
anew from the level with its noise, delays and faults, arm i drawing from
``train_stream(seed) + i`` (:func:`twolink.training.config.train_stream`, never an
evaluation plant; the evaluation seeds are refused as training seeds), and the curve is
scored under the same level on the 65 states and the
:data:`~twolink.training.config.EVAL_PLANTS` plants of seed
:data:`~twolink.training.config.EVAL_SEED`, PPO's protocol, so the curves compare.
Beside the final agent, ``<algo>_<N>links_<observe>_seed<S>.best.marl.pt`` holds the
policies of the curve's best point so far (PPO's rule:
:func:`twolink.training.run.is_best`), named with its point in the record's ``best``.
``history`` K > 1: each agent's policy (and IPPO's critic) sees the last K of its own
observations and its own K - 1 last actions (:mod:`twolink.training.marl_history`).
``action_rate`` c > 0: a training-only penalty against torque chatter
(:func:`twolink.training.action_rate.agent_penalties`): IPPO's agent i earns its reward
less c (a_i,k - a_i,k-1)^2, MAPPO's team reward is lessened by c times the mean of those
over the agents (PPO's penalty of the arm).
``std_floor`` S: each policy's Gaussian noise starts at standard deviation S (in units of
the normalized action; by default 1, the whole torque limit) and is clipped from below at
S (skrl's ``min_log_std``), so the learner never stops exploring: the policy's mean, which
the controller runs, is learnt under noise of at least S.
``value_norm``: each critic learns the returns standardized by their running mean and
variance (skrl's ``RunningStandardScaler`` as ``value_preprocessor``), the value
normalization Yu et al. (2021) count among MAPPO's implementation details; the critics
then fit returns of any scale (the minimum-time reward's returns reach -100) alike.
``bound_loss`` C > 0: each policy's update also minimizes C * mean(max(|mu| - 1, 0)^2) of
its mean actions mu (rl_games' bound loss, :mod:`twolink.training.bound_loss`), so no
agent's mean settles beyond the torque limit where every sample clips alike.
``start`` (``twolink train --start``, PPO's option): the training episodes' initial poses,
``'random'`` (uniform angles at rest), ``'slow'`` (only poses beyond the own motors' reach,
:mod:`twolink.envs.starts`) or ``'mixed'`` (half of each); the curve stays on uniform poses.
"""
from __future__ import annotations

import dataclasses
import math
import os
import platform
import time
from pathlib import Path

from twolink.arm.parameters import LINK_RULES, check_links, horizon, links_parameters
from twolink.artifacts import VERSION as TWOLINK_VERSION
from twolink.artifacts import write_json
from twolink.control.history import check_history
from twolink.control.residual import BASES, check_base
from twolink.training.action_rate import check_action_rate
from twolink.training.bound_loss import check_bound_loss
from twolink.training.config import DEVICES, EVAL_PLANTS, EVAL_POSES, EVAL_SEED, PLANTS, \
    MAX_ENVS, MAX_STEPS, MAX_THREADS, check_challenge_run, check_gamma, check_mix_arms, \
    REWARD_SUFFIX, START_OPTIONS, TRAIN_REWARDS, check_recipe, evaluate_under, mix_protocol, recipe_suffix, train_stream
from twolink.training.std_floor import check_std_floor
from twolink.validate import choice, whole

#: The multi-agent algorithms (skrl).
MARL_ALGOS = ("ippo", "mappo")
#: What each algorithm's agents earn (the env's ``reward``) under each ``reward`` of
#: :data:`twolink.training.config.TRAIN_REWARDS`.
REWARDS = {("ippo", "shaped"): "shaped", ("mappo", "shaped"): "shaped_team",
           ("ippo", "shaped_time"): "shaped_time",
           ("mappo", "shaped_time"): "shaped_team_time",
           ("ippo", "paper"): "paper", ("mappo", "paper"): "centralized"}
#: ``observe``: what each agent's policy sees.
OBSERVE = ("local", "neighbours", "global")
#: The skrl this code is written against (``pyproject.toml``'s ``marl`` extra).
SKRL_VERSION = "2.1.1"
#: The message of a missing skrl.
NEEDS_SKRL = ("needs skrl, the marl extra: pip install 'twolink[marl]' (or "
              "scripts/install-rl-extras.sh VENV)")
#: One hyperparameter set for both algorithms (see the module docstring).
HYPERPARAMETERS = dict(n_envs=16, n_steps=128, learning_epochs=10, batch_size=256,
                       learning_rate=3e-4, gamma=0.98, gae_lambda=0.95, ratio_clip=0.2,
                       value_clip=0.0, value_loss_scale=0.5, entropy_loss_scale=0.0,
                       grad_norm_clip=0.5, hidden=[64, 64], activation="Tanh",
                       log_std_init=0.0, min_log_std=-20.0)
#: Environment steps between evaluations by default.
EVAL_EVERY = 50_000
#: The run's learning curve (as PPO's, :data:`twolink.training.run.CURVE`).
CURVE_NAME = "curve.json"
#: The env's options (beside links, rule, reward, observe).
ENV = dict(observation="cos_sin", actions="normalized")


def skrl_modules():
    """(skrl, torch), or a RuntimeError naming the extra to install."""
    try:
        import skrl
        import torch
    except ImportError:
        raise RuntimeError(f"twolink train --algo ippo|mappo {NEEDS_SKRL}") from None
    if not str(skrl.__version__).startswith("2."):
        raise RuntimeError(f"twolink train --algo ippo|mappo needs skrl 2.x (the marl extra "
                           f"pins {SKRL_VERSION}); this is skrl {skrl.__version__}")
    return skrl, torch


@dataclasses.dataclass(frozen=True)
class MarlConfig:
    """One IPPO or MAPPO run (fields as :class:`twolink.training.config.TrainConfig`'s;
    ``observe``: what each policy sees; ``n_steps``: the rollout length per arm;
    ``challenge``, ``history``, ``action_rate``: see the module docstring)."""

    algo: str = "ippo"
    links: int = 2
    rule: str = "tapered"
    observe: str = "neighbours"
    steps: int = 1_000_000
    seed: int = 0
    envs: int | None = None
    n_steps: int | None = None
    eval_every: int | None = None
    device: str = "cpu"
    threads: int = 1
    base: str = "none"
    challenge: str | None = None
    history: int = 1
    action_rate: float = 0.0
    gamma: float | None = None
    batch_size: int | None = None
    epochs: int | None = None
    net: tuple[int, ...] | None = None
    std_floor: float | None = None
    reward: str = "shaped"
    value_norm: bool = False
    start: str = "random"
    bound_loss: float = 0.0
    plant: str = "mujoco"

    #: The fields that make a run what it is: a checkpoint resumes only a run of the same.
    IDENTITY = ("algo", "links", "rule", "observe", "seed", "envs", "n_steps",
                "eval_every", "device", "threads", "base", "challenge", "history",
                "action_rate", "gamma", "batch_size", "epochs", "net", "std_floor", "reward",
                "value_norm", "start", "bound_loss", "plant")

    def __post_init__(self):
        choice(self.algo, "algo", MARL_ALGOS)
        check_links(self.links)
        choice(self.rule, "rule", LINK_RULES)
        choice(self.observe, "observe", OBSERVE)
        choice(self.device, "device", DEVICES)
        choice(self.reward, "reward", TRAIN_REWARDS)
        choice(self.plant, "plant", tuple(PLANTS))
        if self.challenge is not None and self.plant != "mujoco":
            raise ValueError("a challenge draws a new plant every episode: train it on "
                             "--plant mujoco")
        if not isinstance(self.value_norm, bool):
            raise ValueError(f"value_norm must be true or false, got {self.value_norm!r}")
        whole(self.steps, "steps", 1, MAX_STEPS)
        whole(self.seed, "seed", 0, 2**31 - 1 - MAX_ENVS)
        whole(self.threads, "threads", 1, MAX_THREADS)
        if self.envs is not None:
            whole(self.envs, "envs", 1, MAX_ENVS)
        if self.n_steps is not None:
            whole(self.n_steps, "n_steps", 2, 100_000)
        if self.eval_every is not None:
            whole(self.eval_every, "eval_every", 1, MAX_STEPS)
        choice(self.base, "base", BASES)
        check_base(self.base, self.links)
        check_history(self.history)
        object.__setattr__(self, "action_rate", check_action_rate(self.action_rate))
        if self.gamma is not None:
            object.__setattr__(self, "gamma", check_gamma(self.gamma))
        check_recipe(self)
        if self.std_floor is not None:
            object.__setattr__(self, "std_floor", check_std_floor(self.std_floor))
        object.__setattr__(self, "bound_loss", check_bound_loss(self.bound_loss))
        choice(self.start, "start", START_OPTIONS)
        if self.start != "random":
            from twolink.envs.starts import check_slow_starts

            check_slow_starts(self.start, links_parameters(self.links, self.rule), "start")
        check_challenge_run(self.challenge, self.links, self.seed)
        check_mix_arms(self.challenge, self.hyperparameters()["n_envs"])

    def arm_seed(self) -> int:
        """The seed of the arms' first reset (arm i: this + i): ``seed``, or under a
        challenge :func:`twolink.training.config.train_stream` of it."""
        return self.seed if self.challenge is None else train_stream(self.seed)

    def hyperparameters(self) -> dict:
        """:data:`HYPERPARAMETERS` with this run's arms, rollout length, discount, minibatch
        (held to at most one rollout), epochs and hidden layers."""
        hp = dict(HYPERPARAMETERS, hidden=list(self.net or HYPERPARAMETERS["hidden"]))
        if self.batch_size is not None:
            hp["batch_size"] = self.batch_size
        if self.epochs is not None:
            hp["learning_epochs"] = self.epochs
        if self.envs is not None:
            hp["n_envs"] = self.envs
        if self.gamma is not None:
            hp["gamma"] = self.gamma
        if self.n_steps is not None:
            hp["n_steps"] = self.n_steps
        if self.std_floor is not None:
            hp["log_std_init"] = hp["min_log_std"] = math.log(self.std_floor)
        if self.bound_loss > 0:
            hp["bound_loss"] = self.bound_loss
        hp["batch_size"] = min(hp["batch_size"], hp["n_steps"] * hp["n_envs"])
        hp["mini_batches"] = max(1, hp["n_steps"] * hp["n_envs"] // hp["batch_size"])
        return hp

    def unit(self) -> int:
        """Environment steps between update boundaries: one rollout of all arms."""
        hp = self.hyperparameters()
        return hp["n_envs"] * hp["n_steps"]

    def total_steps(self) -> int:
        return self.unit() * math.ceil(self.steps / self.unit())

    def every(self) -> int:
        return self.unit() * math.ceil((self.eval_every or EVAL_EVERY) / self.unit())

    def env_options(self) -> dict:
        """The options of :func:`batched_parallel_env` for this run."""
        return dict(ENV, x0=self.start, links=self.links,
                    rule=None if self.links == 2 else self.rule,
                    reward=REWARDS[self.algo, self.reward], observe=self.observe, nthread=1,
                    challenge=self.challenge, plant=PLANTS[self.plant])

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d) -> "MarlConfig":
        if not isinstance(d, dict):
            raise ValueError("a training config is a dict of its fields")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ValueError(f"unknown multi-agent training option {unknown[0]!r}")
        return cls(**d)


#: Options of ``twolink train`` that multi-agent runs do not take, with why.
NOT_MARL = {"init": "a multi-agent run starts from random policies",
            "action_gain": "skrl's Gaussian policies are not squashed: their actions reach "
                           "the torque limit without a gain"}


def config_from_options(given: dict) -> dict:
    """The :class:`MarlConfig` fields of the command's options ``given``; a one-line
    ValueError for an option multi-agent runs do not take."""
    for name, why in NOT_MARL.items():
        if given.get(name) is not None:
            raise ValueError(f"--{name.replace('_', '-')} does not apply to --algo "
                             f"ippo|mappo ({why})")
    names = {f.name for f in dataclasses.fields(MarlConfig)}
    return {k: v for k, v in given.items() if k in names and v is not None}


def run_name(config: MarlConfig) -> str:
    """``<algo>_<N>links_<observe>[_<level>][_h<K>][_<base>][_ar<C>][_g<gamma>][_<start>]
    [_b<B>][_e<E>]
    [_net<W>x<W>][_sf<S>][_rt|_rp][_vn][_bl<C>][_model]_seed<S>`` (``_rt``, ``_rp``:
    ``reward='shaped_time'`` or ``'paper'``; ``_vn``: ``value_norm``; ``_bl``:
    ``bound_loss``; ``_model``: trained on the model (6), ``plant='model'``; PPO's
    :func:`twolink.training.run.run_name` with the observation model): the default folder
    and the agent's stem."""
    level = f"_{config.challenge}" if config.challenge is not None else ""
    memory = f"_h{config.history}" if config.history > 1 else ""
    base = f"_{config.base}" if config.base != "none" else ""
    rate = f"_ar{config.action_rate:g}" if config.action_rate > 0 else ""
    discount = f"_g{config.gamma:g}" if config.gamma is not None else ""
    start = f"_{config.start}" if config.start != "random" else ""
    floor = f"_sf{config.std_floor:g}" if config.std_floor is not None else ""
    reward = REWARD_SUFFIX[config.reward]
    norm = "_vn" if config.value_norm else ""
    bound = f"_bl{config.bound_loss:g}" if config.bound_loss > 0 else ""
    plant = "_model" if config.plant == "model" else ""
    return (f"{config.algo}_{config.links}links_{config.observe}{level}{memory}{base}{rate}"
            f"{discount}{start}{recipe_suffix(config)}{floor}{reward}{norm}{bound}{plant}"
            f"_seed{config.seed}")


def agent_name(config: MarlConfig) -> str:
    from twolink.control.marl_agent import SUFFIX

    return run_name(config) + SUFFIX


def versions() -> dict:
    skrl, torch = skrl_modules()
    return {"twolink": TWOLINK_VERSION, "python": platform.python_version(),
            "skrl": skrl.__version__, "torch": torch.__version__}


def evaluation_protocol(config: MarlConfig) -> dict:
    """What an evaluation of ``config``'s controller runs (recorded in the curve; PPO's
    :func:`twolink.training.run.evaluation_protocol` with the controller named)."""
    if config.challenge is not None:
        return {"states": "twolink.sim.metrics.evaluation_set (65 states)", "horizon_s": 5.0,
                "plant": "mujoco", "challenge": config.challenge, "plants": EVAL_PLANTS,
                "seed": EVAL_SEED, "controller": "decentralized: each joint from its agent",
                **mix_protocol(config.challenge)}
    if config.links == 2:
        return {"states": "twolink.sim.metrics.evaluation_set (65 states)", "horizon_s": 5.0,
                "plant": "mujoco", "controller": "decentralized: each joint from its agent"}
    return {"states": f"twolink.sim.metrics.random_poses({config.links}, {EVAL_POSES}, "
                      f"{EVAL_SEED} + {config.links})", "horizon_s": horizon(config.links),
            "plant": "mujoco", "controller": "decentralized: each joint from its agent"}


def evaluate_controller(agent, config: MarlConfig):
    """The :class:`twolink.sim.metrics.Score` of the controller ``agent`` under the
    evaluation protocol of ``config`` (PPO's: :func:`twolink.training.run.evaluate_policy`)."""
    from twolink.envs.core import arm

    if config.links == 2:
        from twolink.sim.evaluation import evaluate

        if config.challenge is not None:
            return evaluate_under(agent, config.challenge, f"{config.algo} seed {config.seed}",
                                  EVAL_PLANTS)
        return evaluate(agent, label=f"{config.algo} seed {config.seed}", nthread=1).score
    from twolink.sim.metrics import random_poses, score, settle_time, success
    from twolink.sim.plants import MujocoPlant
    from twolink.sim.rollout import rollout

    params = arm(links=config.links, rule=config.rule)
    x0 = random_poses(config.links, EVAL_POSES, EVAL_SEED + config.links)
    with MujocoPlant(params, nthread=1) as plant:
        traj = rollout(agent, plant, x0, duration=horizon(config.links))
    return score(success(traj), settle_time(traj))


def train(config, out, *, resume: bool = False, progress=None) -> dict:
    """Run the IPPO/MAPPO training of ``config`` (a :class:`MarlConfig`) into ``out``, or,
    ``resume``, continue the run of ``out/checkpoint.pt`` (``config``: None or the options
    given, a dict or a MarlConfig, which must be the checkpoint's run; ``steps`` may grow
    it); the final curve record (as :func:`twolink.training.run.train`'s)."""
    from twolink.training import marl_state
    from twolink.training.run import CHECKPOINT, CURVE, CURVE_SCHEMA, CURVE_VERSION, \
        folder_state

    skrl_modules()
    out = Path(out)
    state = folder_state(out)
    if state == "finished":
        raise ValueError(f"{out} holds a finished run (its agent and {CURVE}); train "
                         f"into another --out")
    if state == "interrupted" and not resume:
        raise ValueError(f"{out} holds an interrupted run; --resume continues it, or give "
                         f"another --out")
    header = tensors = None
    if resume:
        if state == "new":
            raise ValueError(f"no run in {out} to resume (no {CHECKPOINT})")
        header, tensors = marl_state.load(out / CHECKPOINT)
        config = marl_state.check_resume(header, config, out / CHECKPOINT, versions(),
                                         MarlConfig)
    elif not isinstance(config, MarlConfig):
        raise ValueError("give a MarlConfig (or resume=True)")
    total, every = config.total_steps(), config.every()
    if header is not None and header["steps"] > total:
        raise ValueError(f"{out / CHECKPOINT} is at {header['steps']:,} steps, past the "
                         f"{total:,} asked for")
    learner = marl_state.Learner(config, skrl_modules()[1])
    record = {"schema": CURVE_SCHEMA, "version": CURVE_VERSION, "config": config.as_dict(),
              "hyperparameters": config.hyperparameters(), "env": config.env_options(),
              "evaluation": evaluation_protocol(config), "steps_requested": total,
              "eval_every": every, "versions": versions(),
              "machine": {"cpus": os.cpu_count(), "torch_threads": config.threads,
                          "device": config.device}, "curve": [], "done": False}
    clocks = {"wall_s": 0.0, "cpu_s": 0.0}
    if header is not None:
        learner.restore(header["plain"], tensors)
        record["curve"], clocks = header["curve"], header["clocks"]
        record["resumed_at"] = header.get("resumed_at", []) + [header["steps"]]
        if header.get("best"):
            record["best"] = header["best"]
    out.mkdir(parents=True, exist_ok=True)
    try:
        _loop(config, learner, out, record, clocks, total, every,
              progress or (lambda text: None))
    finally:
        learner.close()
    return record


def _loop(config, learner, out, record, clocks, total, every, say) -> None:
    from twolink.training import marl_state
    from twolink.training.run import CHECKPOINT, CURVE, best_entry, curve_point, is_best

    def point() -> None:
        sc = evaluate_controller(learner.controller(), config)
        record["curve"].append(curve_point(learner.steps, sc, clocks["wall_s"], clocks["cpu_s"]))
        if is_best(record["curve"]):
            record["best"] = best_entry(record["curve"], agent_name(config))
            learner.save_agent(out / record["best"]["agent"])
        plain, tensors = learner.capture()
        header = {"config": config.as_dict(), "versions": record["versions"],
                  "steps": learner.steps, "plain": plain, "curve": record["curve"],
                  "clocks": clocks, "best": record.get("best")}
        if "resumed_at" in record:
            header["resumed_at"] = record["resumed_at"]
        marl_state.save(out / CHECKPOINT, header, tensors)
        write_json(out / CURVE, record)
        lo, hi = sc.wilson_95
        p = record["curve"][-1]
        base = "" if config.challenge is None else f" under {config.challenge}"
        base += "" if config.history == 1 else f" history {config.history}"
        base += "" if config.base == "none" else f" over base {config.base}"
        say(f"train {config.algo} {config.links} links ({config.observe}){base} seed "
            f"{config.seed}: {learner.steps:,}/{total:,} steps  {sc.successes}/{sc.n} "
            f"succeed [{lo:.2f}, {hi:.2f}]  {p['steps_per_s'] or 0:.0f} steps/s")

    if not record["curve"]:
        point()
    while learner.steps < total:
        chunk = min(every - learner.steps % every, total - learner.steps)
        wall, cpu = time.perf_counter(), time.process_time()
        learner.learn(chunk, total)
        clocks["wall_s"] += time.perf_counter() - wall
        clocks["cpu_s"] += time.process_time() - cpu
        point()
    learner.save_agent(out / agent_name(config))
    record.update(done=True, steps=learner.steps, agent=agent_name(config),
                  wall_s=round(clocks["wall_s"], 3), cpu_s=round(clocks["cpu_s"], 3),
                  steps_per_s=round(learner.steps / clocks["wall_s"], 1)
                  if clocks["wall_s"] > 0 else None)
    write_json(out / CURVE, record)


def run_algo(out) -> str | None:
    """The algorithm of the run in the folder ``out`` (from its ``curve.json``, else from
    its checkpoint's header: a folder holding the checkpoint alone), None where there is
    none to read."""
    import json

    from twolink.training import checkpoint

    try:
        return json.loads((Path(out) / "curve.json").read_text())["config"]["algo"]
    except (OSError, ValueError, KeyError, TypeError):
        pass
    try:
        return checkpoint.read(Path(out) / "checkpoint.pt")[0]["config"]["algo"]
    except (ValueError, KeyError, TypeError):
        return None
