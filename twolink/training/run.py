"""One deep-RL training run on the arm: build, train, evaluate, checkpoint, save the agent.

:func:`train` trains a Stable-Baselines3 learner (:data:`twolink.training.config.ALGOS`)
on :class:`twolink.envs.sb3.TwoLinkSB3VecEnv` (all arms of a batch in one
``mujoco.rollout`` call per Ts, or the numpy full model) and writes into its folder:

* ``curve.json`` (:data:`CURVE_SCHEMA`): the run's config, hyperparameters, evaluation
  protocol and versions, and one point per evaluation (environment steps, successes of
  n, rate, Wilson 95 % interval, median settle time, training wall and CPU seconds,
  steps per second), rewritten atomically after every point;
* ``checkpoint.pt`` (:mod:`twolink.training.checkpoint`), rewritten atomically at the
  same points, from which ``resume=True`` continues exactly;
* ``<algo>_<N>links_seed<S>.zip`` (:func:`agent_name`), the final policy as an SB3 save with
  the ``twolink.json`` member of :mod:`twolink.control.agent_meta`: a controller for
  :mod:`twolink.control.sb3_agent` (``twolink evaluate/leaderboard/rollout --controller``);
* ``<algo>_<N>links_seed<S>.best.zip`` (:func:`best_agent_name`), the policy of the
  curve's best point so far (most successes, the latest of equals; :func:`is_best`),
  rewritten when a point ties or beats every earlier one, and named with its point in
  the curve record's ``best``: a pick on the curve's own evaluation, which is the
  training side's (never the leaderboard's plants or the evaluate command's poses).

Evaluation (before the first step, every ``eval_every`` steps and after the last) runs
the deterministic policy on MuJoCo: for two links the 65-state evaluation set for 5 s
(:func:`twolink.sim.evaluation.evaluate`, the paper's metric); for N links
:data:`~twolink.training.config.EVAL_POSES` random poses at rest
(:func:`twolink.sim.metrics.random_poses`, seed ``EVAL_SEED + N``) for 8 s, the scaling
table's protocol. Success: settled in the goal band from 1 s before the end on. Under a
challenge level the evaluation is the same level's: the 65 states on the
:data:`~twolink.training.config.EVAL_PLANTS` plants of seed
:data:`~twolink.training.config.EVAL_SEED` (``evaluate(..., challenge=level,
seed=EVAL_SEED)``: neither the training stream nor the leaderboard's seed 2026). With an
observation history (``history`` K > 1) the arms are wrapped in
:class:`twolink.envs.history.HistoryVecEnv` and the agent's ``twolink.json`` records K
and the observation layout. With ``base='pd'`` the arms are wrapped in
:class:`twolink.envs.residual.ResidualVecEnv` (the action a residual over the tuned
per-joint PD), the curve scores the same residual controller, and the agent's
``twolink.json`` records the base and its gains (:mod:`twolink.control.residual`).
"""
from __future__ import annotations

import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from twolink.arm.parameters import horizon
from twolink.artifacts import VERSION as TWOLINK_VERSION
from twolink.artifacts import atomic_path, write_json
from twolink.control.action_gain import gained
from twolink.control.agent_meta import AGENT_MEMBER, agent_record
from twolink.control.history import ObservationHistory, history_layout
from twolink.control.residual import base_controller, base_gains, residual_torques
from twolink.control.sb3_agent import NEEDS_RL, model_torques
from twolink.envs.core import arm
from twolink.training import checkpoint, episodes
from twolink.training.config import (EVAL_PLANTS, EVAL_POSES, EVAL_SEED, REWARD_SUFFIX,
                                     TrainConfig, evaluate_under, mix_protocol,
                                     recipe_suffix, train_stream)

#: Schema and version of ``curve.json``.
CURVE_SCHEMA, CURVE_VERSION = "twolink.train", 1
#: The files of a run's folder (the agent's: :func:`agent_name`).
CURVE, CHECKPOINT = "curve.json", "checkpoint.pt"
#: The fields of a curve point that are clocks (the rest are the same bit for bit in a
#: resumed run).
CLOCKS = ("wall_s", "cpu_s", "steps_per_s")


def _imports():
    try:
        import stable_baselines3
        import torch
    except ImportError:
        raise RuntimeError(f"twolink train {NEEDS_RL}") from None
    return stable_baselines3, torch


def versions() -> dict:
    sb3, torch = _imports()
    return {"twolink": TWOLINK_VERSION, "python": platform.python_version(),
            "stable_baselines3": sb3.__version__, "torch": torch.__version__}


def build(config: TrainConfig):
    """(model, env): the seeded SB3 model of ``config`` on its vector environment."""
    sb3, torch = _imports()
    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    if config.device == "cuda" and not torch.cuda.is_available():
        raise RuntimeError("--device cuda: torch sees no CUDA device here (torch "
                           f"{torch.__version__}); train with --device cpu")
    torch.set_num_threads(config.threads)
    hp = config.hyperparameters()
    n_envs, net = hp.pop("n_envs"), hp.pop("net_arch")
    env = TwoLinkSB3VecEnv(n_envs, **config.env_options())
    if config.base != "none":
        from twolink.envs.residual import ResidualVecEnv

        env = ResidualVecEnv(env, base_controller(config.base, arm_of(config)))
    if config.action_gain != 1.0:
        from twolink.envs.action_gain import ActionGainVecEnv

        env = ActionGainVecEnv(env, config.action_gain)
    if config.action_rate > 0:
        from twolink.training import action_rate

        env = action_rate.wrap(env, config.action_rate)
    if config.history > 1:
        from twolink.envs.history import HistoryVecEnv

        env = HistoryVecEnv(env, config.history)
    cls = sb3.SAC if config.algo == "sac" else sb3.PPO
    kwargs = dict(net_arch=net)
    if config.std_floor is not None:                  # the noise starts at the floor
        kwargs["log_std_init"] = math.log(config.std_floor)
    model = cls("MlpPolicy", env, seed=config.seed, device=config.device, verbose=0,
                policy_kwargs=kwargs, **hp)
    if config.init is not None:
        warm_start(model, config)
    if config.challenge is not None:         # the arms' own stream (config's docstring)
        env.seed(train_stream(config.seed))
    return model, env


def warm_start(model, config: TrainConfig) -> None:
    """Load the policy weights of the saved agent ``config.init`` into ``model`` (read as
    data: :class:`twolink.control.sb3_agent.SB3Agent`), so training starts from it. One
    line when the agent is not one this run could have saved: another algorithm, arm,
    observation history, base, action gain or network."""
    from twolink.control.sb3_agent import SB3Agent

    agent = SB3Agent(config.init)
    want = {"algorithm": config.algo, "links": config.links,
            "rule": config.rule if config.links > 2 else None,
            "history": config.history, "base": config.base,
            "action gain": config.action_gain}
    have = {"algorithm": agent.algo, "links": agent.links, "rule": agent.rule,
            "history": agent.history, "base": agent.base_name or "none",
            "action gain": agent.action_gain}
    for key in want:
        if want[key] != have[key]:
            raise ValueError(f"--init {config.init}: its {key} is {have[key]}, this run's "
                             f"{want[key]}")
    mine, theirs = model.policy.state_dict(), agent.policy.state_dict()
    if mine.keys() != theirs.keys() or any(mine[k].shape != theirs[k].shape for k in mine):
        raise ValueError(f"--init {config.init}: its network does not fit this run's "
                         f"({config.hyperparameters()['net_arch']})")
    model.policy.load_state_dict(theirs, strict=True)


def arm_of(config: TrainConfig):
    """The arm parameters of ``config``'s run."""
    return arm(links=config.links, rule=None if config.links == 2 else config.rule)


class PolicyController:
    """An SB3 policy in memory under the controller protocol: states (n, 2N) -> torques
    (n, N), the clipped deterministic action times ``gain`` (clipped again,
    :func:`twolink.control.action_gain.gained`) scaled to +-tau_max, added to ``base``'s
    torques when given (:func:`twolink.control.residual.residual_torques`)."""

    def __init__(self, policy, params, name: str = "sb3", history: int = 1, base=None,
                 gain: float = 1.0):
        self.policy, self.tau_max, self.links = policy, params.tau_max, params.links
        self.name, self.history, self._buffer, self.base = name, history, None, base
        self.gain = gain

    def reset(self, n: int) -> None:
        if self.history > 1:
            self._buffer = ObservationHistory(n, 3 * self.links, self.links, self.history)

    def __call__(self, x):
        unit = model_torques(self.policy, x, "cos_sin", 1.0) if self.history == 1 \
            else self._history_action(x)
        unit = gained(unit, self.gain)
        if self.base is not None:
            return residual_torques(self.base, x, unit, self.tau_max)
        return unit * np.asarray(self.tau_max, dtype=float)

    def _history_action(self, x):
        from twolink.arm.observations import features

        if self._buffer is None or self._buffer.rows != len(x):
            self.reset(len(x))
        action, _ = self.policy.predict(self._buffer.observe(features(x, "cos_sin")),
                                        deterministic=True)
        a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
        self._buffer.act(a)
        return a


def evaluation_protocol(config: TrainConfig) -> dict:
    """What an evaluation of ``config``'s agent runs (recorded in the curve)."""
    if config.challenge is not None:
        return {"states": "twolink.sim.metrics.evaluation_set (65 states)", "horizon_s": 5.0,
                "plant": "mujoco", "challenge": config.challenge, "plants": EVAL_PLANTS,
                "seed": EVAL_SEED, **mix_protocol(config.challenge)}
    if config.links == 2:
        return {"states": "twolink.sim.metrics.evaluation_set (65 states)", "horizon_s": 5.0,
                "plant": "mujoco"}
    return {"states": f"twolink.sim.metrics.random_poses({config.links}, {EVAL_POSES}, "
                      f"{EVAL_SEED} + {config.links})", "horizon_s": horizon(config.links),
            "plant": "mujoco"}


def evaluate_policy(policy, config: TrainConfig):
    """The :class:`twolink.sim.metrics.Score` of the deterministic ``policy`` under the
    evaluation protocol of ``config`` (see the module docstring)."""
    params = arm_of(config)
    agent = PolicyController(policy, params, history=config.history,
                             base=base_controller(config.base, params),
                             gain=config.action_gain)
    if config.links == 2:
        from twolink.sim.evaluation import evaluate

        if config.challenge is not None:
            return evaluate_under(agent, config.challenge, f"{config.algo} seed {config.seed}",
                                  EVAL_PLANTS)
        return evaluate(agent, label=f"{config.algo} seed {config.seed}", nthread=1).score
    from twolink.sim.metrics import random_poses, score, settle_time, success
    from twolink.sim.plants import MujocoPlant
    from twolink.sim.rollout import rollout

    x0 = random_poses(config.links, EVAL_POSES, EVAL_SEED + config.links)
    with MujocoPlant(params, nthread=1) as plant:
        traj = rollout(agent, plant, x0, duration=horizon(config.links))
    return score(success(traj), settle_time(traj))


def save_agent(model, path, config: TrainConfig) -> Path:
    """The SB3 save of ``model`` at ``path`` (atomically) with the ``twolink.json`` member
    naming its arm, so :mod:`twolink.control.sb3_agent` loads it."""
    import zipfile

    record = agent_record(config.links, config.rule, algo=config.algo, seed=config.seed,
                          steps=int(model.num_timesteps), plant=config.plant,
                          challenge=config.challenge, history=config.history,
                          observation_layout=history_layout(config.history,
                                                            3 * config.links, config.links),
                          **_base_record(config), **_gain_record(config))
    with atomic_path(path) as tmp:
        model.save(tmp)
        with zipfile.ZipFile(tmp, "a", zipfile.ZIP_DEFLATED) as z:
            z.writestr(AGENT_MEMBER, json.dumps(record))
    return Path(path)


def _gain_record(config: TrainConfig) -> dict:
    """The agent's ``action_gain`` field: none for a gain of 1 (an older loader reads the
    agent as before)."""
    return {} if config.action_gain == 1.0 else {"action_gain": config.action_gain}


def _base_record(config: TrainConfig) -> dict:
    """The agent's ``base`` fields: none for ``'none'`` (an older loader reads the agent
    as before), else the base and the gains it was trained over."""
    if config.base == "none":
        return {}
    return {"base": config.base, "base_gains": base_gains(config.base, arm_of(config))}


def agent_name(config: TrainConfig) -> str:
    """The file name of the run's agent (its stem labels it on the leaderboard)."""
    return run_name(config) + ".zip"


#: What a run's best agent adds to its agent's stem.
BEST = ".best"


def best_agent_name(agent: str) -> str:
    """``<stem>.best<suffix>``: the file name of the best agent of a run whose final agent
    is ``agent`` (an SB3 ``.zip`` or a multi-agent ``.marl.pt``)."""
    for suffix in (".marl.pt", ".zip"):
        if agent.endswith(suffix):
            return agent[:-len(suffix)] + BEST + suffix
    raise ValueError(f"{agent!r} is not an agent file name (.zip or .marl.pt)")


def is_best(curve) -> bool:
    """Whether the curve's last point scores at least as many successes as every earlier
    one: the run's best so far (of equals, the latest)."""
    return bool(curve) and curve[-1]["successes"] >= max(p["successes"] for p in curve)


def best_entry(curve, agent: str) -> dict:
    """The curve record's ``best``: the best agent's file name and its point."""
    p = curve[-1]
    return {"agent": best_agent_name(agent), "steps": p["steps"],
            "successes": p["successes"], "n": p["n"], "rate": p["rate"]}


def run_name(config: TrainConfig) -> str:
    """``<algo>_<N>links[_<level>][_h<K>][_<base>][_ar<C>][_g<gamma>][_<start>][_init]
    [_b<B>][_e<E>][_net<W>x<W>][_sf<S>][_rt|_rp][_ag<G>]_seed<S>`` (``_sf``: the noise
    floor; ``_rt``, ``_rp``: the ``shaped_time`` or ``paper`` reward,
    :data:`twolink.training.config.REWARD_SUFFIX`; ``_ag``: the action gain): the run's default
    folder and its agent's stem."""
    level = f"_{config.challenge}" if config.challenge is not None else ""
    memory = f"_h{config.history}" if config.history > 1 else ""
    base = f"_{config.base}" if config.base != "none" else ""
    rate = f"_ar{config.action_rate:g}" if config.action_rate > 0 else ""
    discount = f"_g{config.gamma:g}" if config.gamma is not None else ""
    start = f"_{config.start}" if config.start != "random" else ""
    init = "_init" if config.init is not None else ""
    reward = REWARD_SUFFIX[config.reward]
    gain = f"_ag{config.action_gain:g}" if config.action_gain != 1.0 else ""
    floor = f"_sf{config.std_floor:g}" if config.std_floor is not None else ""
    return (f"{config.algo}_{config.links}links{level}{memory}{base}{rate}{discount}{start}"
            f"{init}{recipe_suffix(config)}{floor}{reward}{gain}_seed{config.seed}")


def _point(steps: int, sc, wall: float, cpu: float) -> dict:
    med = sc.median_settle
    return {"steps": int(steps), "successes": int(sc.successes), "n": int(sc.n),
            "rate": sc.rate, "wilson_95": [float(v) for v in sc.wilson_95],
            "median_settle": None if math.isinf(med) else float(med),
            "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
            "steps_per_s": round(steps / wall, 1) if wall > 0 and steps else None}


def _check_resume(header: dict, given, path: Path) -> TrainConfig:
    """The config of the checkpoint ``header`` with ``given`` applied (a TrainConfig, or a
    dict of the options given; None: none): every field of
    :attr:`TrainConfig.IDENTITY` given must be the checkpoint's, ``steps`` may change;
    and this machine's Stable-Baselines3 must be the checkpoint's."""
    saved = TrainConfig.from_dict(header.get("config"))
    if isinstance(given, TrainConfig):
        given = given.as_dict()
    given = {k: v for k, v in (given or {}).items() if v is not None}
    for name in TrainConfig.IDENTITY:
        if name in given and given[name] != getattr(saved, name):
            raise ValueError(f"{path} is a checkpoint of a run with {name} "
                             f"{getattr(saved, name)!r}, not {given[name]!r}")
    if "steps" in given:
        saved = TrainConfig.from_dict(dict(saved.as_dict(), steps=given["steps"]))
    mine = versions()
    theirs = (header.get("versions") or {}).get("stable_baselines3")
    if theirs != mine["stable_baselines3"]:
        raise ValueError(f"{path} was written by Stable-Baselines3 {theirs}, this is "
                         f"{mine['stable_baselines3']}: it cannot resume exactly")
    return saved


def _state_of(out: Path) -> str:
    """``'new'`` (no run in ``out``), ``'finished'`` or ``'interrupted'``."""
    curve = out / CURVE
    if not curve.is_file() and not (out / CHECKPOINT).is_file():
        return "new"
    try:
        record = json.loads(curve.read_text())
        done = record.get("done") is True and (out / str(record.get("agent"))).is_file()
    except (OSError, ValueError, AttributeError):
        done = False
    return "finished" if done else "interrupted"


def train(config, out, *, resume: bool = False, progress=None) -> dict:
    """Run the training of ``config`` (a :class:`TrainConfig`) into the folder ``out``,
    or, ``resume``, continue the run of ``out/checkpoint.pt`` (``config``: None, or the
    options given, a TrainConfig or a dict, which must be the checkpoint's run; ``steps``
    may grow it); the final curve record. ``progress(text)`` gets one line per
    evaluation. A folder holding a finished run is never written over, nor one holding
    an interrupted run unless ``resume``."""
    out = Path(out)
    state = _state_of(out)
    if state == "finished":
        raise ValueError(f"{out} holds a finished run (its agent and {CURVE}); train "
                         f"into another --out")
    if state == "interrupted" and not resume:
        raise ValueError(f"{out} holds an interrupted run; --resume continues it, or give "
                         f"another --out")
    if resume:
        if state == "new":
            raise ValueError(f"no run in {out} to resume (no {CHECKPOINT})")
        header, tensors = checkpoint.load(out / CHECKPOINT)
        config = _check_resume(header, config, out / CHECKPOINT)
    elif not isinstance(config, TrainConfig):
        raise ValueError("give a TrainConfig (or resume=True)")
    total, every = config.total_steps(), config.every()
    model, env = build(config)
    record = {"schema": CURVE_SCHEMA, "version": CURVE_VERSION, "config": config.as_dict(),
              "hyperparameters": config.hyperparameters(), "env": config.env_options(),
              "evaluation": evaluation_protocol(config), "steps_requested": total,
              "eval_every": every, "versions": versions(),
              "machine": {"cpus": os.cpu_count(), "torch_threads": config.threads,
                          "device": config.device}, "curve": [], "done": False}
    clocks = {"wall_s": 0.0, "cpu_s": 0.0}
    if resume:
        if header["steps"] > total:
            raise ValueError(f"{out / CHECKPOINT} is at {header['steps']:,} steps, past the "
                             f"{total:,} asked for")
        checkpoint.restore(model, episodes.base(env), header["plain"], tensors)
        if "episodes" in tensors:
            episodes.restore(env, tensors["episodes"])
        record["curve"], clocks = header["curve"], header["clocks"]
        record["resumed_at"] = header.get("resumed_at", []) + [header["steps"]]
        if header.get("best"):
            record["best"] = header["best"]
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda text: None)
    try:
        _loop(config, model, env, out, record, clocks, total, every, say)
    finally:
        env.close()
    return record


def _loop(config, model, env, out, record, clocks, total, every, say) -> None:
    def point() -> None:
        sc = evaluate_policy(model.policy, config)
        record["curve"].append(_point(model.num_timesteps, sc, clocks["wall_s"],
                                      clocks["cpu_s"]))
        if is_best(record["curve"]):
            record["best"] = best_entry(record["curve"], agent_name(config))
            save_agent(model, out / record["best"]["agent"], config)
        plain, tensors = checkpoint.capture(model, episodes.base(env))
        if plain["started"] and (config.challenge is not None or config.history > 1
                                 or config.action_rate > 0):
            tensors["episodes"] = episodes.capture(env)
        header = {"config": config.as_dict(), "versions": record["versions"],
                  "steps": int(model.num_timesteps), "plain": plain,
                  "curve": record["curve"], "clocks": clocks, "best": record.get("best")}
        if "resumed_at" in record:
            header["resumed_at"] = record["resumed_at"]
        checkpoint.save(out / CHECKPOINT, header, tensors)
        write_json(out / CURVE, record)
        lo, hi = sc.wilson_95
        p = record["curve"][-1]
        under = "" if config.challenge is None else f" under {config.challenge}"
        memory = "" if config.history == 1 else f" history {config.history}"
        memory += "" if config.base == "none" else f" over base {config.base}"
        say(f"train {config.algo} {config.links} links{under}{memory} seed {config.seed}: "
            f"{model.num_timesteps:,}/{total:,} steps  {sc.successes}/{sc.n} succeed "
            f"[{lo:.2f}, {hi:.2f}]  {p['steps_per_s'] or 0:.0f} steps/s")

    callback = None
    if config.std_floor is not None:
        from twolink.training.std_floor import floor_callback

        callback = floor_callback(config.std_floor)
    if not record["curve"]:
        point()
    while model.num_timesteps < total:
        chunk = min(every - model.num_timesteps % every, total - model.num_timesteps)
        wall, cpu = time.perf_counter(), time.process_time()
        model.learn(total_timesteps=chunk, reset_num_timesteps=model.num_timesteps == 0,
                    log_interval=None, progress_bar=False, callback=callback)
        clocks["wall_s"] += time.perf_counter() - wall
        clocks["cpu_s"] += time.process_time() - cpu
        point()
    save_agent(model, out / agent_name(config), config)
    record.update(done=True, steps=int(model.num_timesteps), agent=agent_name(config),
                  wall_s=round(clocks["wall_s"], 3), cpu_s=round(clocks["cpu_s"], 3),
                  steps_per_s=round(model.num_timesteps / clocks["wall_s"], 1)
                  if clocks["wall_s"] > 0 else None)
    write_json(out / CURVE, record)


#: Public names of the curve point and the folder's state, for the multi-agent runs
#: (:mod:`twolink.training.marl`), which write the same curve into the same folders.
curve_point, folder_state = _point, _state_of
