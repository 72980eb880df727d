"""``twolink learn``: online fuzzy Q-learning on the MuJoCo arm (:mod:`twolink.synthesis.learning`).

Many arms learn one shared theta; every evaluation writes the current policy, with its
provenance and everything needed to resume, atomically to the checkpoint (a policy file
that ``twolink rollout --policy`` reads). Ctrl-C or SIGTERM keeps the last complete
checkpoint; ``--resume FILE`` continues from it exactly as if never interrupted.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from twolink.artifacts import check_outputs, make_folders, output_file
from twolink.commands import SUMMARIES
from twolink.commands.grammar import add_out
from twolink.commands._options import seed_option
from twolink.synthesis.learning import Learner, evaluate, stays_above, steps_to_reach
from twolink.synthesis.learning_setup import (
    MAX_ARMS,
    MAX_STEPS,
    RECOMMENDED_AVERAGE,
    UPDATES,
    LearnConfig,
    policy_kind,
)
from twolink.policy.fuzzy_policy import Policy, load_policy
from twolink.viz.formatting import format_rate
from twolink.viz.learning_curves import learning_curves

_DEFAULTS = LearnConfig()
#: The command's defaults are the API's (LearnConfig): theta averaged over 200 k control
#: steps for the decentralized learners, each bin's greedy action kept until beaten by 0.1,
#: a warm start at half the given Q.
AVERAGE = RECOMMENDED_AVERAGE
INIT_SCALE = _DEFAULTS.init_scale
HYSTERESIS = _DEFAULTS.hysteresis


def _count(text: str, option: str) -> int:
    """A whole number written as 1000000, 1_000_000 or 1e6; else a ValueError naming
    ``option``."""
    try:
        value = float(text.replace("_", ""))
    except ValueError:
        raise ValueError(f"{option} must be a whole number, got {text!r}") from None
    if not math.isfinite(value) or value != int(value):
        raise ValueError(f"{option} must be a whole number, got {text!r}")
    if abs(value) < 2**53:
        return int(value)
    try:                                  # beyond a float's integers: read it exactly
        return int(text.replace("_", ""))
    except ValueError:
        return int(value)


def add_parser(sub):
    p = sub.add_parser(
        "learn", help=SUMMARIES["learn"],
        description="Learn a fuzzy Q-function online on the MuJoCo arm: --arms arms step "
                    "together and update one shared theta (Q(x,u) = sum_m mu_m(x) theta[m,u], "
                    "the approximator of fuzzy Q-iteration). Every evaluation (the 65-state "
                    "evaluation set) writes a checkpoint policy file; a learning-curve PNG "
                    "is written at the end.")
    p.add_argument("--task", choices=("centralized", "decentralized"),
                   help="centralized: one agent, joint reward (15); decentralized: the "
                        "paper's ordered agents (agent 2 first, agent 1 sees tau2), rewards "
                        "(17) (required unless --resume)")
    p.add_argument("--independent", action="store_true",
                   help="decentralized only: fully independent learners (agent 1 does not "
                        "see tau2)")
    p.add_argument("--steps", default=None, metavar="N",
                   help=f"control steps summed over all arms, e.g. 1e6 (default "
                        f"{_DEFAULTS.steps:.0e}, at most {MAX_STEPS:.0e}); with --resume the "
                        f"new total")
    p.add_argument("--arms", default=str(_DEFAULTS.arms), metavar="M",
                   help=f"arms learning in parallel (default {_DEFAULTS.arms}, at most "
                        f"{MAX_ARMS})")
    p.add_argument("--init", metavar="NAME|FILE",
                   help="warm-start theta from a policy of the same task and grid, e.g. the "
                        "shipped 'decentralized' (synthesised on model (11))")
    p.add_argument("--update", choices=UPDATES, default=_DEFAULTS.update,
                   help="fuzzy: act and update as policy (14) (each active bin its own "
                        "action, target sum mu max theta, per-rule error); rule: the same with "
                        "epsilon-greedy per bin; fql: per-bin actions, error against "
                        "sum mu theta[m, a_m] (Jouffe/Glorennec); discrete: plain Q-learning "
                        f"(4) (default {_DEFAULTS.update})")
    p.add_argument("--average", type=float, default=None, metavar="STEPS",
                   help="the saved and evaluated policy reads an exponential average of theta "
                        "over about STEPS control steps (iterate averaging against the noise "
                        "of a constant alpha; learning itself unchanged); 0: theta itself "
                        f"(default {AVERAGE:g}; 0 for the centralized learner, whose "
                        f"checkpoint cannot hold a second theta)")
    p.add_argument("--init-scale", type=float, default=None, metavar="LAMBDA",
                   help="with --init, start from LAMBDA times its Q, in (0, 1]: the same "
                        "greedy policy, values nearer the optimistic 0 of a cold start "
                        f"(default {INIT_SCALE:g}; 1: the given Q as it is)")
    p.add_argument("--hysteresis", type=float, default=HYSTERESIS, metavar="M",
                   help="keep each bin's greedy action until another beats it by more than M "
                        "in the read theta (near-ties stop flipping the policy); 0: plain "
                        f"argmax (default {HYSTERESIS:g})")
    p.add_argument("--seed", default="0", metavar="S", help="seed of every random draw (default 0)")
    p.add_argument("--alpha", type=float, default=_DEFAULTS.alpha,
                   help=f"learning rate per unit of membership weight, in (0, 1] (default "
                        f"{_DEFAULTS.alpha:g})")
    p.add_argument("--alpha-halflife", type=float, default=_DEFAULTS.alpha_halflife,
                   metavar="STEPS",
                   help="alpha_t = alpha * H / (H + t) after t control steps (default 0: "
                        "constant)")
    p.add_argument("--epsilon", type=float, default=_DEFAULTS.epsilon,
                   help=f"exploration probability per arm and step at the start (default "
                        f"{_DEFAULTS.epsilon:g})")
    p.add_argument("--epsilon-final", type=float, default=None,
                   help="exploration probability at the end, reached linearly (default: "
                        "--epsilon)")
    p.add_argument("--episode", default=str(_DEFAULTS.episode), metavar="K",
                   help=f"sample periods per episode before an arm restarts from a random "
                        f"pose (default {_DEFAULTS.episode})")
    p.add_argument("--eval-every", default="0", metavar="N",
                   help="control steps between evaluations and checkpoints (default: "
                        "steps / 20)")
    add_out(p, "learn", default=None, metavar="FILE",
            help="checkpoint policy file (default ./learned_<learner>.npz; with --resume, "
                 "the resumed file; DIR/ writes that name in DIR, making DIR)")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="learning-curve figure (default: the checkpoint's name with "
                        "_curve.png)")
    p.add_argument("--resume", type=Path, default=None, metavar="FILE",
                   help="continue a run from its checkpoint (its settings are kept; --steps "
                        "may raise the total)")
    p.add_argument("--force", action="store_true", help="overwrite an existing checkpoint")
    p.add_argument("--threads", default="1", metavar="T",
                   help="MuJoCo threads stepping the arms (default 1)")
    p.add_argument("--json", action="store_true", help="print the run's summary as JSON")
    p.set_defaults(_defaults={a.dest: a.default for a in p._actions})
    return p


#: Options that define a run: a resumed run keeps its checkpoint's, so they are refused.
RUN_SETTINGS = ("task", "independent", "arms", "seed", "update", "alpha", "alpha_halflife",
                "epsilon", "epsilon_final", "episode", "eval_every", "average", "init",
                "init_scale", "hysteresis")


def check_resume_options(args) -> None:
    """With --resume, a one-line ValueError naming every run setting also given."""
    given = [f"--{d.replace('_', '-')}" for d in RUN_SETTINGS
             if getattr(args, d) != args._defaults.get(d)]
    if given:
        raise ValueError(f"{', '.join(given)}: a resumed run keeps the settings of its "
                         f"checkpoint ({args.resume}); drop {'it' if len(given) == 1 else 'them'}"
                         f" (--steps may raise the total)")


def _config(args) -> LearnConfig:
    if args.task is None:
        raise ValueError("--task is required (centralized or decentralized) unless --resume")
    if args.independent and args.task != "decentralized":
        raise ValueError("--independent applies to --task decentralized only")
    learner = "independent" if args.independent else args.task
    if args.init is None and args.init_scale is not None:
        raise ValueError("--init-scale applies to a warm start (--init) only")
    scale = INIT_SCALE if args.init_scale is None else args.init_scale
    return LearnConfig(
        learner=learner, steps=_count(args.steps, "--steps") if args.steps else _DEFAULTS.steps,
        arms=_count(args.arms, "--arms"),
        seed=seed_option(_count(args.seed, "--seed")), update=args.update,
        alpha=args.alpha, alpha_halflife=args.alpha_halflife, epsilon=args.epsilon,
        epsilon_final=args.epsilon if args.epsilon_final is None else args.epsilon_final,
        episode=_count(args.episode, "--episode"),
        eval_every=_count(args.eval_every, "--eval-every"),
        average=(0.0 if learner == "centralized" else AVERAGE) if args.average is None
        else args.average, init_scale=scale if args.init else 1.0,
        hysteresis=args.hysteresis).check()


def resume_learner(path: Path, *, steps=None, nthread: int = 1) -> Learner:
    """The learner of checkpoint ``path``, its whole resume state checked first
    (:meth:`Learner.resume`); any fault is one ValueError line naming the file."""
    checkpoint = Policy.load(path)             # names the file itself
    try:
        return Learner.resume(checkpoint, steps=steps, nthread=nthread)
    except ValueError as exc:
        raise ValueError(f"--resume {path}: {exc}") from None


def run(args) -> int:
    threads = _count(args.threads, "--threads")
    if not 1 <= threads <= 64:
        raise ValueError(f"--threads must be in [1, 64], got {threads}")
    if args.resume is not None:
        check_resume_options(args)
        steps = _count(args.steps, "--steps") if args.steps else None
        learner = resume_learner(args.resume, steps=steps, nthread=threads)
        output, folders = output_file(args.output, args.resume.name) if args.output \
            else (args.resume, [])
    else:
        config = _config(args)
        init = load_policy(args.init) if args.init else None
        output, folders = output_file(args.output, f"learned_{config.learner}.npz")
        if output.is_dir():
            raise ValueError(f"-o {output} is a directory; give a policy file name")
        if output.exists() and not args.force:
            raise ValueError(f"{output} exists; give --force to overwrite it or --resume it")
        learner = Learner(config, init=init, nthread=threads)
    plot = args.plot or output.with_name(output.stem + "_curve.png")
    try:
        check_outputs({"--output": output, "--plot": plot}, creatable=folders)
        make_folders(folders)
        with learner:
            curve = learner.run(checkpoint=output, progress=not args.json)
            kind = policy_kind(learner.config.learner)
            baseline = evaluate(load_policy(kind), learner.plant)
    except BaseException:
        learner.close()
        raise
    c = learner.config
    label = c.learner + (f" from {learner.init_label}" if learner.init_label else "") + \
        (f" x {c.init_scale:g}" if learner.init_label and c.init_scale != 1 else "") + \
        f" ({c.update}" + (f", theta averaged over {c.average:g} steps" if c.average else "") + \
        (f", hysteresis {c.hysteresis:g}" if c.hysteresis else "") + ")"
    learning_curves({f"{c.learner}, {c.arms} arms, seed {c.seed}": {label: curve}}, plot,
                    baselines={f"{kind} (11)": baseline.rate})
    final = curve[-1]
    summary = {"config": c.as_dict(), "init": learner.init_label, "checkpoint": str(output),
               "plot": str(plot), "curve": [e.as_dict() for e in curve],
               "final": final.as_dict(), "steps_to_90": steps_to_reach(curve),
               "stays_above_90": stays_above(curve),
               "model_based": {"policy": kind, **baseline.as_dict()},
               "learn_seconds": learner.learn_seconds,
               "steps_per_second": learner.steps_done / max(learner.learn_seconds, 1e-9)}
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    settle = f"{final.median_settle:.2f} s" if math.isfinite(final.median_settle) else "never"
    reach = steps_to_reach(curve)
    print(f"{label}: {final.steps} steps in {learner.learn_seconds:.1f} s "
          f"({summary['steps_per_second']:.0f} steps/s)")
    print(f"  final success {format_rate(final.successes, final.n)}, median settle {settle}, "
          f"mean return {final.mean_return:.3f}")
    print(f"  90 % reached: {'never' if reach is None else f'at {reach} steps'}; model-based "
          f"{kind}: {format_rate(baseline.successes, baseline.n)}")
    print(f"  wrote {output} and {plot}")
    return 0
