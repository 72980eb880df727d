"""What run-time compensation (twolink.sim.estimation) buys on MuJoCo, with and without it.

For every policy and condition, success (k/n, 95 % Wilson interval, the success rule of docs/conventions.md) over
the 65 states of the evaluation set, 5 s rollouts on the MuJoCo plant:

* ``nominal``: Table I plant, exact readings (the policy's own ceiling; compensation is
  then the policy itself, so both columns agree);
* ``delay``: a ``--delay``-sample actuation delay (Table I plant);
* ``noise``: Gaussian reading noise, ``--noise-deg`` on the angles and ``--noise-deg`` x
  0.02 rad/s on the speeds (twolink.sim.cells.SPEED_PER_DEG), Table I plant;
* ``plants`` (only when named in ``--conditions``): the perturbed plants below alone;
* ``combined``: both, on ``--plants`` plants whose ten physical parameters
  (perturbations.PHYSICAL) change jointly, each uniform in +-``--spread``
  (perturbations.random_perturbation), 65 states on each.

"with" wraps the policy in ``estimation.compensated(policy, delay=, noise=)``: the d-step
predictor when there is delay, the observer when there is noise. Both columns see the
same plants and the same noise: every number is one call of
:func:`twolink.sim.evaluation.evaluate` (noise keyed per (plant, state) from ``--seed``;
plants from default_rng(seed)), the compensated policy handed to it already wrapped.

``--tune`` instead measures the noise and combined conditions (compensated) for each
candidate observer process std (estimation.PROCESS_STD, ``--process-std``) on the given
seed: run it on a development seed (1000), never on the seed of the reported figures.

Run: .venv/bin/python docs/studies/compensation_study.py [--policies centralized_full ...]
     [--seed 2027] [--plants 32] [--spread 0.2] [--delay 1] [--noise-deg 1]
     [--conditions nominal delay noise plants combined] [--json]
     .venv/bin/python docs/studies/compensation_study.py --tune --seed 1000
A full run (four policies, five conditions) takes about 5 CPU-minutes (7 min wall on the
shared 2-core machine); --level hard on two policies about 2 CPU-minutes.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np
from tqdm import tqdm

from twolink.arm.dynamics import MODELS
from twolink.arm.integrate import sample_step, wrap_angle
from twolink.arm.parameters import TABLE_I
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.challenges import LEVELS, challenge
from twolink.sim.estimation import PROCESS_STD, compensated
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import evaluation_set
from twolink.sim.perturbations import PHYSICAL, random_perturbation
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout
from twolink.viz.formatting import format_rate

CONDITIONS = ("nominal", "delay", "noise", "combined")
#: More conditions --conditions may name: the perturbed plants alone (exact readings, no
#: delay), where compensation passes through: the policy's own robustness.
EXTRA_CONDITIONS = ("plants",)
#: Candidate observer process stds (rad/s per sample) of --tune.
TUNE_PROCESS_STD = (0.01, 0.02, 0.03, 0.05, 0.1, 0.3, 1.0)
#: Most plants of the combined condition (65 rollouts each).
MAX_PLANTS = 1000


def plants_for(condition: str, count: int, spread: float, seed: int) -> list:
    """Parameter sets of the condition: Table I, or ``count`` jointly perturbed plants."""
    if condition not in ("combined", "plants"):
        return [TABLE_I]
    rng = np.random.default_rng(seed)
    return [random_perturbation(rng, spread, names=PHYSICAL) for _ in range(count)]


def measure(policy, params: list, *, delay: int, noise_deg: float, seed: int,
            compensate: bool, **design) -> dict:
    """Success over the evaluation set on each plant of ``params``
    (:func:`twolink.sim.evaluation.evaluate`, one batched MuJoCo run): counts and rates."""
    controller = compensated(policy, delay=delay, noise=noise_deg > 0, **design) \
        if compensate else policy
    ev = evaluate(controller, params=params, delay=delay, angle_noise_deg=noise_deg,
                  seed=seed, compensate=False)
    return {k: v for k, v in ev.as_dict(rows=False).items()
            if k in ("successes", "n", "rate", "wilson_95", "worst_plant_rate",
                     "median_settle")}


def study(policies, *, seed: int, plants: int, spread: float, delay: int,
          noise_deg: float, conditions=CONDITIONS) -> list:
    settings = {"nominal": (0, 0.0), "delay": (delay, 0.0), "noise": (0, noise_deg),
                "combined": (delay, noise_deg), "plants": (0, 0.0)}
    runs = [(name, c, comp) for name in policies for c in conditions for comp in (False, True)]
    out = []
    for name, cond, comp in tqdm(runs, desc="compensation study", file=sys.stderr):
        d, nd = settings[cond]
        params = plants_for(cond, plants, spread, seed)
        r = measure(load_policy(name), params, delay=d, noise_deg=nd, seed=seed,
                    compensate=comp)
        out.append({"policy": name, "condition": cond, "compensated": comp, "delay": d,
                    "noise_deg": nd, "plants": len(params), **r})
    return out


def link2_prediction_error(policy) -> dict:
    """What agent 2 could predict of its own link: one-step predictions of (theta2,
    dtheta2) along the policy's nominal MuJoCo runs from the evaluation set, with the full
    model (6) from the whole state and both torques (what the shared compensator uses),
    and with the link-2 row of (11), which needs only (theta2, dtheta2, tau2) (all an
    agent-2-local predictor has). RMS errors against MuJoCo's next state."""
    with MujocoPlant(TABLE_I) as plant:
        traj = rollout(policy, plant, evaluation_set())
    x, u, nxt = traj.x[:, :-1], traj.u, traj.x[:, 1:]
    out = {}
    for name in ("full", "simplified"):
        e = sample_step(MODELS[name], TABLE_I, x, u) - nxt
        e[..., :2] = wrap_angle(e[..., :2])
        out[name] = {"theta2_rms": float(np.sqrt(np.mean(e[..., 1] ** 2))),
                     "dtheta2_rms": float(np.sqrt(np.mean(e[..., 3] ** 2)))}
    return out


def level_study(policies, level: str, *, seed: int, plants: int) -> list:
    """Each policy under a challenge level (:data:`twolink.sim.challenges.LEVELS`, through
    :func:`twolink.sim.evaluation.evaluate`): as it is, compensated with the observer gain of
    the default design noise (the medium level's), and with the gain designed for the
    level's own noise."""
    ch = challenge(level)
    noisy = bool(ch.angle_noise_deg or ch.speed_noise or ch.dropout or ch.stuck)
    modes = (("plain", None), ("compensated, design gain", {}),
             ("compensated, gain for the level's noise",
              {"angle_noise_deg": ch.angle_noise_deg, "speed_noise": ch.speed_noise}))
    out = []
    for name in policies:
        for mode, design in tqdm(modes, desc=f"{level} {name}", file=sys.stderr):
            policy = load_policy(name)
            if design is not None:
                policy = compensated(policy, delay=ch.action_delay,
                                     observation_delay=ch.observation_delay, noise=noisy,
                                     **design)
            ev = evaluate(policy, challenge=ch, count=plants, seed=seed, compensate=False)
            out.append({"policy": name, "level": level, "mode": mode,
                        **{k: v for k, v in ev.as_dict(rows=False).items()
                           if k in ("successes", "n", "rate", "wilson_95",
                                    "worst_plant_rate", "median_settle")}})
    return out


def tune(policies, *, seed: int, plants: int, spread: float, delay: int,
         noise_deg: float, candidates=TUNE_PROCESS_STD) -> list:
    out = []
    for name in policies:
        for q in tqdm(candidates, desc=f"tune {name}", file=sys.stderr):
            for cond, d in (("noise", 0), ("combined", delay)):
                r = measure(load_policy(name), plants_for(cond, plants, spread, seed), delay=d,
                            noise_deg=noise_deg, seed=seed, compensate=True, process_std=q)
                out.append({"policy": name, "condition": cond, "process_std": q, **r})
    return out


def _check(args) -> None:
    if not 1 <= args.plants <= MAX_PLANTS:
        raise ValueError(f"--plants must lie in [1, {MAX_PLANTS}], got {args.plants}")
    if not 0 <= args.spread < 1:
        raise ValueError(f"--spread must lie in [0, 1), got {args.spread}")
    if not 0 <= args.delay <= 20:
        raise ValueError(f"--delay must lie in [0, 20] samples, got {args.delay}")
    if not (math.isfinite(args.noise_deg) and 0 <= args.noise_deg <= 45):
        raise ValueError(f"--noise-deg must lie in [0, 45], got {args.noise_deg}")
    for name in args.policies:
        load_policy(name)
    if not all(math.isfinite(q) and 0 < q <= 10 for q in args.process_std):
        raise ValueError(f"--process-std values must lie in (0, 10], got {args.process_std}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--policies", nargs="+", default=["centralized_full", "decentralized_full"],
                    help="shipped policy names or .npz paths")
    ap.add_argument("--seed", type=int, default=2027,
                    help="seed of the plants and the noise (not the development seed 1000)")
    ap.add_argument("--plants", type=int, default=32, help="plants of the combined condition")
    ap.add_argument("--spread", type=float, default=0.2,
                    help="joint relative change of the physical parameters (combined)")
    ap.add_argument("--delay", type=int, default=1, help="actuation delay (samples)")
    ap.add_argument("--noise-deg", type=float, default=1.0,
                    help="angle noise std (deg); speeds get 0.02 rad/s per deg")
    ap.add_argument("--conditions", nargs="+", default=list(CONDITIONS),
                    choices=CONDITIONS + EXTRA_CONDITIONS, help="conditions to measure")
    ap.add_argument("--tune", action="store_true",
                    help="measure the candidate observer process stds (development seed)")
    ap.add_argument("--process-std", type=float, nargs="+", default=list(TUNE_PROCESS_STD),
                    help="candidate observer process stds of --tune (rad/s per sample)")
    ap.add_argument("--level", choices=tuple(LEVELS),
                    help="measure instead a challenge level: plain, compensated with the "
                         "design gain, and with the gain for the level's noise")
    ap.add_argument("--coupling", action="store_true",
                    help="measure instead how well link 2 is predicted without link 1")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        _check(args)
    except ValueError as exc:
        ap.exit(2, f"compensation_study: error: {exc}\n")
    opts = dict(seed=args.seed, plants=args.plants, spread=args.spread, delay=args.delay,
                noise_deg=args.noise_deg)
    if args.coupling:
        res = {name: link2_prediction_error(load_policy(name)) for name in args.policies}
        if args.json:
            print(json.dumps(res, indent=2))
            return 0
        print("| policy | one-step link-2 error, full model (6), whole state | "
              "link-2 row of (11), link 2 only |")
        print("|---|---|---|")
        for name, r in res.items():
            f, s = r["full"], r["simplified"]
            print(f"| {name} | {math.degrees(f['theta2_rms']):.2g} deg, "
                  f"{f['dtheta2_rms']:.2g} rad/s | {math.degrees(s['theta2_rms']):.2g} deg, "
                  f"{s['dtheta2_rms']:.2g} rad/s |")
        return 0
    if args.level:
        rows = level_study(args.policies, args.level, seed=args.seed, plants=args.plants)
        if args.json:
            print(json.dumps(rows, indent=2))
            return 0
        print(f"level {args.level}, seed {args.seed}, {args.plants} plants")
        print("| policy | mode | success (k/n, 95 % CI) | worst plant | median settle |")
        print("|---|---|---|---|---|")
        for r in rows:
            med = r["median_settle"]
            print(f"| {r['policy']} | {r['mode']} | {format_rate(r['successes'], r['n'])} "
                  f"| {100 * r['worst_plant_rate']:.0f} % | "
                  f"{'-' if med is None else f'{med:.2f} s'} |")
        return 0
    rows = tune(args.policies, candidates=args.process_std, **opts) if args.tune \
        else study(args.policies, conditions=args.conditions, **opts)
    if args.json:
        print(json.dumps({"options": opts, "process_std": PROCESS_STD, "results": rows},
                         indent=2))
        return 0
    if args.tune:
        print("| policy | condition | process std | success (k/n, 95 % CI) | worst plant |")
        print("|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['policy']} | {r['condition']} | {r['process_std']:g} | "
                  f"{format_rate(r['successes'], r['n'])} | {100 * r['worst_plant_rate']:.0f} % |")
        return 0
    print(f"seed {args.seed}; combined: {args.plants} plants, +-{100 * args.spread:g} % joint, "
          f"delay {args.delay}, noise {args.noise_deg:g} deg")
    print("| policy | condition | without compensation | with compensation |")
    print("|---|---|---|---|")
    for a, b in zip(rows[::2], rows[1::2]):
        print(f"| {a['policy']} | {a['condition']} | {format_rate(a['successes'], a['n'])} | "
              f"{format_rate(b['successes'], b['n'])} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
