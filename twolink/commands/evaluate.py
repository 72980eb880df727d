"""``twolink evaluate``: one controller under one challenge level on MuJoCo.

Any controller: a shipped policy, a classical baseline, a policy file, ``module:callable``
or ``path/to/file.py:callable`` (a callable mapping states (n, 4) to torques (n, 2):
twolink.sim.controller). Prints k/n with the 95 % Wilson interval, the worst plant, the
median settle time and settle / T*, the settle time over the time-optimal limit of each
initial state. The controller runs plain (it reads the challenge's readings as they are)
unless --compensate puts the delay predictor and observer in front of it. A progress bar
(samples Ts simulated) goes to stderr, as lines when it is not a terminal, unless --json.
The controller gets read-only copies of the states; what it prints goes to stderr, so
--json output stays valid; --timeout ends a call that runs too long.

With --links N (2 to 6) the controller is scored on the scaling table's protocol instead
(twolink.sim.pose_scoring): --poses K random poses at rest of the N-link arm (--rule
tapered or copied), drawn from seed S + N (default S: the scaling table's 20061122), run
for the arm's horizon (5 s for two links, 8 s beyond) on MuJoCo, success = settled in the
goal band 1 s before the end; it prints k/n with the Wilson interval and the median
settle time, the numbers of the scaling table's row of that controller. The two-link
options (--challenge, --compensate, --plants, --states) do not apply there; --horizon S runs
each pose S seconds instead (a pose failed at 8 s may only be late).
"""
from __future__ import annotations

import json
import math

from twolink.arm.parameters import LINK_RULES, MAX_LINKS, MIN_LINKS
from twolink.commands import SUMMARIES
from twolink.commands.grammar import deprecated
from twolink.sim.challenges import LEVELS
from twolink.sim.controller import MAX_TIMEOUT, MIN_TIMEOUT
from twolink.sim.metrics import MAX_POSES

STATE_SETS = ("full", "quick")
#: Poses of ``--links N`` by default and their seed: the scaling table's
#: (:data:`twolink.studies.scaling.measure.DEFAULT_POSES`, ``EVAL_SEED``; a test holds
#: them equal).
DEFAULT_POSES = 64
POSE_SEED = 20061122
#: Options of the two-link evaluation that ``--links`` does not take, and vice versa.
TWO_LINK_OPTIONS = ("challenge", "compensate", "plants", "states", "worst_case")
LINKS_OPTIONS = ("rule", "poses", "plant", "horizon")
#: ``--horizon`` (with --links): the seconds a run may take, beyond the 1 s a success holds.
HORIZON_RANGE = (2.0, 60.0)
#: ``--plant`` (with --links): what the poses run on -> :func:`twolink.sim.plants.make_plant`'s
#: name; the spelling of ``twolink train --plant``.
EVAL_PLANTS = {"mujoco": "mujoco", "model": "full"}


def add_parser(sub):
    p = sub.add_parser("evaluate", help=SUMMARIES["evaluate"],
                       description=" ".join(__doc__.replace("``", "").split("\n\n")[1].split()))
    p.add_argument("controller", metavar="CONTROLLER",
                   help="shipped policy or baseline name, a policy .npz, module:callable or "
                        "path/to/file.py:callable")
    p.add_argument("--challenge", default=None, metavar="LEVEL",
                   help=f"challenge level ({', '.join(LEVELS)}; default none)")
    p.add_argument("--compensate", action="store_true",
                   help="run behind the delay predictor and observer (the controller must "
                        "name its model in meta['model']); default: plain")
    p.add_argument("--plants", type=int, default=None, metavar="K",
                   help="plants drawn for a level that perturbs the plant (default 32)")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help=f"seed of the plants, noise and faults (default 2026); with --links, "
                        f"of the poses (drawn from S + N; default {POSE_SEED}, the scaling "
                        f"table's)")
    p.add_argument("--quick", action="store_const", const="quick", dest="states", default=None,
                   help="every 13th of the 65 states of the evaluation set (5 states)")
    deprecated(p, "evaluate", "--states", "--quick (or nothing: the 65 states)", dest="states",
               choices=STATE_SETS)
    p.add_argument("--worst-case", action="store_true",
                   help="also run the controller on the level's grid of plants (its "
                        "parameter box's centre and 24 corners, twolink.sim.plant_grid) and "
                        "report the worst grid plant beside the random plants' average")
    p.add_argument("--json", action="store_true",
                   help="print the result as JSON (and no progress bar)")
    p.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help=f"end the run (exit status 2) when one call of the controller takes "
                        f"longer than this, from {MIN_TIMEOUT:g} to {MAX_TIMEOUT:g} s "
                        f"(default: no limit)")
    p.add_argument("--links", type=int, default=None, metavar="N",
                   help=f"score on the scaling table's protocol on an arm of N links "
                        f"({MIN_LINKS} to {MAX_LINKS}): random poses at rest, the arm's "
                        f"horizon, settled 1 s before the end")
    p.add_argument("--rule", default=None, choices=LINK_RULES,
                   help="how links beyond the second are made (with --links N > 2; "
                        "default the catalogue entry's rule, else tapered)")
    p.add_argument("--poses", type=int, default=None, metavar="K",
                   help=f"random poses at rest with --links (1 to {MAX_POSES}; default "
                        f"{DEFAULT_POSES})")
    p.add_argument("--plant", default=None, choices=tuple(EVAL_PLANTS),
                   help="with --links: run the poses on MuJoCo (default) or on the "
                        "rigid-body model (6) that `twolink train --plant model` trains "
                        "on; the two scores of one agent are its transfer gap")
    p.add_argument("--horizon", type=float, default=None, metavar="SECONDS",
                   help=f"with --links: run each pose this long instead of the arm's "
                        f"horizon (5 s for two links, 8 s beyond), success settled 1 s "
                        f"before the end ({HORIZON_RANGE[0]:g} to {HORIZON_RANGE[1]:g} s): "
                        f"does a controller fail a pose, or settle it late?")
    return p


def links_result(controller: str, *, links: int, rule: str | None = None,
                 poses: int = DEFAULT_POSES, seed: int = POSE_SEED,
                 timeout: float | None = None, plant: str = "mujoco",
                 horizon: float | None = None) -> dict:
    """The JSON of ``twolink evaluate --links N``: ``controller`` (a catalogue name,
    policy file, ``module:callable`` or ``file.py:callable`` for N links) scored by
    :func:`twolink.sim.pose_scoring.score_on_poses`, the scaling table's scorer, on
    ``poses`` random poses at rest drawn from ``seed + links`` over the arm's horizon
    (:func:`twolink.arm.parameters.horizon`). ``rule`` defaults to the catalogue entry's
    (``pd_3link_copied`` runs on the copied arm), else ``'tapered'``. A ValueError (one line) for links outside
    the arm's range, an unknown rule, a rule with two links, poses outside 1 ..
    :data:`MAX_POSES` or a seed outside 0 .. 2**63 - 1 - N. ``plant``: ``mujoco`` (the
    MJCF arm, default) or ``model`` (the rigid-body model (6) that ``twolink train --plant
    model`` trains on), :data:`EVAL_PLANTS`; the gap between the two is a model-trained
    agent's transfer gap. ``horizon``: seconds per run instead of the arm's (within
    :data:`HORIZON_RANGE`, whole samples)."""
    from twolink.arm.parameters import TS, check_links, horizon as horizon_of
    from twolink.control.controllers import resolve_controller
    from twolink.envs.core import arm
    from twolink.sim.controller import check_timeout, checked
    from twolink.sim.pose_scoring import score_on_poses
    from twolink.validate import whole

    if isinstance(links, bool) or not isinstance(links, int) \
            or not MIN_LINKS <= links <= MAX_LINKS:
        raise ValueError(f"--links must be a whole number from {MIN_LINKS} to {MAX_LINKS} "
                         f"(the arms twolink builds), got {links}")
    n = check_links(links)
    if rule is not None and rule not in LINK_RULES:
        raise ValueError(f"--rule must be one of {', '.join(LINK_RULES)}, got {rule!r}")
    if rule is not None and n == 2:
        raise ValueError("--rule makes links beyond the second; --links 2 is Table I's arm")
    whole(poses, "--poses", 1, MAX_POSES)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63 - n:
        raise ValueError(f"--seed must be a whole number from 0 to {2**63 - 1 - n} (poses "
                         f"are drawn from seed + N), got {seed}")
    timeout = check_timeout(timeout, "--timeout")
    end_s = None
    if horizon is not None:
        low, high = HORIZON_RANGE
        if isinstance(horizon, bool) or not isinstance(horizon, (int, float)) \
                or not low <= horizon <= high \
                or abs(horizon / TS - round(horizon / TS)) > 1e-9:
            raise ValueError(f"--horizon must be from {low:g} to {high:g} s in whole samples "
                             f"of {TS:g} s, got {horizon!r}")
        end_s = float(horizon)
    if plant not in EVAL_PLANTS:
        raise ValueError(f"--plant must be one of {', '.join(EVAL_PLANTS)}, got {plant!r}")
    from twolink.control.catalogue import catalogue
    entry = catalogue().get(controller)   # a catalogue entry says which arm it is for
    if entry is not None and entry.links != n:
        raise ValueError(f"{controller} controls an arm of {entry.links} links; give "
                         f"--links {entry.links} (got --links {n})")
    if entry is not None and n > 2 and entry.rule is not None:
        if rule is not None and rule != entry.rule:
            raise ValueError(f"{controller} controls the {entry.rule} arm of {n} links; "
                             f"give --rule {entry.rule} or leave it out (got --rule {rule})")
        rule = entry.rule
    params = arm(links=n, rule=rule)
    c = resolve_controller(controller, links=n)
    own = getattr(c.controller, "links", None)
    if isinstance(own, int) and not isinstance(own, bool) and own != n:
        raise ValueError(f"{c.name} controls an arm of {own} links; give --links {own} "
                         f"(got --links {n})")
    c = checked(c, name=c.name, links=n, timeout=timeout)
    end = horizon_of(n) if end_s is None else end_s
    drawn, scores = score_on_poses(c, params, poses=int(poses), seed=seed, durations=(end,),
                                   plant=EVAL_PLANTS[plant])
    return {"controller": c.name, "links": n, "rule": rule_of(params), "plant": plant,
            "protocol": "random poses at rest (twolink.sim.pose_scoring)",
            "poses": int(poses), "seed": seed, "poses_seed": drawn, "horizon": end,
            **scores[end].as_dict()}


def rule_of(params) -> str:
    """The link rule of an arm, or ``'Table I'`` for the two-link arm."""
    return getattr(params, "rule", None) if params.links > 2 else "Table I"


def result(controller: str, *, challenge: str = "none", compensate: bool = False,
           plants: int = 32, seed: int = 2026, states: str = "full",
           progress: bool = False, timeout: float | None = None,
           worst_case: bool = False) -> dict:
    """The JSON of ``twolink evaluate``; ``progress`` shows the evaluation's bar
    (:func:`twolink.sim.progress.progress_bar`) on stderr; ``timeout`` limits each call
    of the controller to that many seconds (:class:`twolink.sim.controller.Checked`);
    ``worst_case`` adds ``"grid"``: the run on the level's grid of plants
    (:func:`twolink.sim.plant_grid.worst_case`, the same states, seed and mode).
    ``"hint"`` says, for a plain run under a perturbed level of a controller that names
    its model, what ``--compensate`` would do."""
    import numpy as np

    from twolink.control.controllers import resolve_controller
    from twolink.sim.cells import states_of
    from twolink.sim.challenges import challenge as challenge_named
    from twolink.sim.controller import check_timeout, checked
    from twolink.sim.evaluation import evaluate
    from twolink.studies.leaderboard.limits import state_limits
    from twolink.studies.leaderboard.measure import settle_ratios

    ch = challenge_named(challenge)
    if not 1 <= plants <= 10_000:
        raise ValueError(f"--plants must be from 1 to 10000, got {plants}")
    if not 0 <= seed < 2**63:
        raise ValueError(f"--seed must be a whole number from 0 to 2**63 - 1, got {seed}")
    timeout = check_timeout(timeout, "--timeout")
    c = checked(resolve_controller(controller), timeout=timeout)
    x0 = states_of(states)
    limits, source = state_limits(x0)
    ev = evaluate(c, x0=x0, challenge=ch, seed=seed, compensate=compensate,
                  count=plants if ch.perturbs_plant() else 1, label=c.name,
                  progress=progress)
    out = {"controller": c.name, "challenge": ch.name,
           "mode": "compensated" if compensate else "plain", "states": len(x0),
           "plants": len(ev.params), "seed": seed, **ev.score.as_dict(), "limits": source}
    if limits is not None:
        ratio = settle_ratios(ev.settle, ev.success, limits)
        med, worst = float(np.median(ratio)), float(ratio.max())
        out["settle_ratio_median"] = med if math.isfinite(med) else None
        out["settle_ratio_worst"] = worst if math.isfinite(worst) else None
    if worst_case:
        from twolink.sim.plant_grid import worst_case as on_grid

        out["grid"] = on_grid(c, ch, x0=x0, compensate=compensate, seed=seed).as_dict()
    if not compensate and ch.name != "none" and "model" in (c.meta or {}):
        out["hint"] = (f"{c.name} names its model ({c.meta['model']}); --compensate runs it "
                       f"behind the delay predictor and state observer, which predict through "
                       f"{ch.name}'s delays and filter its noise with that model "
                       f"(docs/guides/compensation.md)")
    return out


def _given(args, names) -> list:
    spelt = {"states": "quick"}                 # the option that sets the attribute
    return [f"--{spelt.get(n, n).replace('_', '-')}" for n in names
            if getattr(args, n) not in (None, False)]


def run_links(args) -> int:
    """``twolink evaluate NAME --links N``: print :func:`links_result`."""
    from twolink.viz.formatting import format_rate

    extra = _given(args, TWO_LINK_OPTIONS)
    if extra and not (extra == ["--challenge"] and args.challenge == "none"):
        raise ValueError(f"{', '.join(extra)} {'is a' if len(extra) == 1 else 'are'} two-link "
                         f"evaluation option{'s' if len(extra) > 1 else ''} (the 65 states "
                         f"and challenges); --links N scores random poses at rest")
    r = links_result(args.controller, links=args.links, rule=args.rule,
                     poses=DEFAULT_POSES if args.poses is None else args.poses,
                     seed=POSE_SEED if args.seed is None else args.seed,
                     timeout=args.timeout,
                     plant="mujoco" if args.plant is None else args.plant,
                     horizon=args.horizon)
    if args.json:
        print(json.dumps(r, indent=2))
        return 0
    settle = "never" if r["median_settle"] is None else f"{r['median_settle']:.2f} s"
    arm = "two links" if r["links"] == 2 else f"{r['links']} links, {r['rule']}"
    arm += "" if r["plant"] == "mujoco" else ", on the model (6)"
    print(f"{r['controller']} on {arm} ({r['poses']} random poses at rest, seed "
          f"{r['seed']} + {r['links']}, {r['horizon']:g} s): "
          f"{format_rate(r['successes'], r['n'])}; median settle {settle}")
    return 0


def run(args) -> int:
    from twolink.viz.formatting import format_rate

    if args.links is not None:
        return run_links(args)
    given = _given(args, LINKS_OPTIONS)
    if given:
        raise ValueError(f"{', '.join(given)} need{'s' if len(given) == 1 else ''} --links N (the "
                         f"scaling table's protocol); without it evaluate scores the two-link "
                         f"arm on the 65 states")
    r = result(args.controller,
               challenge="none" if args.challenge is None else args.challenge,
               compensate=args.compensate,
               plants=32 if args.plants is None else args.plants,
               seed=2026 if args.seed is None else args.seed,
               states="full" if args.states is None else args.states,
               progress=not args.json, timeout=args.timeout, worst_case=args.worst_case)
    if args.json:
        print(json.dumps(r, indent=2))
        return 0
    worst = ("" if r["worst_plant"] is None else
             f"; worst plant {r['worst_plant_successes']}/{r['n'] // r['plants']}")
    settle = "never" if r["median_settle"] is None else f"{r['median_settle']:.2f} s"
    line = (f"{r['controller']} under {r['challenge']} ({r['mode']}): "
            f"{format_rate(r['successes'], r['n'])}{worst}; median settle {settle}")
    if "settle_ratio_median" in r:
        def fmt(v):
            return "never" if v is None else f"{v:.2f}"
        line += (f"; settle / T* {fmt(r['settle_ratio_median'])} median, "
                 f"{fmt(r['settle_ratio_worst'])} worst")
    print(line)
    if "grid" in r:
        g = r["grid"]
        print(f"grid of {g['plants']} plants (centre and corners of {g['level']}'s box): "
              f"{format_rate(g['successes'], g['n'])}; worst plant "
              f"{g['worst_plant_successes']}/{g['states']} ({g['worst_plant']})")
    if "hint" in r:
        print(f"hint: {r['hint']}")
    return 0
