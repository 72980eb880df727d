"""Deep RL on the MuJoCo arm: SB3's SAC or PPO, scored by the paper's success metric.

``python docs/studies/deep_rl.py --algo sac|ppo --steps 1e6 --seed 0 [--minutes M]
[--out renders/deep_rl/sac_seed0.json] [--save renders/deep_rl/sac_seed0.zip]`` trains one Stable-Baselines3 learner with the one
hyperparameter set of :data:`HYPERPARAMETERS` on the arm through
:class:`twolink.envs.sb3.TwoLinkSB3VecEnv` (all arms in one ``mujoco.rollout`` call per
Ts): the shaped reward (:func:`twolink.envs.core.shaped_reward`), normalized actions
(a float32 Box [-1, 1]^2 scaled to +-tau_max), the cos/sin observation, random initial
angles at rest, 5 s episodes. Every ``--eval-every`` environment steps (and before the
first and after the last) the deterministic policy is scored by
:func:`twolink.sim.evaluation.evaluate` on the 65-state evaluation set on MuJoCo, the
paper's metric (settled in the goal band 1 s before the end of 5 s); the learning curve
(steps, successes/65, Wilson 95 % interval, wall time, steps/s) goes to ``--out`` as JSON,
rewritten whole after every point. ``--minutes`` caps the wall time of training (the run
stops at the first step past it and records where it stopped). ``--save`` writes the
final model (the one at the end of the step or minute budget, never a checkpoint picked
by its score: the curve is measured on the evaluation set) as an SB3 ``.zip`` that
``twolink leaderboard --controller FILE.zip`` (:mod:`twolink.control.sb3_agent`) runs.

Needs the rl extras: ``pip install 'twolink[rl]'`` (on Python 3.11:
``scripts/install-rl-extras.sh .venv``).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.arm.parameters import TABLE_I  # noqa: E402
from twolink.control.sb3_agent import model_torques  # noqa: E402

#: What the agent sees and does (the options of TwoLinkSB3VecEnv).
ENV = dict(observation="cos_sin", actions="normalized", reward="shaped", x0="random")
#: One hyperparameter set per algorithm, stated once; nothing is tuned per seed.
HYPERPARAMETERS = {
    # One gradient step per vector step of 8 arms (8 environment steps): on a CPU the
    # gradient steps, not the arms, bound the wall time (about 40 ms each on the 2-core
    # machine), so more arms per update buy data at no cost.
    "sac": dict(n_envs=8, learning_rate=3e-4, buffer_size=1_000_000, batch_size=256,
                learning_starts=5_000, gamma=0.98, tau=0.005, train_freq=1,
                gradient_steps=1, ent_coef="auto", net_arch=[256, 256]),
    "ppo": dict(n_envs=16, learning_rate=3e-4, n_steps=128, batch_size=256, n_epochs=10,
                gamma=0.98, gae_lambda=0.95, clip_range=0.2, ent_coef=0.0, vf_coef=0.5,
                max_grad_norm=0.5, net_arch=[256, 256]),
}
#: Environment steps between evaluations, per algorithm (default of --eval-every).
EVAL_EVERY = {"sac": 10_000, "ppo": 50_000}


class Controller:
    """A trained SB3 policy under the controller protocol of :mod:`twolink.sim.controller`:
    states (n, 4) -> torques (n, 2), the deterministic action scaled to +-tau_max."""

    def __init__(self, model, observation: str = ENV["observation"], params=TABLE_I):
        self.model, self.observation, self.tau_max = model, observation, params.tau_max
        self.name = "sb3"

    def __call__(self, x):
        return model_torques(self.model, x, self.observation, self.tau_max)


def _write(path: Path, record: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(record, indent=1) + "\n")
    os.replace(tmp, path)


def build(algo: str, seed: int, threads: int):
    """The SB3 model and its (monitored) VecEnv."""
    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.vec_env import VecMonitor

    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    torch.set_num_threads(threads)
    hp = dict(HYPERPARAMETERS[algo])
    n_envs, net = hp.pop("n_envs"), hp.pop("net_arch")
    venv = VecMonitor(TwoLinkSB3VecEnv(n_envs, nthread=1, **ENV))
    cls = SAC if algo == "sac" else PPO
    model = cls("MlpPolicy", venv, seed=seed, device="cpu", verbose=0,
                policy_kwargs=dict(net_arch=net), **hp)
    return model, venv


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    p.add_argument("--algo", choices=sorted(HYPERPARAMETERS), default="sac")
    p.add_argument("--steps", type=float, default=1e6,
                   help="environment steps to train (default 1e6)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None,
                   help="curve JSON (default renders/deep_rl/<algo>_seed<seed>.json)")
    p.add_argument("--eval-every", type=float, default=None,
                   help=f"environment steps between evaluations (default {EVAL_EVERY})")
    p.add_argument("--minutes", type=float, default=None,
                   help="stop training after this much wall time (default: no cap)")
    p.add_argument("--save", type=Path, default=None, metavar="FILE.zip",
                   help="save the final model there (default: not saved)")
    p.add_argument("--threads", type=int, default=1,
                   help="torch threads (default 1: the networks are small, and on 2 "
                        "shared cores 2 threads made a gradient step 40 times slower)")
    args = p.parse_args(argv)
    steps, every = int(args.steps), int(args.eval_every or EVAL_EVERY[args.algo])
    if steps < 1 or every < 1 or args.seed < 0 or args.threads < 1 or \
            (args.minutes is not None and not args.minutes > 0):
        p.error("--steps, --eval-every, --threads and --minutes must be positive, "
                "--seed non-negative")
    out = args.out or Path("renders/deep_rl") / f"{args.algo}_seed{args.seed}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    if args.save is not None and args.save.suffix != ".zip":
        p.error("--save must name a .zip file")
    try:
        import stable_baselines3
        import torch
    except ImportError:
        print("deep_rl.py needs the rl extras: pip install 'twolink[rl]'", file=sys.stderr)
        return 2
    from stable_baselines3.common.callbacks import BaseCallback

    from twolink.sim.evaluation import evaluate

    model, venv = build(args.algo, args.seed, args.threads)
    record = {"algo": args.algo, "seed": args.seed, "env": ENV,
              "hyperparameters": HYPERPARAMETERS[args.algo], "steps_requested": steps,
              "eval_every": every, "minutes_cap": args.minutes,
              "metric": "twolink.sim.evaluation.evaluate: 65-state evaluation set on "
                        "MuJoCo, success = settled in the goal band 1 s before the end of 5 s",
              "versions": {"python": platform.python_version(),
                           "stable_baselines3": stable_baselines3.__version__,
                           "torch": torch.__version__},
              "machine": {"cpus": os.cpu_count(), "torch_threads": args.threads},
              "curve": [], "done": False}
    clock = {"start": time.perf_counter(), "eval": 0.0}

    def point(n_steps: int) -> None:
        t0 = time.perf_counter()
        score = evaluate(Controller(model), label=f"{args.algo} seed {args.seed}").score
        clock["eval"] += time.perf_counter() - t0
        train = time.perf_counter() - clock["start"] - clock["eval"]
        ep = [e["r"] for e in (model.ep_info_buffer or [])]
        record["curve"].append({
            "steps": n_steps, "successes": score.successes, "n": score.n,
            "rate": score.rate, "wilson_95": [float(v) for v in score.wilson_95],
            "median_settle": None if math.isinf(score.median_settle) else score.median_settle,
            "train_wall_s": round(train, 2),
            "steps_per_s": round(n_steps / train, 1) if train > 0 and n_steps else None,
            "mean_episode_return_shaped": float(np.mean(ep)) if ep else None})
        lo, hi = score.wilson_95
        print(f"{n_steps:>9} steps  {score.successes:>2}/{score.n} succeed "
              f"[{lo:.2f}, {hi:.2f}]  train {train:7.1f} s  "
              f"{record['curve'][-1]['steps_per_s'] or 0:7.1f} steps/s", flush=True)
        _write(out, record)

    class Curve(BaseCallback):
        def __init__(self):
            super().__init__()
            self.next = every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                point(self.num_timesteps)
                self.next += every
            if args.minutes is not None and \
                    time.perf_counter() - clock["start"] > 60 * args.minutes:
                record["stopped_by_minutes_cap"] = True
                return False
            return True

    point(0)
    model.learn(total_timesteps=steps, callback=Curve(), progress_bar=False)
    if record["curve"][-1]["steps"] != model.num_timesteps:
        point(model.num_timesteps)
    wall = time.perf_counter() - clock["start"]
    train = wall - clock["eval"]
    record.update(done=True, steps=int(model.num_timesteps), wall_s=round(wall, 1),
                  train_wall_s=round(train, 1), eval_wall_s=round(clock["eval"], 1),
                  steps_per_s=round(model.num_timesteps / train, 1))
    if args.save is not None:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        model.save(args.save)            # the final model: no checkpoint is selected
        record["saved"] = str(args.save)
    _write(out, record)
    venv.close()
    print(f"{args.algo} seed {args.seed}: {model.num_timesteps} steps in {train:.0f} s of "
          f"training ({model.num_timesteps / train:.0f} steps/s); curve in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
