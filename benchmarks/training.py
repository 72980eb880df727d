"""Deep-RL training cost per environment step: ``twolink train``'s PPO, IPPO and MAPPO
(updates included) beside the physics alone, for N = 2 and 6 links.

Three figures per N, in CPU microseconds per environment step (one arm, one sample
period), one process, torch on one thread, MuJoCo on one thread:

* training: :meth:`model.learn` of the PPO that ``twolink train`` builds
  (:func:`twolink.training.run.build`, its hyperparameters; ``n_steps`` per arm per
  update), over whole updates, after one warm-up update: rollouts (the policy's forward
  pass, the vector environment) plus the updates (n_epochs of minibatch gradient steps);
* the vector environment alone: :class:`twolink.envs.sb3.TwoLinkSB3VecEnv` stepped with
  random normalized actions (physics, reward, observations, autoreset);
* the physics alone: :class:`twolink.sim.plants.MujocoPlant` stepping the same batch.

* IPPO and MAPPO (skrl, :mod:`twolink.training.marl`): ``Learner.learn`` of the learner
  ``twolink train --algo ippo|mappo`` builds (its hyperparameters, ``observe=
  'neighbours'``, the same arms and rollout length as PPO's row), over whole updates after
  one warm-up update: the N agents' policies and critics (64x64), the batched multi-agent
  env, and N updates of 10 epochs each.

* the lighter recipe (:data:`LIGHT`, at the largest N only): the same rows with the
  options ``twolink train --batch-size/--epochs/--net/--envs`` gives a lever run of the
  learners page, so its cost stands beside the default recipe's measured in the same run.

* MAPPO on the model (6) (:data:`MODEL_RECIPE`, at the largest N only): the recipe of the
  learners page's lever runs ``mappo-neighbours-cheap-e3-sf0.2*`` trained with
  ``--plant model`` (the arms stepped on the numpy full model in one batch) and, measured
  in the same run, on MuJoCo, beside the model's physics alone for the same batch: the
  figure the training-cost target (150 us per step at six links) is checked by.

Needs the rl extras (the IPPO/MAPPO rows the marl extra); without them the section (or
those rows) reports nothing and says so.
"""
from __future__ import annotations

import time

import numpy as np

from benchmarks.common import Row

SECTION = "training"
#: The lighter recipe per algorithm (``twolink train`` options, with the section's rollout
#: of 64 steps per arm; the learners page's lever runs ``ppo-pd-light_6t_seed*`` and
#: ``mappo-neighbours-cheap_6t_seed0`` / ``-cheap12m`` say how it learns): PPO with a
#: small network and large minibatches; IPPO/MAPPO over 256 arms with minibatches of
#: 4096 and 5 epochs, so the per-call costs of skrl and torch spread over many samples.
LIGHT = {"ppo": dict(batch_size=1024, net=(64, 64)),
         "ippo": dict(envs=256, batch_size=4096, epochs=5),
         "mappo": dict(envs=256, batch_size=4096, epochs=5)}

#: The MAPPO recipe of the model rows: 256 arms, minibatches of 4096, 3 epochs and the
#: noise floor 0.2 (``twolink train --envs 256 --batch-size 4096 --epochs 3 --std-floor
#: 0.2``; the lever runs ``mappo-neighbours-cheap-e3-sf0.2*`` say how it learns).
MODEL_RECIPE = dict(envs=256, batch_size=4096, epochs=3, std_floor=0.2)


def _recipe(options: dict) -> str:
    return ", ".join(f"{k.replace('_', ' ')} "
                     f"{'x'.join(map(str, v)) if isinstance(v, tuple) else v}"
                     for k, v in options.items())


def _cpu(fn) -> float:
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def measure(links: int, *, envs: int = 16, n_steps: int = 128, updates: int = 2,
            **options) -> dict:
    """CPU seconds per environment step of PPO training, of the vector environment and of
    the plant, for an arm of ``links`` links (``options``: more TrainConfig fields, e.g.
    ``batch_size``, ``net``)."""
    from twolink.training.config import TrainConfig
    from twolink.training.run import build

    config = TrainConfig(algo="ppo", links=links, envs=envs, n_steps=n_steps, **options)
    unit = config.unit()
    model, env = build(config)
    try:
        model.learn(unit, log_interval=None)                      # warm-up update
        train = _cpu(lambda: model.learn(unit * updates, reset_num_timesteps=False,
                                         log_interval=None))
        steps = unit * updates
        rng = np.random.default_rng(0)
        actions = rng.uniform(-1, 1, (n_steps, envs, links)).astype(np.float32)

        def run_env():
            for a in actions:
                env.step(a)

        def run_plant():
            x = env.states
            for a in actions:
                x = env.plant.step(x, a * env._live().params.tau_max)

        env_s, plant_s = _cpu(run_env), _cpu(run_plant)
    finally:
        env.close()
    per = envs * n_steps
    return {"links": links, "envs": envs, "n_steps": n_steps, "updates": updates,
            "train_us": 1e6 * train / steps, "env_us": 1e6 * env_s / per,
            "plant_us": 1e6 * plant_s / per}


def measure_marl(algo: str, links: int, *, envs: int = 16, n_steps: int = 128,
                 updates: int = 2, **options) -> dict:
    """CPU seconds per environment step of IPPO or MAPPO training (updates included;
    ``options``: more MarlConfig fields)."""
    import torch

    from twolink.training.marl import MarlConfig
    from twolink.training.marl_state import Learner

    config = MarlConfig(algo=algo, links=links, envs=envs, n_steps=n_steps, **options)
    unit = config.unit()
    learner = Learner(config, torch)
    try:
        learner.learn(unit, unit * (updates + 1))                  # warm-up update
        train = _cpu(lambda: learner.learn(unit * updates, unit * (updates + 1)))
    finally:
        learner.close()
    return {"algo": algo, "links": links, "envs": envs, "n_steps": n_steps,
            "updates": updates, "train_us": 1e6 * train / (unit * updates)}


def model_plant_us(links: int, envs: int, n_steps: int) -> float:
    """CPU microseconds per arm step of the model (6) alone (:class:`ModelPlant`) stepping
    ``envs`` arms of ``links`` tapered links (``links_parameters``) ``n_steps`` times with
    random torques."""
    from twolink.arm.parameters import links_parameters
    from twolink.sim.plants import ModelPlant

    params = links_parameters(links, "tapered")
    plant = ModelPlant("full", params)
    rng = np.random.default_rng(0)
    x = np.zeros((envs, 2 * links))
    x[:, :links] = rng.uniform(-np.pi, np.pi, (envs, links))
    torques = rng.uniform(-1, 1, (n_steps, envs, links)) * params.tau_max

    def run():
        y = x
        for tau in torques:
            y = plant.step(y, tau)

    return 1e6 * _cpu(run) / (envs * n_steps)


def bench_training(*, links=(2, 6), envs: int = 16, n_steps: int = 64, updates: int = 2,
                   model_recipe: dict | None = None) -> tuple[list[Row], dict]:
    """The rows of :func:`measure` for every N of ``links`` (``model_recipe``: the model
    rows' recipe, default :data:`MODEL_RECIPE`)."""
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        return [], {"skipped": "needs the rl extras (scripts/install-rl-extras.sh)"}
    import torch

    torch.set_num_threads(1)
    rows, summary = [], {}
    for n in links:
        m = measure(n, envs=envs, n_steps=n_steps, updates=updates)
        sec = f"{SECTION}: PPO, {n} links, {envs} arms"
        note = (f"{updates} update{'s' if updates > 1 else ''} of {envs} x {n_steps} "
                f"steps, 10 epochs each")
        rows += [
            Row(sec, "training, updates included: CPU per env step", m["train_us"], "us",
                note),
            Row(sec, "vector env alone: CPU per env step", m["env_us"], "us",
                "TwoLinkSB3VecEnv, random normalized actions"),
            Row(sec, "physics alone: CPU per env step", m["plant_us"], "us",
                "MujocoPlant.step of the batch"),
            Row(sec, "training / physics", m["train_us"] / m["plant_us"], "x"),
        ]
        summary[n] = m
        rows += _marl_rows(n, envs, n_steps, updates, m["plant_us"], summary)
    n = max(links)
    light = measure(n, n_steps=n_steps, updates=updates, **{"envs": envs, **LIGHT["ppo"]})
    sec = f"{SECTION}: PPO, {n} links, lighter recipe ({_recipe(LIGHT['ppo'])})"
    rows += [Row(sec, "training, updates included: CPU per env step", light["train_us"], "us",
                 f"{updates} update{'s' if updates > 1 else ''} of {n_steps} steps per arm"),
             Row(sec, "training / physics", light["train_us"] / summary[n]["plant_us"], "x")]
    summary[f"ppo_{n}_light"] = light
    rows += _marl_rows(n, envs, n_steps, updates, summary[n]["plant_us"], summary,
                       light=True)
    if "marl" not in summary:
        rows += _model_rows(n, n_steps, updates, dict(model_recipe or MODEL_RECIPE), summary)
    return rows, summary


def _model_rows(n, n_steps, updates, recipe, summary) -> list[Row]:
    on_model = measure_marl("mappo", n, n_steps=n_steps, updates=updates, plant="model",
                            **recipe)
    on_mujoco = measure_marl("mappo", n, n_steps=n_steps, updates=updates, **recipe)
    physics = model_plant_us(n, recipe["envs"], n_steps)
    sec = f"{SECTION}: MAPPO, {n} links, on the model (6) ({_recipe(recipe)})"
    note = (f"{updates} update{'s' if updates > 1 else ''} of {recipe['envs']} x {n_steps} "
            f"steps, {n} agents x {recipe['epochs']} epochs each")
    summary[f"mappo_{n}_model"] = dict(on_model, plant_us=physics,
                                       mujoco_train_us=on_mujoco["train_us"])
    return [Row(sec, "training on the model, updates included: CPU per env step",
                on_model["train_us"], "us", note),
            Row(sec, "the same recipe on MuJoCo: CPU per env step", on_mujoco["train_us"],
                "us", note),
            Row(sec, "physics alone (the model): CPU per env step", physics, "us",
                f"ModelPlant.step of {recipe['envs']} arms"),
            Row(sec, "training on the model / its physics", on_model["train_us"] / physics,
                "x")]


def _marl_rows(n, envs, n_steps, updates, plant_us, summary, light=False) -> list[Row]:
    try:
        import skrl  # noqa: F401
    except ImportError:
        summary["marl"] = "skipped: needs the marl extra (scripts/install-rl-extras.sh)"
        return []
    rows = []
    for algo in ("ippo", "mappo"):
        options = {"envs": envs, **(LIGHT[algo] if light else {})}
        m = measure_marl(algo, n, n_steps=n_steps, updates=updates, **options)
        sec = (f"{SECTION}: {algo.upper()}, {n} links, "
               + (f"lighter recipe ({_recipe(LIGHT[algo])})" if light else f"{envs} arms"))
        rows += [Row(sec, "training, updates included: CPU per env step", m["train_us"],
                     "us", f"{updates} update{'s' if updates > 1 else ''} of "
                           f"{options['envs']} x {n_steps} steps, {n} agents x "
                           f"{options.get('epochs', 10)} epochs each"),
                 Row(sec, "training / physics", m["train_us"] / plant_us, "x")]
        summary[f"{algo}_{n}" + ("_light" if light else "")] = m
    return rows
