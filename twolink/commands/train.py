"""``twolink train``: deep RL on the arm with Stable-Baselines3 (:mod:`twolink.training`).

Trains PPO or SAC (Stable-Baselines3), or IPPO or MAPPO (skrl, one agent per joint,
:mod:`twolink.training.marl`) on N = 2..6 links, evaluates the deterministic policy on fixed poses
every --eval-every steps, rewrites the learning curve and a checkpoint after every
evaluation, and saves the final agent as a controller (``agent.zip``). ``--resume``
continues an interrupted run exactly as if it had never stopped.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from twolink.commands import SUMMARIES
from twolink.commands._options import seed_option
from twolink.resources import output_dir
from twolink.control.action_gain import MAX_ACTION_GAIN, check_action_gain
from twolink.control.history import MAX_HISTORY
from twolink.control.residual import BASES
from twolink.sim.challenges import LEVELS, is_mix, mix
from twolink.validate import choice
from twolink.training.config import (
    ALGOS,
    BATCH_RANGE,
    EVAL_SEED,
    EVALUATION_SEEDS,
    DEVICES,
    EVAL_EVERY,
    GAMMA_RANGE,
    HYPERPARAMETERS,
    START_OPTIONS,
    MARL_ALGOS,
    MAX_EPOCHS,
    MAX_STEPS,
    NET_LAYERS,
    NET_WIDTHS,
    PLANTS,
    TRAIN_REWARDS,
    TrainConfig,
    check_algo,
    check_gamma,
    check_net,
)
from twolink.training.marl import HYPERPARAMETERS as MARL_HYPERPARAMETERS
from twolink.training.bound_loss import BOUND_LOSS_RANGE, check_bound_loss
from twolink.training.std_floor import STD_FLOOR_RANGE, check_std_floor
from twolink.viz.formatting import format_rate


def _count(text, option: str, low: int = 1, high: int = MAX_STEPS) -> int | None:
    """A whole number written as 1000000, 1_000_000 or 1e6 (None stays None); else a
    one-line ValueError naming ``option``."""
    if text is None:
        return None
    try:
        value = float(str(text).replace("_", ""))
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value != int(value) or not low <= value <= high:
        raise ValueError(f"{option} must be a whole number from {low:,} to {high:,}, got "
                         f"{text!r}")
    return int(value)


def add_parser(sub):
    p = sub.add_parser(
        "train", help=SUMMARIES["train"],
        description="Train a deep-RL agent on the arm with Stable-Baselines3 (PPO or SAC) "
                    "or skrl (IPPO or MAPPO: one agent per joint, --observe) "
                    "on many arms stepped together: cos/sin observations, normalized "
                    "actions, the shaped reward, random poses at rest. Every --eval-every "
                    "steps the deterministic policy is scored on MuJoCo (two links: the "
                    "65-state evaluation set, 5 s; N links: 64 random poses at rest, 8 s) "
                    "and the learning curve (DIR/curve.json) and a checkpoint "
                    "(DIR/checkpoint.pt) are rewritten; the final agent is DIR/<algo>_<N>links_seed<S>.zip, "
                    "a controller for evaluate, leaderboard, rollout and render. Needs the "
                    "rl extras (scripts/install-rl-extras.sh).")
    p.add_argument("--algo", default=None, metavar="|".join(ALGOS + MARL_ALGOS),
                   help="the learner (default ppo); ippo and mappo: one agent per joint "
                        "(skrl, the marl extra), IPPO with a critic per agent on its own "
                        "observation and the per-link shaped reward, MAPPO with "
                        "centralized critics on the whole state and the team's shaped "
                        "reward; their agent is DIR/<algo>_<N>links_<observe>_seed<S>.marl.pt")
    p.add_argument("--observe", default=None, metavar="local|neighbours|global",
                   help="ippo/mappo: what each agent's policy sees (default neighbours: "
                        "its own and the next joint's angle and speed)")
    p.add_argument("--links", type=int, default=None, metavar="N",
                   help="links of the arm, 2 to 6 (default 2)")
    p.add_argument("--rule", choices=("tapered", "copied"), default=None,
                   help="how links beyond two are made (default tapered)")
    p.add_argument("--steps", default=None, metavar="N",
                   help="environment steps, all arms together, e.g. 1e6 (default 1e6), "
                        "rounded up to whole updates; with --resume the new total")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help="seed of the learner and arms (default 0; under --challenge not "
                        "an evaluation seed)")
    p.add_argument("--plant", choices=tuple(PLANTS), default=None,
                   help="what the arms are stepped on while training: mujoco (default) or "
                        "model, the full model (6) integrated by numpy; evaluation is on "
                        "MuJoCo either way")
    p.add_argument("--envs", default=None, metavar="M",
                   help=f"arms per batch (default PPO {HYPERPARAMETERS['ppo']['n_envs']}, "
                        f"SAC {HYPERPARAMETERS['sac']['n_envs']})")
    p.add_argument("--n-steps", default=None, metavar="K",
                   help=f"PPO: steps per arm between updates (default "
                        f"{HYPERPARAMETERS['ppo']['n_steps']})")
    p.add_argument("--eval-every", default=None, metavar="N",
                   help=f"environment steps between evaluations and checkpoints (default "
                        f"PPO {EVAL_EVERY['ppo']:,}, SAC {EVAL_EVERY['sac']:,})")
    p.add_argument("--challenge", default=None, metavar="|".join(LEVELS),
                   help="train under this challenge level: every episode on a new plant "
                        "drawn from the level, with its noise, delays and faults (two "
                        "links); the curve is evaluated under the same level on 8 plants of "
                        f"seed {EVAL_SEED}; seeds {' and '.join(map(str, EVALUATION_SEEDS))} "
                        "(the evaluation seeds) are refused. A mix of levels joined by + "
                        "in this order (e.g. none+medium+hard; --envs a multiple of their "
                        "number) trains arm i under level i mod L, and the curve scores "
                        "every level of it (none on the nominal arm once)")
    p.add_argument("--history", default=None, metavar="K",
                   help=f"observe the last K observations and K-1 actions, 1 to "
                        f"{MAX_HISTORY} (default 1: the present observation only; ippo/mappo: "
                        f"each agent its own observations and actions)")
    p.add_argument("--base", default=None, metavar="|".join(BASES),
                   help="none (default), or pd: the action (each agent's, for ippo/mappo) "
                        "is a residual over "
                        "the tuned per-joint PD (3 to 6 links), torque = clip(PD + "
                        "tau_max a, +-tau_max), so an untrained agent starts as the PD; "
                        "the agent records it and is run the same way as a controller")
    p.add_argument("--action-rate", default=None, metavar="C",
                   help="subtract C times the mean squared change of the normalized "
                        "action from every reward while training (0 to 100; default 0: off), "
                        "against torques that chatter under delays and noise (ippo: each "
                        "agent's own change; mappo: the team reward, the mean over agents)")
    p.add_argument("--gamma", default=None, metavar="G",
                   help=f"the discount factor, {GAMMA_RANGE[0]:g} to {GAMMA_RANGE[1]:g} "
                        f"(default {HYPERPARAMETERS['ppo']['gamma']:g} for every algorithm: "
                        f"an effective horizon of 50 samples, 2.5 s); closer to 1 values "
                        f"what pays off later in the episode")
    p.add_argument("--start", choices=START_OPTIONS, default=None,
                   help="the training episodes' initial poses: random (default: uniform "
                        "angles at rest), slow (only poses whose slowest joint its own motor "
                        "cannot bring home 1 s before the episode's end, so the other joints "
                        "must turn it; six tapered links) or mixed (half of each); every "
                        "algorithm; the curve is evaluated on uniform poses")
    p.add_argument("--init", default=None, metavar="AGENT.zip",
                   help="start from the policy of this saved agent (ppo, sac: the same "
                        "algorithm, arm, history and base; read as data) instead of a "
                        "random one, e.g. one cloned from demonstrations")
    p.add_argument("--batch-size", default=None, metavar="B",
                   help=f"samples per gradient step, {BATCH_RANGE[0]:,} to {BATCH_RANGE[1]:,} "
                        f"(default {HYPERPARAMETERS['ppo']['batch_size']} for every algorithm; "
                        f"ppo, ippo, mappo: held to at most one rollout, --envs x --n-steps); "
                        f"a larger batch takes fewer gradient steps per sample")
    p.add_argument("--epochs", default=None, metavar="E",
                   help=f"ppo, ippo, mappo: passes over each rollout per update, 1 to "
                        f"{MAX_EPOCHS} (default {HYPERPARAMETERS['ppo']['n_epochs']})")
    p.add_argument("--net", default=None, metavar="W,W",
                   help=f"hidden-layer widths of the policy and value networks, 1 to "
                        f"{NET_LAYERS} layers of {NET_WIDTHS[0]} to {NET_WIDTHS[1]} units "
                        f"(default ppo, sac {','.join(map(str, HYPERPARAMETERS['ppo']['net_arch']))}"
                        f"; ippo, mappo {','.join(map(str, MARL_HYPERPARAMETERS['hidden']))})")
    p.add_argument("--reward", choices=TRAIN_REWARDS, default=None,
                   help="the reward learnt from, shaped (default: dm_control-style "
                        "tolerances of angles and speeds, 0 in the goal band), shaped_time "
                        "(the shaped reward minus 1 for every sample outside the goal band: "
                        "a minimum-time term, as the paper's reward (15)) or paper ((15) "
                        "itself: -0.5 for every sample outside the band); ippo: each "
                        "agent's link and its own band ((17) for paper), mappo: the team's")
    p.add_argument("--action-gain", default=None, metavar="G",
                   help=f"ppo, sac: the torque is clip(G a, -1, 1) tau_max for the normalized "
                        f"action a, so full torque lies at |a| = 1/G (1 to "
                        f"{MAX_ACTION_GAIN:g}; default 1). SAC's squashed actions seldom "
                        f"reach +-1; the agent file records G and every loader applies it")
    p.add_argument("--std-floor", default=None, metavar="S",
                   help=f"ppo, ippo, mappo: each policy's exploration noise starts at "
                        f"standard deviation S, in units of the normalized action, and never "
                        f"falls below it (ppo: raised back to S before every rollout), "
                        f"{STD_FLOOR_RANGE[0]:g} to {STD_FLOOR_RANGE[1]:g} (default: starts "
                        f"at 1, no floor)")
    p.add_argument("--value-norm", action="store_true", default=None,
                   help="ippo, mappo: each critic learns standardized returns (a running "
                        "mean and variance, skrl's RunningStandardScaler: MAPPO's value "
                        "normalization)")
    p.add_argument("--bound-loss", default=None, metavar="C",
                   help=f"ippo, mappo: each policy's update also minimizes C * mean(max(|mu| "
                        f"- 1, 0)^2) of its mean actions mu (rl_games' bound loss), so no "
                        f"agent's mean drifts beyond the torque limit where every sample "
                        f"clips alike, {BOUND_LOSS_RANGE[0]:g} to {BOUND_LOSS_RANGE[1]:g} "
                        f"(default 0: none)")
    p.add_argument("--device", choices=DEVICES, default=None,
                   help="where torch runs the networks (default cpu; resume is bit for bit "
                        "on the CPU)")
    p.add_argument("--threads", default=None, metavar="T",
                   help="torch CPU threads (default 1: the networks are small)")
    p.add_argument("-o", "--out", type=Path, default=None, metavar="DIR",
                   help="the run's folder (default <output>/train/<algo>_<N>links_seed<S>)")
    p.add_argument("--resume", action="store_true",
                   help="continue the interrupted run in DIR from its last checkpoint")
    p.add_argument("--json", action="store_true", help="print the final record as JSON")
    return p


def given_options(args) -> dict:
    """The options given on the command line, checked, by TrainConfig field."""
    if args.algo is not None:
        check_algo(args.algo, marl=True)
    if args.observe is not None:
        from twolink.training.marl import OBSERVE

        if args.algo not in MARL_ALGOS and not args.resume:
            raise ValueError("--observe is for --algo ippo|mappo (one agent per joint)")
        choice(args.observe, "--observe", OBSERVE)
    if args.std_floor is not None and args.algo == "sac":
        raise ValueError("--std-floor is for --algo ppo|ippo|mappo: SAC's noise is an output "
                         "of its network")
    if args.value_norm and args.algo not in MARL_ALGOS and not args.resume:
        raise ValueError("--value-norm is for --algo ippo|mappo (skrl's critics)")
    if args.bound_loss is not None and args.algo not in MARL_ALGOS and not args.resume:
        raise ValueError("--bound-loss is for --algo ippo|mappo (skrl's Gaussian policies)")
    given = {"algo": args.algo, "links": args.links, "rule": args.rule,
             "steps": _count(args.steps, "--steps"),
             "seed": None if args.seed is None else seed_option(args.seed, high=2**32 - 1),
             "plant": args.plant, "envs": _count(args.envs, "--envs", 1, 4096),
             "n_steps": _count(args.n_steps, "--n-steps", 2, 100_000),
             "eval_every": _count(args.eval_every, "--eval-every"),
             "device": args.device, "threads": _count(args.threads, "--threads", 1, 256),
             "challenge": None if args.challenge is None else
             mix(args.challenge).name if is_mix(args.challenge) else
             choice(args.challenge, "--challenge level", tuple(LEVELS)),
             "history": _count(args.history, "--history", 1, MAX_HISTORY),
             "observe": args.observe,
             "base": None if args.base is None else choice(args.base, "--base", BASES),
             "action_rate": None if args.action_rate is None else _rate(args.action_rate),
             "gamma": None if args.gamma is None else _gamma(args.gamma),
             "start": args.start, "init": args.init,
             "batch_size": _count(args.batch_size, "--batch-size", *BATCH_RANGE),
             "epochs": _count(args.epochs, "--epochs", 1, MAX_EPOCHS),
             "net": None if args.net is None else _net(args.net),
             "reward": args.reward,
             "action_gain": None if args.action_gain is None else _number(
                 args.action_gain, "--action-gain", check_action_gain, 1.0, MAX_ACTION_GAIN),
             "std_floor": None if args.std_floor is None else _number(
                 args.std_floor, "--std-floor", check_std_floor, *STD_FLOOR_RANGE),
             "value_norm": args.value_norm,
             "bound_loss": None if args.bound_loss is None else _number(
                 args.bound_loss, "--bound-loss", check_bound_loss, *BOUND_LOSS_RANGE)}
    return {k: v for k, v in given.items() if v is not None}


def _number(text, option: str, check, low: float, high: float) -> float:
    """``check(float(text))`` of a numeric option, or one line naming ``option`` and its
    range ``low`` .. ``high``."""
    try:
        return check(float(text))
    except ValueError:
        raise ValueError(f"{option} must be a number from {low:g} to {high:g}, "
                         f"got {text!r}") from None


def _net(text) -> tuple[int, ...]:
    """``--net W,W,...`` as a tuple of widths; else one line naming the option."""
    try:
        return check_net(tuple(int(w) for w in str(text).split(",")))
    except ValueError:
        raise ValueError(f"--net must be 1 to {NET_LAYERS} comma-separated widths of "
                         f"{NET_WIDTHS[0]} to {NET_WIDTHS[1]} units, e.g. 64,64; got "
                         f"{text!r}") from None


def _gamma(text) -> float:
    return _number(text, "--gamma", check_gamma, *GAMMA_RANGE)


def _rate(text) -> float:
    from twolink.training.action_rate import MAX_ACTION_RATE, check_action_rate

    return _number(text, "--action-rate", check_action_rate, 0.0, MAX_ACTION_RATE)


def run(args) -> int:
    from twolink.training.run import CURVE, run_name, train

    given = given_options(args)
    if _is_marl(args, given):
        return _run_marl(args, given)
    given.pop("observe", None)
    if given.pop("value_norm", None):
        raise ValueError("--value-norm is for --algo ippo|mappo (skrl's critics)")
    if given.pop("bound_loss", None) is not None:
        raise ValueError("--bound-loss is for --algo ippo|mappo (skrl's Gaussian policies)")
    config = None if args.resume else TrainConfig(**given)
    default = config or TrainConfig(**{k: v for k, v in given.items()
                                       if k in ("algo", "links", "seed", "challenge", "history",
                                                "base")})
    out = args.out or output_dir(create=False) / "train" / run_name(default)
    record = train(config if config is not None else given, out, resume=args.resume,
                   progress=lambda text: print(text, file=sys.stderr, flush=True))
    last = record["curve"][-1]
    if args.json:
        print(json.dumps(record, indent=1))
    else:
        c = record["config"]
        level = (f" under {c['challenge']}" if c.get("challenge") else "") + (
            f", history {c['history']}" if c.get("history", 1) > 1 else "") + (
            f", residual over base {c['base']}" if c.get("base", "none") != "none" else "")
        print(f"{c['algo']} on {c['links']} links{level}, seed "
              f"{record['config']['seed']}: {record['steps']:,} steps in "
              f"{record['wall_s']:.0f} s of training ({record['steps_per_s'] or 0:.0f} "
              f"steps/s); final policy {format_rate(last['successes'], last['n'])}; agent "
              f"{out / record['agent']}, curve {out / CURVE}")
    return 0


def _is_marl(args, given) -> bool:
    """Whether this is an IPPO/MAPPO run: asked for, or resumed from a folder holding one."""
    if given.get("algo") in MARL_ALGOS:
        return True
    if args.resume and args.out is not None and "algo" not in given:
        from twolink.training.marl import run_algo

        return run_algo(args.out) in MARL_ALGOS
    return False


def _run_marl(args, given) -> int:
    from twolink.training.marl import CURVE_NAME, MarlConfig, config_from_options, run_name, train

    fields = config_from_options(given)
    config = None if args.resume else MarlConfig(**fields)
    out = args.out or output_dir(create=False) / "train" / run_name(config or MarlConfig(
        **{k: v for k, v in fields.items() if k in ("algo", "links", "observe", "seed",
                                                    "base", "challenge", "history",
                                                    "action_rate")}))
    record = train(config if config is not None else fields, out, resume=args.resume,
                   progress=lambda text: print(text, file=sys.stderr, flush=True))
    last, c = record["curve"][-1], record["config"]
    if args.json:
        print(json.dumps(record, indent=1))
    else:
        base = (f" under {c['challenge']}" if c.get("challenge") else "") + (
            f", history {c['history']}" if c.get("history", 1) > 1 else "") + (
            f", residual over base {c['base']}" if c.get("base", "none") != "none" else "")
        print(f"{c['algo']} on {c['links']} links ({c['observe']}){base}, seed {c['seed']}: "
              f"{record['steps']:,} steps in {record['wall_s']:.0f} s of training "
              f"({record['steps_per_s'] or 0:.0f} steps/s); final controller "
              f"{format_rate(last['successes'], last['n'])}; agent {out / record['agent']}, "
              f"curve {out / CURVE_NAME}")
    return 0
