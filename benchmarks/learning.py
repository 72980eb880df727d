"""Learning from the arm vs learning from a model: the comparison study of issue 12.

``python benchmarks/learning.py [--runs NAME ...] [--steps N] [--arms M] [--seeds S ...]
[--json PATH] [--out DIR]`` learns every run of :data:`RUNS` on MuJoCo, evaluates the
model-based policies on the same evaluation set, measures learning throughput against raw
batched stepping of the same arms side by side, and writes the curves
(``DIR/learning_curves.png``) and the data (``DIR/learning.json``). Results of earlier
invocations in the same JSON are kept (runs are merged by name and seed), so a long study
can be run a few runs at a time.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

if __package__ in (None, ""):                       # `python benchmarks/learning.py`
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from twolink.arm.parameters import REWARD_OTHER  # noqa: E402
from twolink.artifacts import provenance, write_json  # noqa: E402
from twolink.synthesis.learning import (  # noqa: E402
    Learner,
    evaluate,
    stays_above,
    steps_to_reach,
)
from twolink.synthesis.learning_setup import LearnConfig  # noqa: E402
from twolink.policy.fuzzy_policy import load_policy  # noqa: E402
from twolink.sim.plants import MujocoPlant  # noqa: E402
from twolink.viz.formatting import format_rate  # noqa: E402
from twolink.viz.learning_curves import learning_curves  # noqa: E402

#: name: (learner, update, --init policy or None[, other LearnConfig settings])
RUNS = {
    "decentralized cold": ("decentralized", "fuzzy", None),
    "decentralized from (11)": ("decentralized", "fuzzy", "decentralized"),
    "decentralized discrete (4) from (11)": ("decentralized", "discrete", "decentralized"),
    "decentralized discrete (4) cold": ("decentralized", "discrete", None),
    "independent cold": ("independent", "fuzzy", None),
    "independent discrete (4) cold": ("independent", "discrete", None),
    "centralized cold": ("centralized", "fuzzy", None),
    "centralized from (11)": ("centralized", "fuzzy", "centralized"),
    "centralized discrete (4) cold": ("centralized", "discrete", None),
    "centralized discrete (4) from (11)": ("centralized", "discrete", "centralized"),
    "decentralized discrete (4) cold, alpha halving at 250k":
        ("decentralized", "discrete", None, {"alpha_halflife": 250_000.0}),
    # issue 12's fixes: the policy reads theta averaged over 200 k steps; a warm start
    # from half the (11) Q (same greedy policy, values nearer the optimistic 0)
    "decentralized discrete (4) cold, averaged":
        ("decentralized", "discrete", None, {"average": 200_000.0}),
    "decentralized discrete (4) from (11) x 0.5, averaged":
        ("decentralized", "discrete", "decentralized", {"average": 200_000.0,
                                                        "init_scale": 0.5}),
    # ... and the policy's greedy actions kept until beaten by 0.1 (dev seed 98)
    "decentralized discrete (4) cold, averaged, hysteresis 0.1":
        ("decentralized", "discrete", None, {"average": 200_000.0, "hysteresis": 0.1}),
    "decentralized discrete (4) from (11) x 0.5, averaged, hysteresis 0.1":
        ("decentralized", "discrete", "decentralized", {"average": 200_000.0,
                                                        "init_scale": 0.5,
                                                        "hysteresis": 0.1}),
    "decentralized discrete (4) from (11), averaged":
        ("decentralized", "discrete", "decentralized", {"average": 200_000.0}),
    "decentralized discrete (4) from (11) x 0.5":
        ("decentralized", "discrete", "decentralized", {"init_scale": 0.5}),
}
#: Model-based policies drawn as horizontal lines.
BASELINES = ("decentralized", "centralized", "decentralized_full", "centralized_full")
#: Seed of the "other poses" (random angles at rest), never used for choices.
OTHER_POSES_SEED = 20261122
OTHER_POSES = 512


def other_poses(n: int = OTHER_POSES) -> np.ndarray:
    rng = np.random.default_rng(OTHER_POSES_SEED)
    x = np.zeros((n, 4))
    x[:, :2] = rng.uniform(-math.pi, math.pi, (n, 2))
    return x


def throughput(arms: int, iterations: int, *, seed: int = 0, repeats: int = 5) -> dict:
    """Control steps per CPU second of raw batched stepping (random torques), of the
    decentralized learner (default update) and of the same learner with its policy's
    theta averaged and its greedy actions kept (``average`` 200 k, ``hysteresis`` 0.1:
    issue 12's fix, what ``twolink learn`` does by default), on the same arms,
    alternating ``repeats`` times. CPU time of this process (one MuJoCo thread), so that
    other work on a shared machine does not enter the ratio."""
    rng = np.random.default_rng(seed)
    raw, learn, averaged = [], [], []
    config = LearnConfig(learner="decentralized", steps=arms * iterations * (repeats + 1),
                         arms=arms, seed=seed)
    with MujocoPlant(nthread=1) as plant, Learner(config, plant=plant) as learner, \
            Learner(dataclasses.replace(config, average=200_000.0, hysteresis=0.1),
                    plant=plant) as avg:
        x = other_poses(arms)
        for _ in range(repeats):
            tau = rng.uniform(-1, 1, (iterations, arms, 2)) * plant.params.tau_max
            t0 = time.process_time()
            for k in range(iterations):
                x = plant.step(x, tau[k])
            raw.append(arms * iterations / (time.process_time() - t0))
            for who, out in ((learner, learn), (avg, averaged)):
                t0 = time.process_time()
                for _ in range(iterations):
                    who.step()
                out.append(arms * iterations / (time.process_time() - t0))
    r, lr, ar = (float(np.median(v)) for v in (raw, learn, averaged))
    return {"arms": arms, "iterations": iterations, "raw_steps_per_s": r,
            "learn_steps_per_s": lr, "ratio": lr / r, "averaged_steps_per_s": ar,
            "averaged_ratio": ar / r, "raw_all": raw, "learn_all": learn,
            "averaged_all": averaged}


def run_one(name: str, seed: int, steps: int, arms: int, eval_every: int = 0) -> dict:
    learner_name, update, init, *more = RUNS[name]
    config = LearnConfig(learner=learner_name, update=update, steps=steps, arms=arms,
                         seed=seed, eval_every=eval_every or max(arms, steps // 16),
                         **(more[0] if more else {}))
    with Learner(config, init=load_policy(init) if init else None) as learner:
        t0 = time.perf_counter()
        curve = learner.run(on_eval=lambda e: print(
            f"{name}, seed {seed}: {e.steps} steps, {e.successes}/{e.n}", file=sys.stderr,
            flush=True))
        wall = time.perf_counter() - t0
        other = evaluate(learner.policy(), learner.plant, other_poses())
        # Q of (15)/(17) lies in [REWARD_OTHER / (1 - gamma), 0] = [-25, 0]
        low = REWARD_OTHER / (1 - config.gamma)
        out_of_range = {a.name: {"entries": int(np.count_nonzero((a.theta < low - 1e-9) |
                                                                 (a.theta > 1e-9))),
                                 "min": float(a.theta.min()), "max": float(a.theta.max())}
                        for a in learner.agents}
    return {"name": name, "seed": seed, "config": config.as_dict(), "init": init,
            "curve": [e.as_dict() for e in curve], "steps_to_90": steps_to_reach(curve),
            "stays_above_90": stays_above(curve), "other_poses": other.as_dict(),
            "theta_out_of_range": out_of_range,
            "wall_seconds": wall, "learn_seconds": learner.learn_seconds}


def baselines() -> dict:
    with MujocoPlant(nthread=1) as plant:
        return {name: {"evaluation_set": evaluate(load_policy(name), plant).as_dict(),
                       "other_poses": evaluate(load_policy(name), plant,
                                               other_poses()).as_dict()}
                for name in BASELINES}


def figure(data: dict, path: Path) -> Path:
    panels: dict = {"cold start (theta = 0)": {}, "warm start from the (11) policies": {}}
    for run in data["runs"]:
        panel = "warm start from the (11) policies" if run["init"] else "cold start (theta = 0)"
        label = run["name"].replace(" cold", "").replace(" from (11)", "")
        if run["config"]["update"] == "fuzzy":
            label = label.replace("ized", "ized fuzzy (14)", 1).replace("independent",
                                                                       "independent fuzzy (14)")
        label += f", {run['curve'][-1]['steps'] / 1e6:.1f} M" if run["curve"] else ""
        panels[panel][f"{label}, seed {run['seed']}"] = run["curve"]
    panels = {k: v for k, v in panels.items() if v}
    lines = {f"{k} (11)" if "full" not in k else k.replace("_full", " (6)"):
             v["evaluation_set"]["successes"] / v["evaluation_set"]["n"]
             for k, v in data["baselines"].items()}
    return learning_curves(panels, path, baselines=lines,
                           title=f"online fuzzy Q-learning on MuJoCo, "
                                 f"{data['runs'][0]['config']['arms']} arms")


def report(data: dict) -> str:
    lines = ["model-based policies on MuJoCo (evaluation set | 512 other poses):"]
    for k, v in data["baselines"].items():
        e, o = v["evaluation_set"], v["other_poses"]
        lines.append(f"  {k:<26} {format_rate(e['successes'], e['n']):<28} | "
                     f"{format_rate(o['successes'], o['n'])}")
    lines.append("learners (final evaluation | other poses | first >= 90 % | stays):")
    for run in data["runs"]:
        e, o = run["curve"][-1], run["other_poses"]
        best = max(run["curve"], key=lambda p: p["successes"])
        lines.append(f"  {run['name'] + ', seed ' + str(run['seed']):<44} "
                     f"{e['steps']:>9} steps {format_rate(e['successes'], e['n']):<28} | "
                     f"{format_rate(o['successes'], o['n']):<29} | "
                     f"{run['steps_to_90'] if run['steps_to_90'] is not None else 'never'} | "
                     f"{run['stays_above_90']} | best {best['successes']}/{best['n']} at "
                     f"{best['steps']}")
    if "throughput" in data:
        t = data["throughput"]
        lines.append(f"throughput ({t['arms']} arms): raw {t['raw_steps_per_s']:.0f} steps/s, "
                     f"learning {t['learn_steps_per_s']:.0f} steps/s (per CPU second, medians "
                     f"of {len(t['raw_all'])}), ratio {t['ratio']:.2f}" +
                     (f"; averaged theta, kept actions {t['averaged_steps_per_s']:.0f} "
                      f"steps/s, ratio "
                      f"{t['averaged_ratio']:.2f}" if "averaged_ratio" in t else ""))
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", nargs="*", choices=list(RUNS), default=None,
                   help="runs to learn (default: all)")
    p.add_argument("--steps", type=float, default=1e6, help="control steps per run")
    p.add_argument("--arms", type=int, default=256)
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--eval-every", type=float, default=0, metavar="N",
                   help="control steps between evaluations (default: steps / 16)")
    p.add_argument("--throughput", type=int, default=0, metavar="ITER",
                   help="also measure throughput over ITER batched steps (0: skip)")
    p.add_argument("--out", type=Path, default=Path("renders/learning"))
    p.add_argument("--merge", type=Path, nargs="*", default=[], metavar="JSON",
                   help="also take the runs of these learning.json files (from parallel "
                        "invocations with other --out folders)")
    p.add_argument("--json", action="store_true", help="print the data as JSON")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    store = args.out / "learning.json"
    data = json.loads(store.read_text()) if store.is_file() else {"runs": []}
    data["machine"] = provenance()
    if "baselines" not in data:
        data["baselines"] = baselines()
    for other in args.merge:
        for r in json.loads(other.read_text())["runs"]:
            data["runs"] = [q for q in data["runs"]
                            if (q["name"], q["seed"]) != (r["name"], r["seed"])] + [r]
    if args.throughput:
        data["throughput"] = throughput(args.arms, args.throughput)
    for name in (RUNS if args.runs is None else args.runs):
        for seed in args.seeds:
            result = run_one(name, seed, int(args.steps), args.arms, int(args.eval_every))
            data["runs"] = [r for r in data["runs"]
                            if (r["name"], r["seed"]) != (name, seed)] + [result]
            write_json(store, data)
    data["runs"].sort(key=lambda r: (list(RUNS).index(r["name"]), r["seed"]))
    write_json(store, data)
    if data["runs"]:
        figure(data, args.out / "learning_curves.png")
    print(json.dumps(data, indent=2) if args.json else report(data))
    return 0


if __name__ == "__main__":
    sys.exit(main())
